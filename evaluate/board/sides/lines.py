"""Side lines of the squares from a method's refined points: assignment, total least squares, corners.

Side ``k`` of square ``s`` runs from corner ``k`` to corner ``k + 1`` of a quad (the model's
corner order).  A refined point belongs to the side segment nearest to it when

- it lies in the square's part of the photo (nearest to its detected quad: ``square_map``),
- the method refined it (``converged``; a declined candidate is its pixel centre, not an answer),
- its distance to the side's line is within ``band_px``,
- its foot on the side lies at least ``CORNER_EXCLUSION_PX`` from both corners (the profile
  there crosses two sides), and
- its normal is within ``MAX_NORMAL_ANGLE_DEG`` of the side's normal.

Two passes: the first assigns to the detected quads (pixel-accurate polygon vertices) with a
wide band, fits a line per side and intersects neighbouring lines; the second assigns again to
the quad of those corners with a narrower band and refits.  Each side's line is the total-least-
squares line of its points (no weights, no outlier rejection: the straightness statistic is the
RMS about this line, so what a method does to a point shows).  A side needs ``MIN_POINTS``
points; corner ``k`` is the intersection of sides ``k - 1`` and ``k`` and is missing (NaN)
when either is.

Everything is batched: one pass over the points, sums per side by ``np.bincount``.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.ndimage import distance_transform_edt

#: Candidates refined: those within this distance of a side (the rest cannot be assigned).
CANDIDATE_MARGIN_PX = 5.0
CORNER_EXCLUSION_PX = 3.0
MIN_POINTS = 5
MAX_NORMAL_ANGLE_DEG = 30.0
BAND_PASS1_PX = 3.0
BAND_PASS2_PX = 1.5


@dataclass
class SideFits:
    """Per side of every square (arrays of shape (S, 4)) and the corners (S, 4, 2) they give.

    n_points: points used; normal (S, 4, 2) and offset d: the line n.p = d (NaN when n_points < MIN_POINTS);
    rms_px: RMS distance of the side's points to its line; corners: intersections of neighbouring lines;
    labels: (N,) the side label ``4 * square + side`` of each point of the final pass (-1: none), when known."""

    n_points: np.ndarray
    normal: np.ndarray
    offset: np.ndarray
    rms_px: np.ndarray
    corners: np.ndarray
    labels: np.ndarray | None = None

    @property
    def covered(self) -> np.ndarray:
        return self.n_points >= MIN_POINTS


def square_map(quads: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """(H, W) int32: the index of the quad nearest to each pixel (-1 when there is none).  Built once per photo
    from its detected quads; ``assign`` looks each point up in it, so a point is only compared with the sides
    of one square."""
    quads = np.asarray(quads, np.float64)
    fill = np.zeros(shape, np.int32)
    for s in np.flatnonzero(np.all(np.isfinite(quads), axis=(1, 2))):
        cv2.fillConvexPoly(fill, np.round(quads[s]).astype(np.int32), int(s) + 1)
    if not fill.any():
        return fill - 1
    _, (iy, ix) = distance_transform_edt(fill == 0, return_indices=True)
    return fill[iy, ix] - 1


def near_sides(quads: np.ndarray, x, y, margin_px: float) -> np.ndarray:
    """True for points within ``margin_px`` of a side segment of a (finite) quad: the candidates worth refining."""
    quads = np.asarray(quads, np.float64)
    ok = np.all(np.isfinite(quads), axis=(1, 2))
    if not ok.any():
        return np.zeros(np.shape(x), bool)
    q = quads[ok]
    w = int(np.ceil(max(np.max(x), q[..., 0].max()) + margin_px + 2))
    h = int(np.ceil(max(np.max(y), q[..., 1].max()) + margin_px + 2))
    mask = np.zeros((h, w), np.uint8)
    cv2.polylines(mask, [np.round(v).astype(np.int32) for v in q], True, 1, thickness=2 * int(np.ceil(margin_px)) + 1)
    return mask[np.round(y).astype(int), np.round(x).astype(int)] > 0


def near_segments(segments: np.ndarray, x, y, margin_px: float) -> np.ndarray:
    """True for points within ``margin_px`` of one of the (M, 2, 2) segments (start, end)."""
    seg = np.asarray(segments, np.float64).reshape(-1, 2, 2)
    seg = seg[np.all(np.isfinite(seg), axis=(1, 2))]
    if not len(seg) or not np.size(x):
        return np.zeros(np.shape(x), bool)
    w = int(np.ceil(max(np.max(x), seg[..., 0].max()) + margin_px + 2))
    h = int(np.ceil(max(np.max(y), seg[..., 1].max()) + margin_px + 2))
    mask = np.zeros((h, w), np.uint8)
    cv2.polylines(mask, list(np.round(seg).astype(np.int32)), False, 1, thickness=2 * int(np.ceil(margin_px)) + 1)
    return mask[np.round(y).astype(int), np.round(x).astype(int)] > 0


def along_segments(start: np.ndarray, direction: np.ndarray, length: np.ndarray, normal: np.ndarray, x, y, nx, ny,
                   ok) -> np.ndarray:
    """(H, N) for each of H segments (``start`` (H, 2), unit ``direction`` (H, 2), ``length`` (H,) px) and each of N
    points: the point converged (``ok``), its foot on the segment lies ``CORNER_EXCLUSION_PX`` past the start to
    ``CORNER_EXCLUSION_PX`` short of the end, and its normal (nx, ny) is within ``MAX_NORMAL_ANGLE_DEG`` of
    ``normal`` (H, 2).  The distance to a line is the caller's: its band and its line differ."""
    t = (x[None] - start[:, :1]) * direction[:, :1] + (y[None] - start[:, 1:]) * direction[:, 1:]
    with np.errstate(invalid="ignore"):
        cos_n = np.abs(nx[None] * normal[:, :1] + ny[None] * normal[:, 1:])
        return ((t >= CORNER_EXCLUSION_PX) & (t <= length[:, None] - CORNER_EXCLUSION_PX)
                & (cos_n >= np.cos(np.radians(MAX_NORMAL_ANGLE_DEG))) & np.asarray(ok, bool)[None])


