"""Normal profiles: gray values sampled at p + t n, t = -half..half, bilinear.

``bilinear`` is the one interpolation rule used by every profile-based
method (numba kernels call it per sample; ``sample_profiles`` is the numpy
batch form with identical arithmetic).
"""
from __future__ import annotations

import math

import numpy as np

from edgetruth.locate.candidates import PROFILE_HALF
from edgetruth.jit import njit, prange  # numba, imported when a kernel is first called


# forceinline: LLVM inlines the one compiled function (numba's inline="always" would copy and type it again in
# every kernel that calls it, which is slow to compile)
@njit(cache=True, forceinline=True)
def bilinear(img, x, y):
    """Bilinear interpolation at (x, y), OpenCV convention; (x, y) inside the pixel-centre hull."""
    h, w = img.shape
    x0 = int(math.floor(x))
    y0 = int(math.floor(y))
    if x0 > w - 2:
        x0 = w - 2
    if y0 > h - 2:
        y0 = h - 2
    if x0 < 0:
        x0 = 0
    if y0 < 0:
        y0 = 0
    fx = x - x0
    fy = y - y0
    top = img[y0, x0] * (1.0 - fx) + img[y0, x0 + 1] * fx
    bot = img[y0 + 1, x0] * (1.0 - fx) + img[y0 + 1, x0 + 1] * fx
    return top * (1.0 - fy) + bot * fy


@njit(cache=True, parallel=True)
def _sample_kernel(img, xs, ys, nxs, nys, ts, out):
    for i in prange(xs.shape[0]):
        for k in range(ts.shape[0]):
            out[i, k] = bilinear(img, xs[i] + ts[k] * nxs[i], ys[i] + ts[k] * nys[i])


def profile_offsets(half: int = PROFILE_HALF, step_px: float = 1.0) -> np.ndarray:
    """Sample positions t along the normal: -half*step .. +half*step."""
    return np.arange(-half, half + 1, dtype=np.float64) * step_px


def sample_profiles(image: np.ndarray, cand, half: int = PROFILE_HALF, step_px: float = 1.0) -> np.ndarray:
    """(N, 2*half+1) profiles of ``cand`` in ``image`` (float64); index ``half`` is t = 0."""
    ts = profile_offsets(half, step_px)
    out = np.empty((len(cand), ts.size), np.float64)
    if len(cand):
        _sample_kernel(np.ascontiguousarray(image, np.float64), cand.x, cand.y, cand.nx, cand.ny, ts, out)
    return out
