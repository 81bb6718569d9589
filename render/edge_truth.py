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


def edge_from_dict(d: dict):
    d = dict(d)
    kind = d.pop("kind")
    return StraightEdge(**d) if kind == "line" else CircleEdge(**d)
