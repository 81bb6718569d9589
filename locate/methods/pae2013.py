"""PAE2013: subpixel edges from the partial area effect (Trujillo-Pino et al. 2013).

A. Trujillo-Pino, K. Krissian, M. Aleman-Flores, D. Santana-Cedres,
"Accurate subpixel edge location based on partial area effect",
Image and Vision Computing 31(1):72-90, 2013.

Model: pixel values are area means of an ideal step with levels A and B
separated by a curve through the window, F = B + (A - B) P, P the area
fraction on the A side.  Written here in OpenCV axes (y down) for an edge that
is mostly horizontal (|gy| >= |gx| at the candidate): y = a + b x (+ c x^2),
coordinates relative to the candidate pixel centre; A is the level *above*
the curve (y < a + b x), B the level below.  For a mostly vertical edge
(|gx| > |gy|) everything is transposed: x = a + b y, A on the left; rows
play the role of columns.

First-order case (``variant="first_order"``, registered as ``pae2013``):
a 3-column x 5-row window centred on the candidate; column sums
S_L, S_M, S_R over rows -2..2 of columns -1, 0, +1.  Because the line crosses
every column inside the window (|b| <= 1, |a| <= 1/2),

    S_j = 5/2 (A + B) + (A - B)(a + b j)          exactly, so
    a = (2 S_M - 5 (A + B)) / (2 (A - B)),   b = (S_R - S_L) / (2 (A - B)).

``order=2`` adds the paper's parabola y = a + b x + c x^2:
c = (S_L + S_R - 2 S_M) / (2 (A - B)) and a -= c/12.
A and B are the means of the three window pixels farthest from the edge on
each side (paper, Sec. 3): with m = +1 if b > 0 (gx gy < 0 in these axes),
else -1:  A = (F[-2, 0] + F[-2, m] + F[-1, m]) / 3,
          B = (F[+2, 0] + F[+2, -m] + F[+1, -m]) / 3     ([row, col] offsets).
The edge point is (x_c, y_c + a) (horizontal) or (x_c + a, y_c) (vertical),
which lies on the estimated edge; the method's normal is the normal of the
fitted line, oriented dark -> bright.

Smoothed case (``variant="smoothed"``, paper Sec. 5): the image is first
smoothed with the symmetric 3x3 mask [[a11, a01, a11], [a01, a00, a01],
[a11, a01, a11]], a00 = 1 - 4 a01 - 4 a11, giving G; the column sums run over
7 rows shifted by the slope sign m (S_L: rows -3-m..3-m, S_M: -3..3,
S_R: -3+m..3+m), A and B come from F at rows -/+4, -/+3, and

    c = (S_L + S_R - 2 S_M) / (2 (A - B))      (0 for order=1)
    b = m + (S_R - S_L) / (2 (A - B))
    a = (2 S_M - 7 (A + B)) / (2 (A - B)) - (1 + 24 a01 + 48 a11) / 12 * c.

Default mask a01 = 0.125, a11 = 0.0625 (the binomial 1/16 [1 2 1; 2 4 2; 1 2 1]);
the paper's own numeric values were not available here -- pass ``a01``/``a11``
to change them.  Its floating-window extension for nearby edges is not
implemented (one edge per window is assumed).

Choices the paper leaves to the detector: the pixel-level candidates are the
shared Canny candidates (the paper uses its own gradient maxima per column);
the orientation test uses the candidates' smoothed gradient.
``converged=False`` where A = B, a result is non-finite, |a| > 1 (the edge
does not cross the candidate's neighbourhood, outside the model's validity),
or a smoothed-variant window leaves the image.

Known behaviour: exact (to rounding) on an unblurred straight step whose
line crosses the central pixel (|a| <= 1/2, |b| <= 1) -- the paper's claim,
checked in the tests.  On blurred edges the 5-row window truncates the blur
tails and A, B are taken where the profile has not reached its plateaus, so
the first-order case is biased toward the candidate pixel; at blur 1 px a 1-D
model predicts estimate = 0.445 x true offset, RMSE 0.160 px (measured 0.156 on
lines, 0.155 on circles).  The smoothed variant measures 0.015 px there.

Extras: ``offset`` (a, px along the window axis), ``slope`` (b), ``curvature_coef``
(c), ``level_a``, ``level_b``, ``axis`` (0: edge mostly horizontal, column sums;
1: mostly vertical, row sums).
"""
from __future__ import annotations

import math

import cv2
import numba
import numpy as np

from edgetruth.errors import InputError
from edgetruth.locate.registry import register
from edgetruth.locate.result import Refinement

VARIANTS = ("first_order", "smoothed")
A01_DEFAULT = 0.125
A11_DEFAULT = 0.0625


@numba.njit(cache=True, inline="always")
def _px(img, x, y, horiz, along, across):
    # horizontal edge: 'along' runs over columns, 'across' over rows
    if horiz:
        return img[y + across, x + along]
    return img[y + along, x + across]