def assign(quads: np.ndarray, smap: np.ndarray, x, y, nx, ny, ok, band_px: float) -> np.ndarray:
    """Side label ``4 * square + side`` of each point, -1 where none (module docstring).  ``quads`` (S, 4, 2):
    the current corners; ``smap``: ``square_map`` of the photo."""
    quads = np.asarray(quads, np.float64)
    x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
    h, w = smap.shape
    sq = smap[np.clip(np.round(y).astype(int), 0, h - 1), np.clip(np.round(x).astype(int), 0, w - 1)]
    keep = (sq >= 0) & np.asarray(ok, bool)
    sq = np.where(keep, sq, 0)
    a = quads[sq]  # (N, 4, 2) the four sides' starts
    e = np.roll(a, -1, axis=1) - a
    length = np.sqrt((e ** 2).sum(axis=2))
    with np.errstate(invalid="ignore", divide="ignore"):
        ux, uy = e[..., 0] / length, e[..., 1] / length
        px, py = x[:, None] - a[..., 0], y[:, None] - a[..., 1]
        t = px * ux + py * uy  # along the side from corner k
        dist = np.abs(px * uy - py * ux)  # to the side's line
        cos_n = np.abs(np.asarray(nx, float)[:, None] * uy - np.asarray(ny, float)[:, None] * ux)
        good = ((dist <= band_px) & (t >= CORNER_EXCLUSION_PX) & (t <= length - CORNER_EXCLUSION_PX)
                & (cos_n >= np.cos(np.radians(MAX_NORMAL_ANGLE_DEG))) & keep[:, None])
    score = np.where(good, dist, np.inf)
    k = np.argmin(score, axis=1)
    hit = np.isfinite(score[np.arange(len(k)), k])
    return np.where(hit, 4 * sq + k, -1).astype(np.int64)


