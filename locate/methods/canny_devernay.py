"""Canny-Devernay: Devernay's (1995) parabolic subpixel refinement of Canny points,
as implemented by Grompone von Gioi & Randall, "A Sub-Pixel Edge Detector: an
Implementation of the Canny/Devernay Algorithm", IPOL 7 (2017) 347-372.

Per candidate pixel p = (x, y) (integers, OpenCV convention), exactly as the
IPOL code's ``compute_gradient`` / ``compute_edge_points``:

1. Gradient of the smoothed image G by centred differences, *unscaled* as in
   IPOL: gx = G(x+1, y) - G(x-1, y), gy = G(x, y+1) - G(x, y-1);
   |g| = sqrt(gx^2 + gy^2).  (The scale does not change the result.)
2. Interpolation axis d, horizontal or vertical only (IPOL never uses
   diagonals): d = (1, 0) if p is a horizontal local maximum of |g|
   (|g|(p) > |g|(p-d) and not |g|(p+d) > |g|(p)) and |gx| >= |gy|; otherwise
   d = (0, 1) if p is a vertical local maximum (same test along y) and
   |gx| <= |gy|.  "a > b" is IPOL's ``greater``: a > b and a - b >= 1000 DBL_EPSILON.
3. a = |g|(p - d), b = |g|(p), c = |g|(p + d);
   eta = 1/2 (a - c) / (a - 2b + c); the point is p + eta d.

Choices this project makes (the paper leaves them to the detector around it):

- Smoothed image: the shared candidates' ``cand.smoothed`` (OpenCV Gaussian,
  sigma = ``cand.sigma_px``, reflected border) instead of IPOL's own truncated
  Gaussian kernel, so that every method of the study sees the same smoothing.
  The gradient operator itself is IPOL's (centred differences), *not* the Sobel
  field the candidates' normals came from.
- Candidates: the shared Canny candidates (OpenCV NMS with diagonal directions,
  hysteresis) instead of IPOL's own maxima test + chaining.  A candidate that is
  not an IPOL local maximum along either axis (IPOL would emit no point there:
  this happens near 45 degrees, where OpenCV's NMS compares diagonal neighbours)
  is returned as the candidate pixel with ``converged=False``.  Then the local
  maximum condition guarantees a - 2b + c < 0 and |eta| <= 1/2.
- ``strict=False`` (not IPOL, off by default) refines those candidates too:
  axis d = the dominant gradient component (|gx| >= |gy|: horizontal), and the
  parabola is accepted when it is concave with |eta| <= 1.

Extras: ``offset`` (eta, px along the axis), ``axis`` (0 = horizontal, 1 = vertical,
-1 = not a local maximum).

Known behaviour: the parabola through three samples of a Gaussian-like gradient
profile is biased toward the pixel centre unless the edge sits on a pixel
centre or half way between two; at blur ~1 px (gradient profile width
sqrt(s^2 + sigma^2) ~ 1.4 px) the bias is a sinusoid-like function of the
subpixel offset with amplitude of a few hundredths of a pixel (1-D model: RMS
0.014 px, max 0.019 px).  Measured on noise-free Ideal edges at blur 1 px:
RMSE 0.011 px on straight edges (72 % of candidates are IPOL maxima), 0.048 px
on circles of radius 12-20 px (the gradient ridge of a blurred disk lies
inside the circle, and the axis is oblique to the normal); see the tests.
"""
from __future__ import annotations

import math

import numpy as np

from edgetruth.locate import footprints as FP
from edgetruth.locate.registry import register
from edgetruth.locate.result import Refinement
from edgetruth.jit import njit, prange  # numba, imported when a kernel is first called

#: IPOL's tolerance in ``greater(a, b)``: a - b must exceed 1000 * DBL_EPSILON.
GREATER_TOL = 1000.0 * np.finfo(np.float64).eps


# forceinline, not inline="always": LLVM inlines them (numba's own inlining at 11 call sites is slow to compile)
@njit(cache=True, forceinline=True)
def _greater(a, b):
    if a <= b:
        return False
    if (a - b) < 1000.0 * 2.220446049250313e-16:
        return False
    return True