@numba.njit(cache=True, parallel=True)
def _pae_kernel(f, g, xs, ys, gxs, gys, smoothed, order, corr, out):
    h, w = f.shape
    for i in numba.prange(xs.shape[0]):
        x = int(xs[i])
        y = int(ys[i])
        gx = gxs[i]
        gy = gys[i]
        horiz = abs(gy) >= abs(gx)
        m = 1 if gx * gy < 0.0 else -1
        for k in range(9):
            out[i, k] = math.nan
        out[i, 8] = 0.0
        out[i, 7] = 0.0 if horiz else 1.0
        if smoothed:
            reach = 4
        else:
            reach = 2
        if x - reach < 0 or y - reach < 0 or x + reach > w - 1 or y + reach > h - 1:
            continue
        sl = 0.0
        sm = 0.0
        sr = 0.0
        if smoothed:
            for k in range(-3, 4):
                sl += _px(g, x, y, horiz, -1, k - m)
                sm += _px(g, x, y, horiz, 0, k)
                sr += _px(g, x, y, horiz, 1, k + m)
            la = (_px(f, x, y, horiz, 0, -4) + _px(f, x, y, horiz, m, -4) + _px(f, x, y, horiz, m, -3)) / 3.0
            lb = (_px(f, x, y, horiz, 0, 4) + _px(f, x, y, horiz, -m, 4) + _px(f, x, y, horiz, -m, 3)) / 3.0
            nrow = 7.0
        else:
            for k in range(-2, 3):
                sl += _px(f, x, y, horiz, -1, k)
                sm += _px(f, x, y, horiz, 0, k)
                sr += _px(f, x, y, horiz, 1, k)
            la = (_px(f, x, y, horiz, 0, -2) + _px(f, x, y, horiz, m, -2) + _px(f, x, y, horiz, m, -1)) / 3.0
            lb = (_px(f, x, y, horiz, 0, 2) + _px(f, x, y, horiz, -m, 2) + _px(f, x, y, horiz, -m, 1)) / 3.0
            nrow = 5.0
        den = 2.0 * (la - lb)
        out[i, 3] = la
        out[i, 4] = lb
        if not abs(la - lb) > 1e-12 * (abs(la) + abs(lb)):
            continue
        c = (sl + sr - 2.0 * sm) / den if order == 2 else 0.0
        b = (sr - sl) / den
        if smoothed:
            b += m
        a = (2.0 * sm - nrow * (la + lb)) / den - corr * c
        out[i, 0] = a
        out[i, 1] = b
        out[i, 2] = c
        # normal of the fitted line at the point, dark -> bright
        sgn = 1.0 if lb > la else -1.0
        q = 1.0 / math.sqrt(1.0 + b * b)
        if horiz:
            out[i, 5] = -sgn * b * q
            out[i, 6] = sgn * q
        else:
            out[i, 5] = sgn * q
            out[i, 6] = -sgn * b * q
        if math.isfinite(a) and math.isfinite(b) and abs(a) <= 1.0:
            out[i, 8] = 1.0


def smoothing_mask(a01: float = A01_DEFAULT, a11: float = A11_DEFAULT) -> np.ndarray:
    a00 = 1.0 - 4.0 * a01 - 4.0 * a11
    if not (a00 > a01 > a11 >= 0.0):
        raise InputError(f"a01={a01}, a11={a11}: the paper's mask needs a00 > a01 > a11 >= 0, a00 = 1 - 4 a01 - 4 a11")
    return np.array([[a11, a01, a11], [a01, a00, a01], [a11, a01, a11]])


def pae_refine(image, cand, variant: str = "first_order", order: int = 1,
               a01: float = A01_DEFAULT, a11: float = A11_DEFAULT) -> Refinement:
    if variant not in VARIANTS:
        raise InputError(f"variant={variant!r}: choose one of {', '.join(VARIANTS)}")
    if order not in (1, 2):
        raise InputError(f"order={order}: 1 (straight line) or 2 (parabola)")
    f = np.ascontiguousarray(image, np.float64)
    smoothed = variant == "smoothed"
    if smoothed:
        g = cv2.filter2D(f, cv2.CV_64F, smoothing_mask(a01, a11), borderType=cv2.BORDER_REFLECT)
        corr = (1.0 + 24.0 * a01 + 48.0 * a11) / 12.0
    else:
        g = f
        corr = 1.0 / 12.0
    n = len(cand)
    out = np.zeros((n, 9))
    if n:
        xi = cand.x.astype(np.int64)
        yi = cand.y.astype(np.int64)
        _pae_kernel(f, g, xi, yi, cand.grad_x[yi, xi], cand.grad_y[yi, xi], smoothed, int(order), corr, out)
    conv = out[:, 8] > 0.5
    a = np.where(conv, out[:, 0], 0.0)
    horiz = out[:, 7] < 0.5
    x = cand.x + np.where(horiz, 0.0, a)
    y = cand.y + np.where(horiz, a, 0.0)
    nx = np.where(conv, out[:, 5], cand.nx)
    ny = np.where(conv, out[:, 6], cand.ny)
    return Refinement(x, y, conv, nx, ny, extras={
        "offset": a, "slope": out[:, 1], "curvature_coef": out[:, 2], "level_a": out[:, 3],
        "level_b": out[:, 4], "axis": out[:, 7].astype(np.int64)})


@register("pae2013", "PAE2013", family="baseline")
def pae2013(image, cand, variant: str = "first_order", order: int = 1,
            a01: float = A01_DEFAULT, a11: float = A11_DEFAULT, **options) -> Refinement:
    """PAE2013: partial-area-effect line fit on a 3x5 window (variant="smoothed": 3x3-smoothed, 3x7 windows)."""
    return pae_refine(image, cand, variant, order, a01, a11)
