"""Brown–Conrady lens distortion (OpenCV's 5-coefficient model: k1, k2, p1, p2, k3).

The functions use only arithmetic operators, so they work on numpy arrays and on
Dr.Jit arrays alike (the Mitsuba sensor plugin calls them on ``mi.Float``).
Coordinates are *normalised* image coordinates x = X/Z, y = Y/Z (OpenCV camera frame).
"""
from __future__ import annotations

from typing import Sequence

#: Fixed-point iterations for the inverse model.  Each iteration shrinks the error by
#: about 3·|k1|·r² (≈ 0.1 for mild barrel at the image corner), so 20 iterations are
#: far below float32 resolution for any lens this project models.
UNDISTORT_ITERATIONS = 20


def distort_normalized(x, y, coeffs: Sequence[float]):
    """Forward model: ideal (undistorted) normalised coords -> distorted normalised coords."""
    k1, k2, p1, p2, k3 = (float(c) for c in coeffs)
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
    return xd, yd


def undistort_normalized(xd, yd, coeffs: Sequence[float], iterations: int = UNDISTORT_ITERATIONS):
    """Inverse model by fixed-point iteration (the scheme of OpenCV's ``undistortPoints``)."""
    k1, k2, p1, p2, k3 = (float(c) for c in coeffs)
    x, y = xd, yd
    for _ in range(iterations):
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        dx = 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
        dy = p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
        x = (xd - dx) / radial
        y = (yd - dy) / radial
    return x, y


def is_zero(coeffs: Sequence[float]) -> bool:
    """True when the model is the identity."""
    return all(float(c) == 0.0 for c in coeffs)
