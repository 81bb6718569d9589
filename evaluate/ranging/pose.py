"""Pose-based ranging: the target's full pose from its fitted outline, beside Z = fx·S/l.

Z = fx·S/l (the seed's model) assumes a fronto-parallel target on the optical axis; a
target tilted by a few degrees or off axis biases it (the report's "model floor").  A
pose estimate uses the whole outline and removes that floor, so what is left is the
edge localisation's own effect on distance.

- Square: the four corners of the fitted side lines (undistorted image) and the known
  side S -> ``cv2.solvePnP`` with ``SOLVEPNP_IPPE_SQUARE`` (exact for four coplanar
  points); the distance is the Z of the square's centre.
- Circle: the image of a circle of diameter D is a conic.  The centre (X, Y, Z) and the
  plane's tilts are fitted to the refined edge points by least squares on their Sampson
  distances to the projected conic C = H^-T diag(1, 1, -r^2) H^-1, H = K [u v c]
  (u, v the plane's axes, c its centre), started fronto-parallel at the pinhole estimate.

Inputs are undistorted pixel coordinates with the camera matrix ``K`` of that image.
"""
from __future__ import annotations

import cv2
import numpy as np
from scipy.optimize import least_squares

from edgetruth.errors import InputError
from edgetruth.evaluate.ranging.size import circle_taubin


def square_pose_distance(corners_px, K, side_m: float) -> float:
    """Z (m) of the centre of a square of side ``side_m`` from its image corners
    (4, 2): top-left, top-right, bottom-right, bottom-left (OpenCV coordinates, undistorted)."""
    c = np.asarray(corners_px, np.float64).reshape(4, 2)
    if not np.all(np.isfinite(c)):
        raise InputError("square pose: corners are not finite")
    h = side_m / 2.0
    # IPPE_SQUARE's object order; object y up while image y runs down, so TL <-> (-h, +h)
    obj = np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])
    ok, rvec, tvec = cv2.solvePnP(obj, c, np.asarray(K, np.float64), None, flags=cv2.SOLVEPNP_IPPE_SQUARE)
    if not ok:
        raise InputError("square pose: solvePnP found no pose")
    return float(tvec[2, 0])


def _rotation(ax: float, ay: float) -> np.ndarray:
    cx, sx, cy, sy = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    return ry @ rx


def circle_conic(params, K, radius_m: float) -> np.ndarray:
    """3x3 image conic of a circle of ``radius_m`` centred at (X, Y, Z) with tilts (ax, ay) (rad)."""
    X, Y, Z, ax, ay = params
    R = _rotation(ax, ay)
    H = np.asarray(K, np.float64) @ np.column_stack([R[:, 0], R[:, 1], [X, Y, Z]])
    Hi = np.linalg.inv(H)
    return Hi.T @ np.diag([1.0, 1.0, -radius_m ** 2]) @ Hi


def sampson_distance(conic: np.ndarray, x, y) -> np.ndarray:
    """First-order geometric distance (px) of points to the conic x^T C x = 0."""
    p = np.stack([np.asarray(x, float), np.asarray(y, float), np.ones(np.size(x))])
    cp = conic @ p
    return np.sum(p * cp, axis=0) / (2.0 * np.hypot(cp[0], cp[1]))


def circle_pose_distance(x, y, K, diameter_m: float) -> float:
    """Z (m) of the centre of a circle of ``diameter_m`` from edge points on its image (undistorted px)."""
    x = np.asarray(x, np.float64)
    y = np.asarray(y, np.float64)
    if x.size < 8:
        raise InputError(f"circle pose: {x.size} edge points (need 8)")
    K = np.asarray(K, np.float64)
    fx, cx0, cy0 = K[0, 0], K[0, 2], K[1, 2]
    ex, ey, er = circle_taubin(x, y)
    z0 = fx * diameter_m / (2.0 * er)
    start = np.array([(ex - cx0) * z0 / fx, (ey - cy0) * z0 / K[1, 1], z0, 0.0, 0.0])
    r = diameter_m / 2.0
    scale = np.array([0.01, 0.01, 0.01, 0.05, 0.05])

    def residuals(p):
        return sampson_distance(circle_conic(p, K, r), x, y)

    sol = least_squares(residuals, start, x_scale=scale, loss="soft_l1", f_scale=0.5, xtol=1e-12, ftol=1e-12)
    if not np.all(np.isfinite(sol.x)) or sol.x[2] <= 0:
        raise InputError("circle pose: the fit did not converge")
    return float(sol.x[2])


def pose_distance(shape: str, size_m: float, K, corners_px=None, x=None, y=None) -> float:
    """Z (m) of a target's centre from its pose (square: corners; circle: edge points)."""
    if shape == "square":
        return square_pose_distance(corners_px, K, size_m)
    return circle_pose_distance(x, y, K, size_m)
