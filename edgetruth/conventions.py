"""The one place for coordinate, axis and unit conventions.

Image coordinates (everything edgetruth outputs): **OpenCV's**.
Pixel (row r, col c) has its centre at x = c, y = r; x grows to the right,
y grows downwards; pixel (r, c) covers [c - 1/2, c + 1/2] x [r - 1/2, r + 1/2].

Mitsuba's film: pixel i covers [i, i + 1) with its centre at i + 1/2, so
x_cv = u_mitsuba - 1/2.  A centred camera has cx = W/2 - 1/2, cy = H/2 - 1/2.
With ``look_at`` Mitsuba's camera +x points to image *left* and +y to image
*up*: R_cv = diag(-1, -1, 1) @ R_mitsuba.

Units: lengths in metres unless a name says otherwise (``pitch_um``,
``distance_cm``); image quantities in pixels (``_px``).
"""
from __future__ import annotations

import numpy as np

#: Offset to add to a Mitsuba film coordinate to get an OpenCV coordinate.
MITSUBA_TO_CV_OFFSET_PX = -0.5

#: Rotation taking Mitsuba camera axes to OpenCV camera axes.
R_CV_FROM_MITSUBA = np.diag([-1.0, -1.0, 1.0])


def pixel_centres(shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """OpenCV pixel-centre coordinates (x, y) of an image of ``shape`` (H, W), each (H, W)."""
    h, w = shape
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    return x, y


def mitsuba_to_cv(u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mitsuba film coordinates (pixel i covers [i, i+1)) -> OpenCV (centre at integers)."""
    return np.asarray(u) + MITSUBA_TO_CV_OFFSET_PX, np.asarray(v) + MITSUBA_TO_CV_OFFSET_PX


def cv_to_mitsuba(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """OpenCV pixel coordinates -> Mitsuba film coordinates."""
    return np.asarray(x) - MITSUBA_TO_CV_OFFSET_PX, np.asarray(y) - MITSUBA_TO_CV_OFFSET_PX


def principal_point_centred(width: int, height: int) -> tuple[float, float]:
    """(cx, cy) of a camera whose optical axis hits the image centre, OpenCV convention."""
    return width / 2.0 - 0.5, height / 2.0 - 0.5


def focal_length_px(focal_length_m: float, pitch_m: float) -> float:
    """fx = fy = f / pitch (square pixels)."""
    return focal_length_m / pitch_m


def inside_image(x: np.ndarray, y: np.ndarray, shape: tuple[int, int], margin_px: float = 0.0) -> np.ndarray:
    """True where (x, y) lies inside the convex hull of pixel centres, shrunk by ``margin_px``."""
    h, w = shape
    x = np.asarray(x)
    y = np.asarray(y)
    return (x >= margin_px) & (y >= margin_px) & (x <= w - 1 - margin_px) & (y <= h - 1 - margin_px)
