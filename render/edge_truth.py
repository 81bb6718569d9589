"""Ground truth of analytic edges: signed distance to the true edge along the true normal.

Signed distance d > 0 on the bright side; the normal points dark -> bright
(the direction of the image gradient), OpenCV pixel coordinates.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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
    points within a vertex spacing of a smooth curve, the only ones scored)."""
    from scipy.spatial import cKDTree

    poly = np.asarray(poly, float)
    q = np.column_stack([np.ravel(x), np.ravel(y)]).astype(float)
    n = len(poly)
    if n < 3 or not len(q):
        return np.zeros(np.shape(x))
    _, i = cKDTree(poly).query(q)
    area2 = np.sum(poly[:, 0] * np.roll(poly[:, 1], -1) - np.roll(poly[:, 0], -1) * poly[:, 1])
    orient = 1.0 if area2 > 0 else -1.0  # > 0: counter-clockwise in (x right, y down) pixel axes
    best = np.full(len(q), np.inf)
    lever = np.zeros(len(q))  # |distance to the chord's line| of the chord that gave the sign
    sign = np.ones(len(q))
    for j0 in (i - 2, i - 1, i, i + 1):
        a, b = poly[j0 % n], poly[(j0 + 1) % n]
        d = b - a
        u = np.clip(((q - a) * d).sum(1) / np.maximum((d * d).sum(1), 1e-300), 0.0, 1.0)
        dist = np.linalg.norm(q - (a + u[:, None] * d), axis=1)
        cross = d[:, 0] * (q - a)[:, 1] - d[:, 1] * (q - a)[:, 0]
        line = np.abs(cross) / np.maximum(np.linalg.norm(d, axis=1), 1e-300)
        # Off a vertex both chords that meet there are nearest (at the vertex): the sign comes from
        # the one whose line the point is farther from.  The other's line may pass on the wrong side
        # of the point (on the extension of a side beyond an acute corner it does), whereas a
        # point farthest from a line lies on the side of it the vertex's normal cone says.
        tie = np.abs(dist - best) <= 1e-12 * np.maximum(1.0, best)
        signed = (dist < best) & ~tie | tie & (line > lever)
        lever[signed] = line[signed]
        sign[signed] = np.where(cross * orient > 0, -1.0, 1.0)[signed]
        best = np.minimum(best, dist)  # the distance exactly as before: the smallest of the four
    return (sign * best).reshape(np.shape(x))


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
