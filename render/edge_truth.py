"""Ground truth of analytic edges: signed distance to the true edge along the true normal.

Signed distance d > 0 on the bright side; the normal points dark -> bright
(the direction of the image gradient), OpenCV pixel coordinates.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from edgetruth.jit import njit


@dataclass(frozen=True)
class StraightEdge:
    """The line through (x0, y0) with unit normal (cos angle, sin angle) pointing to the bright side."""

    x0: float
    y0: float
    angle_rad: float
    kind: str = "line"

    @property
    def normal(self) -> tuple[float, float]:
        return float(np.cos(self.angle_rad)), float(np.sin(self.angle_rad))

    def signed_distance(self, x, y) -> np.ndarray:
        c, s = self.normal
        return (np.asarray(x, float) - self.x0) * c + (np.asarray(y, float) - self.y0) * s

    def normal_at(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        c, s = self.normal
        shape = np.broadcast(np.asarray(x), np.asarray(y)).shape
        return np.full(shape, c), np.full(shape, s)

    def to_dict(self) -> dict:
        return {"kind": self.kind, "x0": self.x0, "y0": self.y0, "angle_rad": self.angle_rad}


@dataclass(frozen=True)
class CircleEdge:
    """Circle of radius ``radius_px`` centred at (cx, cy); ``bright_inside`` says which side is bright."""

    cx: float
    cy: float
    radius_px: float
    bright_inside: bool = True
    kind: str = "circle"

    def signed_distance(self, x, y) -> np.ndarray:
        r = np.hypot(np.asarray(x, float) - self.cx, np.asarray(y, float) - self.cy)
        return (self.radius_px - r) if self.bright_inside else (r - self.radius_px)

    def normal_at(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        dx = np.asarray(x, float) - self.cx
        dy = np.asarray(y, float) - self.cy
        r = np.maximum(np.hypot(dx, dy), 1e-300)
        sgn = -1.0 if self.bright_inside else 1.0
        return sgn * dx / r, sgn * dy / r

    def to_dict(self) -> dict:
        return {"kind": self.kind, "cx": self.cx, "cy": self.cy, "radius_px": self.radius_px,
                "bright_inside": self.bright_inside}


def closed_polyline_signed_distance(poly: np.ndarray, x, y) -> np.ndarray:
    """Signed distance (px) of points to the closed polyline ``poly`` (N, 2): > 0 outside.

    The nearest vertex (k-d tree), then the exact distance to the four chords around it (enough for
    points within a vertex spacing of a smooth curve, the only ones scored): ``_chords_kernel``."""
    from scipy.spatial import cKDTree

    poly = np.ascontiguousarray(poly, dtype=np.float64)
    q = np.column_stack([np.ravel(x), np.ravel(y)]).astype(float)
    n = len(poly)
    if n < 3 or not len(q):
        return np.zeros(np.shape(x))
    _, i = cKDTree(poly).query(q)
    area2 = np.sum(poly[:, 0] * np.roll(poly[:, 1], -1) - np.roll(poly[:, 0], -1) * poly[:, 1])
    orient = 1.0 if area2 > 0 else -1.0  # > 0: counter-clockwise in (x right, y down) pixel axes
    out = np.empty(len(q))
    _chords_kernel(poly, np.ascontiguousarray(q[:, 0]), np.ascontiguousarray(q[:, 1]), i.astype(np.int64), orient,
                   out)
    return out.reshape(np.shape(x))


@njit(cache=True)  # strict IEEE, each operation as the numpy code it replaced did it: the same bits
def _chords_kernel(poly, qx, qy, nearest, orient, out):
    """Per point: the distance to the nearest of the chords j0 -> j0 + 1, j0 = nearest - 2 .. nearest + 1, and
    its sign.  Off a vertex both chords that meet there are nearest (at the vertex): the sign comes from the
    one whose line the point is farther from.  The other's line may pass on the wrong side of the point (on
    the extension of a side beyond an acute corner it does), whereas a point farthest from a line lies on the
    side of it the vertex's normal cone says."""
    n = poly.shape[0]
    for p in range(qx.shape[0]):
        best = np.inf
        lever = 0.0  # |distance to the chord's line| of the chord that gave the sign
        sign = 1.0
        for o in range(-2, 2):
            j0 = (nearest[p] + o) % n
            j1 = (j0 + 1) % n
            ax, ay = poly[j0, 0], poly[j0, 1]
            dx, dy = poly[j1, 0] - ax, poly[j1, 1] - ay
            qax, qay = qx[p] - ax, qy[p] - ay
            dd = dx * dx + dy * dy
            u = (qax * dx + qay * dy) / (dd if (dd > 1e-300 or dd != dd) else 1e-300)
            if u < 0.0:  # np.clip: NaN passes
                u = 0.0
            elif u > 1.0:
                u = 1.0
            ex, ey = qx[p] - (ax + u * dx), qy[p] - (ay + u * dy)
            dist = math.sqrt(ex * ex + ey * ey)
            cross = dx * qay - dy * qax
            nd = math.sqrt(dx * dx + dy * dy)
            line = abs(cross) / (nd if (nd > 1e-300 or nd != nd) else 1e-300)
            tie = abs(dist - best) <= 1e-12 * (best if (best > 1.0 or best != best) else 1.0)
            if ((dist < best) and not tie) or (tie and line > lever):
                lever = line
                sign = -1.0 if cross * orient > 0 else 1.0
            if dist != dist or best != best:  # np.minimum: NaN wins
                best = np.nan
            elif dist < best:
                best = dist
        out[p] = sign * best


@dataclass(frozen=True)
class OutlineEdge:
    """A rendered target's exact outline: the dense distorted polyline of its ground-truth JSON
    (chords within ``polyline_chord_error_px`` <= 1e-3 px of the curve), > 0 outside on the
    bright board, as the synthetic edges are > 0 on their bright side."""

    polyline_px: np.ndarray  # (N, 2) closed, OpenCV pixel coordinates
    shape: str  # "square" | "circle" (a catalogue shape: "rectangle", "ellipse", "polygon", ...)
    corners_px: np.ndarray | None = None  # (n, 2) distorted corners of a square (any polygon: its vertices)
    kind: str = "outline"

    @classmethod
    def from_ground_truth(cls, gt: dict) -> "OutlineEdge":
        """Shape 0's outline.  Corners: the JSON's ``outline.distorted_px`` where its kind is ``corners``
        (a square preset: its 4 corners, as before; a catalogue polygon: every vertex)."""
        o = gt["outline"]
        shape = gt["target"]["shape"]
        corners = np.asarray(o["distorted_px"], float) if o.get("kind", "corners" if shape == "square" else
                                                                "points") == "corners" else None
        return cls(np.asarray(o["polyline_distorted_px"], float), shape, corners)

    def signed_distance(self, x, y) -> np.ndarray:
        return closed_polyline_signed_distance(self.polyline_px, x, y)

    def corner_distance(self, x, y) -> np.ndarray:
        """Distance (px) to the nearest corner of a square (inf for a circle)."""
        x, y = np.asarray(x, float), np.asarray(y, float)
        if self.corners_px is None:
            return np.full(np.broadcast(x, y).shape, np.inf)
        c = self.corners_px
        return np.min(np.hypot(x[..., None] - c[:, 0], y[..., None] - c[:, 1]), axis=-1)


def edge_from_dict(d: dict):
    d = dict(d)
    kind = d.pop("kind")
    return StraightEdge(**d) if kind == "line" else CircleEdge(**d)