def tls_lines(g: np.ndarray, px: np.ndarray, py: np.ndarray, nb: int):
    """Total-least-squares line of each group's points (group ``g`` of each point, ``nb`` groups): (nb, 2) unit
    normals n and (nb,) offsets d of n.p = d, the RMS distance of the points to their line and the counts."""
    cnt = np.bincount(g, minlength=nb).astype(float)
    with np.errstate(invalid="ignore", divide="ignore"):
        mx = np.bincount(g, px, nb) / cnt
        my = np.bincount(g, py, nb) / cnt
        dx, dy = px - mx[g], py - my[g]  # centred first: no cancellation
        sxx, sxy, syy = (np.bincount(g, dx * dx, nb), np.bincount(g, dx * dy, nb), np.bincount(g, dy * dy, nb))
        theta = 0.5 * np.arctan2(2.0 * sxy, sxx - syy)  # direction of the major axis
        n = np.stack([-np.sin(theta), np.cos(theta)], axis=1)
        d = n[:, 0] * mx + n[:, 1] * my
        r = n[g, 0] * px + n[g, 1] * py - d[g]
        rms = np.sqrt(np.bincount(g, r * r, nb) / cnt)
    return n, d, rms, cnt


def fit_lines(label: np.ndarray, x, y, n_squares: int) -> SideFits:
    """Total-least-squares line of each side's points (labels from ``assign``) and the corners they give."""
    m = label >= 0
    g, px, py = label[m], np.asarray(x, float)[m], np.asarray(y, float)[m]
    nb = 4 * n_squares
    n, d, rms, cnt = tls_lines(g, px, py, nb)
    bad = cnt < MIN_POINTS
    n[bad], d[bad], rms[bad] = np.nan, np.nan, np.nan
    n = n.reshape(n_squares, 4, 2)
    d = d.reshape(n_squares, 4)
    return SideFits(cnt.reshape(n_squares, 4).astype(np.int64), n, d, rms.reshape(n_squares, 4),
                    intersect_sides(n, d))


def intersect(n1: np.ndarray, d1: np.ndarray, n2: np.ndarray, d2: np.ndarray) -> np.ndarray:
    """(..., 2) the intersection of the lines n1.p = d1 and n2.p = d2, NaN where one is missing or they are
    (nearly) parallel."""
    det = n1[..., 0] * n2[..., 1] - n1[..., 1] * n2[..., 0]
    with np.errstate(invalid="ignore", divide="ignore"):
        cx = (d1 * n2[..., 1] - n1[..., 1] * d2) / det
        cy = (n1[..., 0] * d2 - d1 * n2[..., 0]) / det
    c = np.stack([cx, cy], axis=-1)
    c[~np.isfinite(c).all(axis=-1) | ~(np.abs(det) >= 1e-6)] = np.nan
    return c


def intersect_sides(n: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Corner k = intersection of side k-1 and side k: (S, 4, 2), NaN where a line is missing or parallel."""
    return intersect(np.roll(n, 1, axis=1), np.roll(d, 1, axis=1), n, d)


def side_fits(quads: np.ndarray, smap: np.ndarray, x, y, nx, ny, converged) -> SideFits:
    """The two passes (module docstring) for one photo (its detected ``quads`` and their ``square_map``) and one
    method's points."""
    x, y, nx, ny = (np.asarray(v, np.float64) for v in (x, y, nx, ny))
    first = fit_lines(assign(quads, smap, x, y, nx, ny, converged, BAND_PASS1_PX), x, y, len(quads))
    # where pass 1 lost a corner, keep the detected quad's (the square then still gets assigned)
    quads2 = np.where(np.isfinite(first.corners), first.corners, quads)
    labels = assign(quads2, smap, x, y, nx, ny, converged, BAND_PASS2_PX)
    out = fit_lines(labels, x, y, len(quads))
    out.labels = labels
    return out
