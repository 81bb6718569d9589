"""What stands in front of the camera: the targets T1-T4 and the checkerboard (geometry and materials).

Pure data and geometry, no Mitsuba: the spec loader, the ground truth and the
Mitsuba scene all read these definitions.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from edgetruth.render.schema import Key

#: Targets are mounted flush on the board: 10 um stand-off, only to avoid coplanar surfaces
#: (a real stand-off casts ambient-occlusion shading that moves the edge; BRIEF §1).
TARGET_STANDOFF_M = 10e-6
BOARD_HALF_SIZE_M = (1.8, 1.5)  # fills the frame at 3 m with room for lateral offsets
BOARD_REFLECTANCE = 0.8  # white matte board (Lambertian albedo)
CHECKER_BLACK_REFLECTANCE = 0.04  # the checkerboard's black squares: matte black print

#: Target ids -> shape and material.  Reflectances are Lambertian albedos.
TARGETS = {
    "T1": {"shape": "square", "material": "black_matte", "reflectance": 0.04},
    "T2": {"shape": "circle", "material": "black_matte", "reflectance": 0.04},
    "T3": {"shape": "square", "material": "gray_matte", "reflectance": 0.25},
    "T4": {"shape": "square", "material": "glossy_black", "reflectance": 0.03, "alpha": 0.15, "eta": 1.5},
}


@dataclass(frozen=True)
class Checkerboard:
    """``cols`` x ``rows`` squares of ``square_m``; inner corners (cols-1) x (rows-1)."""

    cols: int = 10
    rows: int = 7
    square_m: float = 0.03
    margin_m: float = 0.03

    @property
    def pattern_size(self) -> tuple[int, int]:
        """OpenCV's patternSize (inner corners per row, per column)."""
        return self.cols - 1, self.rows - 1

    @property
    def half_size_m(self) -> tuple[float, float]:
        """Half width and height of the plate (squares plus margin)."""
        return self.cols * self.square_m / 2 + self.margin_m, self.rows * self.square_m / 2 + self.margin_m

    def plate_corners_local(self) -> np.ndarray:
        hx, hy = self.half_size_m
        return np.array([[-hx, -hy, 0.0], [hx, -hy, 0.0], [hx, hy, 0.0], [-hx, hy, 0.0]])

    def inner_corners_local(self, z_m: float = 0.0) -> np.ndarray:
        """Inner corners, row-major (x fastest) like ``cv2.findChessboardCorners``; board centre at 0."""
        xs = (np.arange(1, self.cols) - self.cols / 2) * self.square_m
        ys = (np.arange(1, self.rows) - self.rows / 2) * self.square_m
        gx, gy = np.meshgrid(xs, ys)
        return np.stack([gx.ravel(), gy.ravel(), np.full(gx.size, z_m)], axis=1)

    def black_quads_local(self, z_m: float) -> np.ndarray:
        """(n, 4, 3) corners of the black squares ((i + j) even is black)."""
        quads = []
        s = self.square_m
        for j in range(self.rows):
            for i in range(self.cols):
                if (i + j) % 2 == 0:
                    x0 = (i - self.cols / 2) * s
                    y0 = (j - self.rows / 2) * s
                    quads.append([[x0, y0, z_m], [x0 + s, y0, z_m], [x0 + s, y0 + s, z_m], [x0, y0 + s, z_m]])
        return np.asarray(quads, dtype=np.float64)

    def to_dict(self) -> dict:
        return {"cols": self.cols, "rows": self.rows, "square_m": self.square_m, "margin_m": self.margin_m,
                "pattern_size": list(self.pattern_size), "black_square": "(col + row) even, col 0 row 0 at top-left",
                "white_reflectance": BOARD_REFLECTANCE, "black_reflectance": CHECKER_BLACK_REFLECTANCE,
                "material": "Lambertian (diffuse) white plate and black squares"}


_C = Checkerboard()
CHECKERBOARD_KEYS = [
    Key("cols", "int", _C.cols, "squares", "squares per row", 3, 100),
    Key("rows", "int", _C.rows, "squares", "squares per column", 3, 100),
    Key("square_m", "float", _C.square_m, "m", "side of one square", 1e-4, 1.0),
    Key("margin_m", "float", _C.margin_m, "m", "white margin around the squares", 0.0, 1.0),
]
