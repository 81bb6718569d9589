"""A circle grid (``kind = "circles_grid"``): dark circles printed flush on a white plate, as OpenCV's
``findCirclesGrid`` expects them (dark blobs on white: its default ``SimpleBlobDetector`` looks for dark ones).

OpenCV's conventions (``patternSize`` = (COLS, ROWS): COLS circles in each row, ROWS rows):

- **symmetric** (``CALIB_CB_SYMMETRIC_GRID``): circle (row i, column j) at (j s, i s);
- **asymmetric** (``CALIB_CB_ASYMMETRIC_GRID``): circle (i, j) at ((2 j + i mod 2) s, i s), the layout of
  OpenCV's calibration sample: ``s`` (``spacing_m``, what ``--square-m`` gives for such a grid) is the distance
  between rows and half the distance between neighbours in one row (diagonal neighbours lie s√2 apart).

``object_points`` is that layout, row-major (j fastest): the order ``findCirclesGrid`` returns the centres in
for a board seen upright (x right, y down in the image; checked on renders by the tests).  The rendering's board
frame is centred on the circles' bounding box (``centre_model_m``); ``pose_model`` in the truth maps the
object points' frame.

Rendering: ``board_mode = "frame"`` composites the plate's shading with each circle's exact lens-weighted
coverage (``dark_curves``: the exact ellipse outline, ``render.scene.board_frame``); ``board_mode = "path"``
path-traces the circles as regular polygons of ``POLYGON_SIDES`` sides of the circle's area
(``black_quads_local``), within ``polygon_error_m`` of the circle (a few 1e-4 px at the shipped sizes).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from edgetruth.render.schema import Key
from edgetruth.render.scene.shapes import TARGET_STANDOFF_M

#: sides of the polygon that stands for a circle in the path-traced mesh (even: it splits into quads)
POLYGON_SIDES = 258


@dataclass(frozen=True)
class CirclesGrid:
    """``cols`` circles in each of ``rows`` rows (OpenCV's patternSize), ``spacing_m`` apart (asymmetric: the
    row distance, half the in-row distance), each ``diameter_m`` across, on a white plate with ``margin_m``
    beyond the circles' bounding box."""

    cols: int = 4
    rows: int = 11
    spacing_m: float = 0.02
    diameter_m: float = 0.015
    asymmetric: bool = True
    margin_m: float = 0.02
    circle_reflectance: float = 0.04
    board_reflectance: float = 0.8

    @property
    def pattern_size(self) -> tuple[int, int]:
        """OpenCV's patternSize: (circles per row, rows)."""
        return self.cols, self.rows

    @property
    def square_reflectance(self) -> float:  # the name the board renderers read for the dark print
        return self.circle_reflectance

    @property
    def radius_m(self) -> float:
        return self.diameter_m / 2.0

    @property
    def n_circles(self) -> int:
        return self.cols * self.rows

    def object_points(self, z_m: float = 0.0) -> np.ndarray:
        """(n, 3) OpenCV's object points (module docstring), row-major, the first circle at the origin."""
        i, j = np.divmod(np.arange(self.n_circles), self.cols)
        x = (2 * j + i % 2) if self.asymmetric else j
        return np.column_stack([x * self.spacing_m, i * self.spacing_m, np.full(self.n_circles, float(z_m))])

    @property
    def centre_model_m(self) -> np.ndarray:
        """The circles' bounding-box centre in the object points' frame (the board frame's origin there)."""
        p = self.object_points()
        return np.r_[0.5 * (p[:, :2].min(0) + p[:, :2].max(0)), 0.0]

    def centres_local(self, z_m: float = 0.0) -> np.ndarray:
        """(n, 3) the circles' centres in the board frame (centred on the circles), ``object_points`` order."""
        return self.object_points(z_m) - self.centre_model_m

    @property
    def half_size_m(self) -> tuple[float, float]:
        """Half width and height of the plate (the circles' bounding box, their radius and the margin)."""
        p = self.centres_local()
        ext = np.max(np.abs(p[:, :2]), axis=0) + self.radius_m + self.margin_m
        return float(ext[0]), float(ext[1])

    def plate_corners_local(self) -> np.ndarray:
        hx, hy = self.half_size_m
        return np.array([[-hx, -hy, 0.0], [hx, -hy, 0.0], [hx, hy, 0.0], [-hx, hy, 0.0]])

    def polygon_radius_m(self) -> float:
        """Circumradius of the ``POLYGON_SIDES``-gon of the circle's area."""
        n = POLYGON_SIDES
        return self.radius_m * math.sqrt(2.0 * math.pi / (n * math.sin(2.0 * math.pi / n)))

    def polygon_error_m(self) -> float:
        """Largest distance between the mesh's polygon and the circle (at a vertex or mid-side)."""
        rp = self.polygon_radius_m()
        return max(rp - self.radius_m, self.radius_m - rp * math.cos(math.pi / POLYGON_SIDES))

    def black_quads_local(self, z_m: float) -> np.ndarray:
        """(n (N − 2) / 2, 4, 3) the path-traced mesh: each circle's ``POLYGON_SIDES``-gon (``polygon_radius_m``) as
        a fan of quads (v0, v_2k+1, v_2k+2, v_2k+3), wound like a checkerboard's squares."""
        n = POLYGON_SIDES
        ang = 2.0 * np.pi * np.arange(n) / n
        ring = self.polygon_radius_m() * np.column_stack([np.cos(ang), np.sin(ang)])
        k = np.arange((n - 2) // 2)
        fan = np.stack([np.zeros_like(k), 2 * k + 1, 2 * k + 2, 2 * k + 3], axis=1)  # (Q, 4) vertex indices
        quads = ring[fan]  # (Q, 4, 2)
        # a checkerboard square's corners go TL, TR, BR, BL: clockwise on screen (y down) = increasing angle here
        xy = self.centres_local()[:, None, None, :2] + quads[None]
        out = np.concatenate([xy, np.full(xy.shape[:-1] + (1,), float(z_m))], axis=-1)
        return out.reshape(-1, 4, 3)

    def dark_curves(self, camera, pose, z_m: float = -TARGET_STANDOFF_M) -> list:
        """The circles' exact outlines (``OutlineCurve.ellipse``) at ``pose``: what ``board_frame`` covers."""
        from edgetruth.render.scene.outline import OutlineCurve

        r = self.radius_m
        return [OutlineCurve.ellipse(camera, pose, (float(c[0]), float(c[1]), r, r, 0.0), standoff_m=-float(z_m))
                for c in self.centres_local()]

    def to_dict(self) -> dict:
        return {"cols": self.cols, "rows": self.rows, "spacing_m": self.spacing_m, "diameter_m": self.diameter_m,
                "asymmetric": self.asymmetric, "margin_m": self.margin_m, "pattern_size": list(self.pattern_size),
                "flags": "CALIB_CB_ASYMMETRIC_GRID" if self.asymmetric else "CALIB_CB_SYMMETRIC_GRID",
                "layout": ("circle (row i, column j) at ((2 j + i % 2) s, i s), s = spacing_m" if self.asymmetric
                           else "circle (row i, column j) at (j s, i s), s = spacing_m"),
                "white_reflectance": self.board_reflectance, "black_reflectance": self.circle_reflectance,
                "material": "Lambertian (diffuse) white plate and dark circles"}

    def resolved(self) -> dict:
        out = {"cols": self.cols, "rows": self.rows, "spacing_m": self.spacing_m, "diameter_m": self.diameter_m,
               "asymmetric": self.asymmetric, "margin_m": self.margin_m}
        # the print's albedos only where not the defaults: specs written before them keep their identity
        for key in ("circle_reflectance", "board_reflectance"):
            if getattr(self, key) != getattr(_G, key):
                out[key] = getattr(self, key)
        return out


_G = CirclesGrid()
CIRCLES_GRID_KEYS = [
    Key("cols", "int", _G.cols, "circles", "circles in each row (OpenCV's patternSize width)", 2, 100),
    Key("rows", "int", _G.rows, "circles", "rows of circles (OpenCV's patternSize height)", 2, 100),
    Key("spacing_m", "float", _G.spacing_m, "m", "the grid's spacing s: circle (i, j) at (j s, i s), or asymmetric "
        "((2 j + i % 2) s, i s) (OpenCV's sample; --square-m for such a grid)", 1e-4, 1.0),
    Key("diameter_m", "float", _G.diameter_m, "m", "diameter of each circle (must leave the circles apart)", 1e-4, 1.0),
    Key("asymmetric", "bool", _G.asymmetric, "", "every other row shifted by s (CALIB_CB_ASYMMETRIC_GRID); false: "
        "a symmetric grid (CALIB_CB_SYMMETRIC_GRID)"),
    Key("margin_m", "float", _G.margin_m, "m", "white margin beyond the circles", 0.0, 1.0),
    Key("circle_reflectance", "float", _G.circle_reflectance, "", "Lambertian albedo of the circles (matte black "
        "print)", 0.0, 1.0),
    Key("board_reflectance", "float", _G.board_reflectance, "", "Lambertian albedo of the plate (white paper)",
        0.0, 1.0),
]


def circles_grid_from_dict(d: dict, where: str) -> CirclesGrid:
    """``[spec] circles_grid`` -> ``CirclesGrid``; one ``InputError`` line when its circles touch."""
    from edgetruth.errors import InputError
    from edgetruth.render.schema import parse_table

    g = CirclesGrid(**parse_table(d, CIRCLES_GRID_KEYS, where))
    nearest = g.spacing_m * (math.sqrt(2.0) if g.asymmetric else 1.0)
    if g.diameter_m >= nearest:
        raise InputError(f"{where}: diameter_m = {g.diameter_m:g} m: neighbouring circles lie {nearest:g} m apart "
                         f"and would touch; give a diameter below that (OpenCV's patterns use about half of it)")
    return g
