"""Plane polygon geometry of the shape catalogue, numpy only: point in polygon (even-odd), signed area,
simplicity, ear-clipping triangulation, convex hull and the intersection of two convex polygons."""
from __future__ import annotations

import math

import numpy as np

from edgetruth.errors import InputError


def rot(theta_rad: float) -> np.ndarray:
    """The 2-D rotation by ``theta_rad`` (from +x towards +y)."""
    c, s = math.cos(theta_rad), math.sin(theta_rad)
    return np.array([[c, -s], [s, c]])


def point_in_polygon(poly: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Even-odd rule, vectorised over points."""
    x, y = xy[:, 0][:, None], xy[:, 1][:, None]
    x0, y0 = poly[:, 0][None], poly[:, 1][None]
    x1, y1 = np.roll(poly[:, 0], -1)[None], np.roll(poly[:, 1], -1)[None]
    crosses = (y0 > y) != (y1 > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xi = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
    return (np.sum(crosses & (x < xi), axis=1) % 2) == 1


def polygon_area2(v: np.ndarray) -> float:
    """Twice the signed (shoelace) area; > 0 for vertices clockwise on the board seen from the camera."""
    return float(np.sum(v[:, 0] * np.roll(v[:, 1], -1) - np.roll(v[:, 0], -1) * v[:, 1]))


def _segments_cross(p1, p2, q1, q2) -> bool:
    def orient(a, b, c):
        return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    d1, d2, d3, d4 = orient(q1, q2, p1), orient(q1, q2, p2), orient(p1, p2, q1), orient(p1, p2, q2)
    return (d1 * d2 < 0) and (d3 * d4 < 0)


def check_simple_polygon(v: np.ndarray, where: str) -> None:
    n = len(v)
    if abs(polygon_area2(v)) < 1e-18:
        raise InputError(f"{where}: vertices_m enclose no area; list 3 or more points around the polygon")
    if np.any(np.linalg.norm(np.roll(v, -1, axis=0) - v, axis=1) == 0):
        raise InputError(f"{where}: vertices_m repeats a point; list each corner once")
    for i in range(n):
        for j in range(i + 2, n):
            if i == 0 and j == n - 1:
                continue  # neighbours
            if _segments_cross(v[i], v[(i + 1) % n], v[j], v[(j + 1) % n]):
                raise InputError(f"{where}: vertices_m: sides {i} and {j} cross; list the corners in order "
                                 "around a simple polygon")


def triangulate(v: np.ndarray) -> np.ndarray:
    """Ear clipping of a simple polygon: (n - 2, 3) vertex indices, each triangle wound like ``v`` after
    making its area positive (the caller reverses for Mitsuba)."""
    idx = list(range(len(v)))
    if polygon_area2(v) < 0:
        idx.reverse()
    tris = []
    guard = 0
    while len(idx) > 3 and guard < 10 * len(v) ** 2:
        guard += 1
        m = len(idx)
        for k in range(m):
            a, b, c = idx[k - 1], idx[k], idx[(k + 1) % m]
            pa, pb, pc = v[a], v[b], v[c]
            if (pb[0] - pa[0]) * (pc[1] - pa[1]) - (pb[1] - pa[1]) * (pc[0] - pa[0]) <= 0:
                continue  # reflex
            others = [i for i in idx if i not in (a, b, c)]
            if others and np.any(point_in_polygon(np.array([pa, pb, pc]), v[others])):
                continue
            tris.append((a, b, c))
            idx.pop(k)
            break
    tris.append(tuple(idx))
    return np.asarray(tris, dtype=np.int64)


def convex_hull(q: np.ndarray) -> np.ndarray:
    """Indices of the convex hull of 2-D points (N, 2), counter-clockwise in (x, y), collinear points left out
    (Andrew's monotone chain)."""
    q = np.asarray(q, float)
    order = sorted(range(len(q)), key=lambda i: (q[i, 0], q[i, 1]))

    def cross(o, a, b):
        return (q[a, 0] - q[o, 0]) * (q[b, 1] - q[o, 1]) - (q[a, 1] - q[o, 1]) * (q[b, 0] - q[o, 0])

    scale = float(np.ptp(q, axis=0).max()) ** 2
    lower, upper = [], []
    for i in order:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], i) <= 1e-12 * scale:
            lower.pop()
        lower.append(i)
    for i in reversed(order):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], i) <= 1e-12 * scale:
            upper.pop()
        upper.append(i)
    return np.asarray(lower[:-1] + upper[:-1], dtype=np.int64)


def convex_intersection(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The intersection of two convex polygons (n, 2), (m, 2) (Sutherland-Hodgman: ``a`` clipped by each side
    of ``b``); (k, 2) in ``a``'s orientation, empty when they do not overlap."""
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    if polygon_area2(b) < 0:
        b = b[::-1]
    out = list(a)
    for i in range(len(b)):
        p, q = b[i], b[(i + 1) % len(b)]
        e = q - p
        src, out = out, []
        if not src:
            break
        for j in range(len(src)):
            c, d = src[j], src[(j + 1) % len(src)]
            fc = e[0] * (c[1] - p[1]) - e[1] * (c[0] - p[0])
            fd = e[0] * (d[1] - p[1]) - e[1] * (d[0] - p[0])
            if fc >= 0:
                out.append(c)
            if (fc >= 0) != (fd >= 0):
                out.append(c + (d - c) * (fc / (fc - fd)))
    return np.asarray(out, float).reshape(-1, 2)