@njit(cache=True, forceinline=True)
def _mod_g(g, x, y):
    gx = g[y, x + 1] - g[y, x - 1]
    gy = g[y + 1, x] - g[y - 1, x]
    return math.sqrt(gx * gx + gy * gy)


@njit(cache=True)
def _devernay_point(g, x, y, strict):
    """IPOL Devernay point at pixel (x, y): (x, y, eta, axis), axis -1 where there is none."""
    h, w = g.shape
    if x < 2 or y < 2 or x > w - 3 or y > h - 3:
        return float(x), float(y), 0.0, -1
    gxa = abs(g[y, x + 1] - g[y, x - 1])
    gya = abs(g[y + 1, x] - g[y - 1, x])
    mod = _mod_g(g, x, y)
    left = _mod_g(g, x - 1, y)
    right = _mod_g(g, x + 1, y)
    down = _mod_g(g, x, y - 1)
    up = _mod_g(g, x, y + 1)
    dx = 0
    dy = 0
    if _greater(mod, left) and not _greater(right, mod) and gxa >= gya:
        dx = 1
    elif _greater(mod, down) and not _greater(up, mod) and gxa <= gya:
        dy = 1
    if dx == 0 and dy == 0:
        if strict:
            return float(x), float(y), 0.0, -1
        # non-IPOL fallback: the dominant gradient axis, any concave parabola with |eta| <= 1
        if gxa >= gya:
            dx = 1
        else:
            dy = 1
    a = _mod_g(g, x - dx, y - dy)
    c = _mod_g(g, x + dx, y + dy)
    den = a - mod - mod + c
    if not strict and not (den < 0.0 and abs(0.5 * (a - c)) <= -den):
        return float(x), float(y), 0.0, -1
    eta = 0.5 * (a - c) / den
    return x + eta * dx, y + eta * dy, eta, 0 if dx == 1 else 1


@njit(cache=True, parallel=True)
def _devernay_kernel(g, xs, ys, strict, out_x, out_y, out_eta, out_axis):
    # the per-point work in its own function: numba's parallel pass is slow on a large loop body
    for i in prange(xs.shape[0]):
        out_x[i], out_y[i], out_eta[i], out_axis[i] = _devernay_point(g, xs[i], ys[i], strict)


def devernay_points(smoothed: np.ndarray, xs: np.ndarray, ys: np.ndarray, strict: bool = True):
    """IPOL Devernay points at integer pixels (xs, ys) of the smoothed image.

    Returns x, y, eta, axis (axis -1: no point, which is the pixel itself)."""
    n = xs.shape[0]
    out_x = np.empty(n)
    out_y = np.empty(n)
    eta = np.empty(n)
    axis = np.empty(n, np.int64)
    if n:
        _devernay_kernel(np.ascontiguousarray(smoothed, np.float64), np.asarray(xs, np.int64),
                         np.asarray(ys, np.int64), bool(strict), out_x, out_y, eta, axis)
    return out_x, out_y, eta, axis


def devernay_footprint(cand, **options):
    """|g| at p and its four neighbours (the axis test and the parabola), each from G at +-1 in x and y:
    the diamond |dx| + |dy| <= 2 of the smoothed image, widened by the Gaussian kernel's reach."""
    dy, dx = np.mgrid[-2:3, -2:3]
    m = FP.pattern_masks(len(cand), np.abs(dx) + np.abs(dy) <= 2)
    return FP.dilate(m, FP.gaussian_radius_px(cand.sigma_px))


@register("canny_devernay", "Canny–Devernay", family="baseline", footprint=devernay_footprint)
def canny_devernay(image, cand, strict: bool = True, **options) -> Refinement:
    """Canny–Devernay: IPOL 2017 parabola through |g| at p-d, p, p+d (d horizontal or vertical)."""
    x, y, eta, axis = devernay_points(cand.smoothed, cand.x.astype(np.int64), cand.y.astype(np.int64), strict)
    conv = axis >= 0
    return Refinement(x, y, conv, extras={"offset": eta, "axis": axis})
