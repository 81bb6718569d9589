"""PAE2013: subpixel edges from the partial area effect (Trujillo-Pino et al. 2013).

A. Trujillo-Pino, K. Krissian, M. Aleman-Flores, D. Santana-Cedres,
"Accurate subpixel edge location based on partial area effect",
Image and Vision Computing 31(1):72-90, 2013.

Model: pixel values are area means of a step with levels A and B separated by
a curve through a window of three lines (columns for a mostly horizontal
edge, rows for a mostly vertical one); the sum of each line measures where the
curve crosses it.  Written in OpenCV axes for a mostly horizontal edge
(|gy| >= |gx| at the pixel): the lines are the columns x - 1, x, x + 1 (L, M, R)
and offsets run along rows; a mostly vertical edge is the transpose.

Variants (``variant=``):

``"floating"`` (default): the authors' released detector (their code, and its
    faithful port, the PyPI package ``subpixel-edges``; "iters = 0", for images
    without smoothing).  The three lines have *floating* limits: from the pixel,
    each line grows row by row, up to 3 or 4 rows each way (the longer reach on
    the side the slope makes the edge run to), while the magnitude of the
    across-derivative keeps falling -- so the window ends where the edge's
    blur has died out (or a neighbouring edge begins), not at a fixed 2 rows.
    With line sums S_L, S_M, S_R over limits [l1, l2], [m1, m2], [r1, r2] and
    the levels A (bright-row end) and B (other end), each the mean of two end
    pixels (the M line's and the L or R line's, by the slope sign),

        c = (S_L + S_R - 2 S_M + A (2 m2 - l2 - r2) - B (2 m1 - l1 - r1)) / (2 (A - B))   (0 for order 1)
        b = (S_R - S_L + A (l2 - r2) - B (l1 - r1)) / (2 (A - B))
        a = (2 S_M - A (1 + 2 m2) - B (1 - 2 m1)) / (2 (A - B)) - w c,    w = 1/12,

    and the point is (x, y - a) (horizontal) or (x - a, y) (vertical).  The
    derivatives are centred differences (g(x+1) - g(x-1)) / 2.  Initial limits
    and reaches follow the released code, including its near-axis rule (an
    along-derivative below 1 gray level per px starts every line at +-1).

``"smoothed"``: the authors' detector for noisy images ("iters = 1", paper
    Sec. 5): the image is first smoothed with their 3x3 mask (box 1/9 by
    default; ``a01``/``a11`` change it), limits float on the smoothed
    derivative, the sums *and A, B* are read from the smoothed image G, and the
    mask's effect on the curvature enters as w = (1 + 24 a01 + 48 a11) / 12.
    Their check for a second edge just beyond a line's end (a derivative >
    1/4 of the pixel's and > threshold / 2 two rows further) is implemented:
    the far side of the local window is then replaced by the level read on the
    unsmoothed image and re-smoothed locally, as in their code.

``"basic"``: the paper's basic first-order detector (Sec. 3) on a fixed 3 x 5
    window: S over rows -2..2, A and B the means of the three window pixels
    farthest from the edge on each side.  Exact on an unblurred straight step,
    biased on blurred edges (the window cuts the blur tails: a 1-D model
    predicts 0.160 px RMSE at blur 1 px, measured 0.156).  ``"first_order"`` is
    accepted as its former name.

Candidates (the study's unified framework): the shared Canny candidates
instead of the authors' own edge pixels.  The authors' detector emits a point
only at a pixel whose across-derivative magnitude is a maximum along its line
(>= the previous, > the next pixel) with |g_across| >= |g_along| (strictly > for
vertical edges).  For a candidate that is not such a pixel, the floating and
smoothed variants first move to the neighbouring pixel (one step along the
line, toward the larger derivative) when that one is; otherwise -- or when the
window would leave the image, A = B, or |a| >= 1 (the authors' validity
limit) -- the candidate is declined: ``converged=False`` at the candidate pixel.
On each accepted pixel the result equals the released detector's to rounding
(tests, against stored outputs of ``subpixel-edges`` 0.1.1).  ``threshold``
(gray levels per px; default: the candidates' Canny low threshold) only enters
the smoothed variant's second-edge test.

Extras: ``offset`` (a, px along the window axis), ``slope`` (b),
``curvature_coef`` (c), ``curvature`` (the authors' 2 c s / (1 + b^2)^1.5),
``level_a``, ``level_b``, ``axis`` (0: edge mostly horizontal, column lines;
1: mostly vertical, row lines), ``moved`` (pixels moved along the line to the
authors' edge pixel, -1/0/+1).
"""
from __future__ import annotations

import math

import cv2
import numpy as np

from edgetruth.errors import InputError
from edgetruth.locate import footprints as FP
from edgetruth.locate.registry import register
from edgetruth.locate.result import Refinement
from edgetruth.jit import njit, prange  # numba, imported when a kernel is first called

VARIANTS = ("floating", "smoothed", "basic")
ALIASES = {"first_order": "basic"}
A01_DEFAULT = 1.0 / 9.0  # the authors' released mask: 3x3 box
A11_DEFAULT = 1.0 / 9.0
NEAR_AXIS_GRAD = 1.0  # released detector: along-derivative below this (gray levels / px) starts lines at +-1
MAX_VALID_OFFSET = 1.0
#: how far the floating windows index the image arrays from the pixel: +-5 across (lines reach +-4,
#: the derivative comparisons and the second-edge test one and two further, the local patch +-5),
#: +-2 along (the second-edge test reads the lines two beyond the centre one)
REACH_ACROSS = 5
REACH_ALONG = 2
N_OUT = 11


# The pixel helpers are called ~60 times with literal offsets: compiled for one signature (each literal would
# compile another), inlined by LLVM (numba's own inlining of ~60 call sites is slow to compile).
_PX_SIG = "float64(float64[:, ::1], int64, int64, boolean, int64, int64)"


@njit(signature_or_function=_PX_SIG, cache=True, forceinline=True)
def _px(img, x, y, horiz, along, across):
    """img at the pixel ``along`` lines and ``across`` rows from (x, y) (transposed for vertical edges)."""
    if horiz:
        return img[y + across, x + along]
    return img[y + along, x + across]


@njit(signature_or_function=_PX_SIG, cache=True, forceinline=True)
def _ad(gc, x, y, horiz, along, across):
    """|gc| at that pixel."""
    if horiz:
        return abs(gc[y + across, x + along])
    return abs(gc[y + along, x + across])


@njit(cache=True)
def _is_edge_pixel(ga, gc, x, y, horiz):
    """The authors' edge-pixel test at (x, y): |g_across| maximal along the line, dominant over |g_along|."""
    v = abs(_px(gc, x, y, horiz, 0, 0))
    if horiz:
        if not v >= abs(ga[y, x]):
            return False
    else:
        if not v > abs(ga[y, x]):
            return False
    return v >= _ad(gc, x, y, horiz, 0, -1) and v > _ad(gc, x, y, horiz, 0, 1)


@njit(cache=True)
def floating_one(F, G, ga, gc, x, y, horiz, smoothed, order, w, threshold, out):
    """The released detector's floating-window estimate at edge pixel (x, y).

    F: image, G: the image the windows read (F itself, or the smoothed image), ga/gc: along/across
    centred derivatives of G in image axes (gx, gy for a horizontal edge).  out <- [a, b, c, A, B,
    valid, curvature, nx, ny] (out[9:] untouched); a, b, c in window axes (module docstring)."""
    for k in range(9):
        out[k] = math.nan
    out[5] = 0.0
    g_along = _px(ga, x, y, horiz, 0, 0)
    g_across = _px(gc, x, y, horiz, 0, 0)
    m1 = -1
    m2 = 1
    pos = ga[y, x] * gc[y, x] >= 0.0
    m = 1 if pos else -1
    if smoothed:
        l1 = -1; l2 = 1; r1 = -1; r2 = 1
    elif pos:
        l1 = 0; l2 = 1; r1 = -1; r2 = 0
    else:
        l1 = -1; l2 = 0; r1 = 0; r2 = 1
    if pos:
        min_l1 = -3; max_l2 = 4; min_r1 = -4; max_r2 = 3
    else:
        min_l1 = -4; max_l2 = 3; min_r1 = -3; max_r2 = 4
    if not smoothed and abs(g_along) < NEAR_AXIS_GRAD:
        l1 = -1; l2 = 1; r1 = -1; r2 = 1
    while l1 > min_l1 and _ad(gc, x, y, horiz, -1, l1) >= _ad(gc, x, y, horiz, -1, l1 - 1):
        l1 -= 1
    while l2 < max_l2 and _ad(gc, x, y, horiz, -1, l2) >= _ad(gc, x, y, horiz, -1, l2 + 1):
        l2 += 1
    while m1 > -4 and _ad(gc, x, y, horiz, 0, m1) >= _ad(gc, x, y, horiz, 0, m1 - 1):
        m1 -= 1
    while m2 < 4 and _ad(gc, x, y, horiz, 0, m2) >= _ad(gc, x, y, horiz, 0, m2 + 1):
        m2 += 1
    while r1 > min_r1 and _ad(gc, x, y, horiz, 1, r1) >= _ad(gc, x, y, horiz, 1, r1 - 1):
        r1 -= 1
    while r2 < max_r2 and _ad(gc, x, y, horiz, 1, r2) >= _ad(gc, x, y, horiz, 1, r2 + 1):
        r2 += 1
    if m > 0:
        la = 0.5 * (_px(G, x, y, horiz, 0, m2) + _px(G, x, y, horiz, 1, r2))
        lb = 0.5 * (_px(G, x, y, horiz, -1, l1) + _px(G, x, y, horiz, 0, m1))
    else:
        la = 0.5 * (_px(G, x, y, horiz, -1, l2) + _px(G, x, y, horiz, 0, m2))
        lb = 0.5 * (_px(G, x, y, horiz, 0, m1) + _px(G, x, y, horiz, 1, r1))
    up = False
    down = False
    if smoothed:
        ref = abs(g_across)
        if m1 > -4:
            v = _ad(gc, x, y, horiz, 0, m1 - 2)
            up = v > ref / 4.0 and v > threshold / 2.0
        if m2 < 4:
            v = _ad(gc, x, y, horiz, 0, m2 + 2)
            down = v > ref / 4.0 and v > threshold / 2.0
    sl = 0.0
    sm = 0.0
    sr = 0.0
    if up or down:
        # a second edge just beyond a line's end: local 11 x 5 patch of F (across x along), its far
        # side set to the level read on F, re-smoothed with the box before summing (released code)
        patch = np.empty((11, 5))
        for i in range(11):
            for j in range(5):
                patch[i, j] = _px(F, x, y, horiz, j - 2, i - 5)
        sgn = 1.0 if g_across > 0.0 else (-1.0 if g_across < 0.0 else 0.0)
        if up:
            if m > 0:
                lb = 0.5 * (_px(F, x, y, horiz, 0, m1) + _px(F, x, y, horiz, -1, l1))
                p = 1
            else:
                lb = 0.5 * (_px(F, x, y, horiz, 0, m1) + _px(F, x, y, horiz, 1, r1))
                p = 0
            ll = l1 + p - 1 if _px(gc, x, y, horiz, -2, l1 + p) * sgn > 0.0 else l1 + p
            rr = r1 - p if _px(gc, x, y, horiz, 2, r1 + 1 - p) * sgn > 0.0 else r1 + 1 - p
            lim = (ll, l1, m1, r1, rr)
            for j in range(5):
                for i in range(0, lim[j] + 6):
                    patch[i, j] = lb
            l1 = -3 + m
            m1 = -3
            r1 = -3 - m
        if down:
            if m > 0:
                la = 0.5 * (_px(F, x, y, horiz, 0, m2) + _px(F, x, y, horiz, 1, r2))
                p = 1
            else:
                la = 0.5 * (_px(F, x, y, horiz, 0, m2) + _px(F, x, y, horiz, -1, l2))
                p = 0
            ll = l2 + p if _px(gc, x, y, horiz, -2, l2 + p - 1) * sgn > 0.0 else l2 + p - 1
            rr = r2 + 1 - p if _px(gc, x, y, horiz, 2, r2 - p) * sgn > 0.0 else r2 - p
            lim = (ll, l2, m2, r2, rr)
            for j in range(5):
                for i in range(lim[j] + 5, 11):
                    patch[i, j] = la
            l2 = 3 + m
            m2 = 3
            r2 = 3 - m
        lims = ((l1, l2), (m1, m2), (r1, r2))
        sums = np.zeros(3)
        for j in range(3):
            lo, hi = lims[j]
            for n in range(lo, hi + 1):
                i = n + 4  # rows of the re-smoothed 9 x 3 patch: offsets -4..4
                acc = 0.0
                for di in range(3):
                    for dj in range(3):
                        acc += patch[i + di, j + dj]
                sums[j] += acc / 9.0
        sl = sums[0]
        sm = sums[1]
        sr = sums[2]
    else:
        for n in range(l1, l2 + 1):
            sl += _px(G, x, y, horiz, -1, n)
        for n in range(m1, m2 + 1):
            sm += _px(G, x, y, horiz, 0, n)
        for n in range(r1, r2 + 1):
            sr += _px(G, x, y, horiz, 1, n)
    den = 2.0 * (la - lb)
    out[3] = la
    out[4] = lb
    if den == 0.0:
        return
    c = 0.0
    if order == 2:
        c = (sl + sr - 2.0 * sm + la * (2 * m2 - l2 - r2) - lb * (2 * m1 - l1 - r1)) / den
    b = (sr - sl + la * (l2 - r2) - lb * (l1 - r1)) / den
    a = (2.0 * sm - la * (1 + 2 * m2) - lb * (1 - 2 * m1)) / den - w * c
    out[0] = a
    out[1] = b
    out[2] = c
    q = 1.0 / math.sqrt(1.0 + b * b)
    sab = 1.0 if la > lb else (-1.0 if la < lb else 0.0)
    if horiz:
        out[7] = sab * b * q
        out[8] = sab * q
    else:
        out[7] = sab * q
        out[8] = sab * b * q
    nn = -1.0 if g_across < 0.0 else 1.0
    out[6] = 2.0 * c * nn * q * q * q
    if math.isfinite(a) and math.isfinite(b) and (not smoothed or abs(a) < MAX_VALID_OFFSET):
        out[5] = 1.0


@njit(cache=True, parallel=True)
def _floating_kernel(F, G, gx, gy, xs, ys, smoothed, order, w, threshold, out, moved):
    h, wd = F.shape
    for i in prange(xs.shape[0]):
        x = xs[i]
        y = ys[i]
        for k in range(N_OUT):
            out[i, k] = math.nan
        out[i, 5] = 0.0
        moved[i] = 0
        horiz = abs(gy[y, x]) >= abs(gx[y, x])
        out[i, 9] = 0.0 if horiz else 1.0
        ga = gx if horiz else gy
        gc = gy if horiz else gx
        if not _is_edge_pixel(ga, gc, x, y, horiz):
            # one step along the line, toward the larger across-derivative
            step = 1 if _ad(gc, x, y, horiz, 0, 1) > _ad(gc, x, y, horiz, 0, -1) else -1
            nx_ = x + (step if not horiz else 0)
            ny_ = y + (step if horiz else 0)
            if nx_ < 1 or ny_ < 1 or nx_ > wd - 2 or ny_ > h - 2:
                continue
            # the moved pixel must keep the orientation and be an edge pixel itself
            if (abs(gy[ny_, nx_]) >= abs(gx[ny_, nx_])) != horiz or not _is_edge_pixel(ga, gc, nx_, ny_, horiz):
                continue
            x = nx_
            y = ny_
            moved[i] = step
        ra = REACH_ALONG if horiz else REACH_ACROSS
        rc = REACH_ACROSS if horiz else REACH_ALONG
        if x - ra < 0 or x + ra > wd - 1 or y - rc < 0 or y + rc > h - 1:
            continue
        floating_one(F, G, ga, gc, x, y, horiz, smoothed, order, w, threshold, out[i])
        out[i, 10] = float(moved[i])


@njit(cache=True, parallel=True)
def _basic_kernel(f, xs, ys, gxs, gys, order, out):
    """The paper's basic first-order detector on a fixed 3 x 5 window (Sec. 3); out[0] = a with the
    point at (x, y + a) / (x + a, y): A is the level above the curve, B below."""
    h, w = f.shape
    for i in prange(xs.shape[0]):
        x = int(xs[i])
        y = int(ys[i])
        gx = gxs[i]
        gy = gys[i]
        horiz = abs(gy) >= abs(gx)
        m = 1 if gx * gy < 0.0 else -1
        for k in range(N_OUT):
            out[i, k] = math.nan
        out[i, 5] = 0.0
        out[i, 9] = 0.0 if horiz else 1.0
        out[i, 10] = 0.0
        if x - 2 < 0 or y - 2 < 0 or x + 2 > w - 1 or y + 2 > h - 1:
            continue
        sl = 0.0
        sm = 0.0
        sr = 0.0
        for k in range(-2, 3):
            sl += _px(f, x, y, horiz, -1, k)
            sm += _px(f, x, y, horiz, 0, k)
            sr += _px(f, x, y, horiz, 1, k)
        la = (_px(f, x, y, horiz, 0, -2) + _px(f, x, y, horiz, m, -2) + _px(f, x, y, horiz, m, -1)) / 3.0
        lb = (_px(f, x, y, horiz, 0, 2) + _px(f, x, y, horiz, -m, 2) + _px(f, x, y, horiz, -m, 1)) / 3.0
        den = 2.0 * (la - lb)
        out[i, 3] = la
        out[i, 4] = lb
        if not abs(la - lb) > 1e-12 * (abs(la) + abs(lb)):
            continue
        c = (sl + sr - 2.0 * sm) / den if order == 2 else 0.0
        b = (sr - sl) / den
        a = (2.0 * sm - 5.0 * (la + lb)) / den - c / 12.0
        out[i, 0] = a
        out[i, 1] = b
        out[i, 2] = c
        # normal of the fitted line at the point, dark -> bright
        sgn = 1.0 if lb > la else -1.0
        q = 1.0 / math.sqrt(1.0 + b * b)
        if horiz:
            out[i, 7] = -sgn * b * q
            out[i, 8] = sgn * q
        else:
            out[i, 7] = sgn * q
            out[i, 8] = -sgn * b * q
        out[i, 6] = 2.0 * c * sgn * q * q * q
        if math.isfinite(a) and math.isfinite(b) and abs(a) <= 1.0:
            out[i, 5] = 1.0


def smoothing_mask(a01: float = A01_DEFAULT, a11: float = A11_DEFAULT) -> np.ndarray:
    """The paper's symmetric 3x3 mask [[a11, a01, a11], [a01, a00, a01], [a11, a01, a11]], a00 = 1 - 4 a01 - 4 a11."""
    a00 = 1.0 - 4.0 * a01 - 4.0 * a11
    if not (a01 >= 0.0 and a11 >= 0.0 and a00 >= 0.0):
        raise InputError(f"a01={a01}, a11={a11}: the mask needs a01, a11 >= 0 and a00 = 1 - 4 a01 - 4 a11 >= 0")
    return np.array([[a11, a01, a11], [a01, a00, a01], [a11, a01, a11]])


def centred_gradient(g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(g(x+1) - g(x-1)) / 2 and (g(y+1) - g(y-1)) / 2, zero on the border lines (the released code)."""
    gx = np.zeros_like(g)
    gy = np.zeros_like(g)
    gx[:, 1:-1] = 0.5 * (g[:, 2:] - g[:, :-2])
    gy[1:-1, :] = 0.5 * (g[2:, :] - g[:-2, :])
    return gx, gy


def prepare(image, variant: str, a01: float = A01_DEFAULT, a11: float = A11_DEFAULT):
    """(F, G, gx, gy, w): the image, the image the windows read, its centred derivatives, the curvature factor."""
    f = np.ascontiguousarray(image, np.float64)
    if variant == "smoothed":
        # zero padding at the border, as the released code (scipy.ndimage.convolve, mode='constant')
        g = cv2.filter2D(f, cv2.CV_64F, smoothing_mask(a01, a11), borderType=cv2.BORDER_CONSTANT)
        w = (1.0 + 24.0 * a01 + 48.0 * a11) / 12.0
    else:
        g = f
        w = 1.0 / 12.0
    gx, gy = centred_gradient(g)
    return f, g, gx, gy, w


def edge_pixels(gx, gy, threshold: float, margin_rows: int = 5, margin_cols: int = 2):
    """The released detector's own edge pixels: (xs, ys, horizontal) -- for comparisons with it."""
    ax, ay = np.abs(gx), np.abs(gy)
    mag = np.hypot(gx, gy)
    h, w = gx.shape
    ey = np.zeros((h, w), bool)
    ex = np.zeros((h, w), bool)
    r, c = slice(margin_rows, h - margin_rows), slice(margin_cols, w - margin_cols)
    ey[r, c] = ((mag[r, c] > threshold) & (ay[r, c] >= ax[r, c]) & (ay[r, c] >= ay[margin_rows - 1:h - margin_rows - 1, c])
                & (ay[r, c] > ay[margin_rows + 1:h - margin_rows + 1, c]))
    r, c = slice(margin_cols, h - margin_cols), slice(margin_rows, w - margin_rows)
    ex[r, c] = ((mag[r, c] > threshold) & (ax[r, c] > ay[r, c]) & (ax[r, c] >= ax[r, margin_rows - 1:w - margin_rows - 1])
                & (ax[r, c] > ax[r, margin_rows + 1:w - margin_rows + 1]))
    yh, xh = np.nonzero(ey.T)[::-1]  # column-major order, as the released code lists them
    yv, xv = np.nonzero(ex.T)[::-1]
    xs = np.r_[xh, xv].astype(np.int64)
    ys = np.r_[yh, yv].astype(np.int64)
    return xs, ys, np.r_[np.ones(xh.size, bool), np.zeros(xv.size, bool)]


def detect(image, threshold: float, variant: str = "floating", order: int = 2,
           a01: float = A01_DEFAULT, a11: float = A11_DEFAULT) -> dict:
    """The released detector end to end (its own edge pixels, no Canny): arrays x, y, nx, ny, curv, i0, i1, valid."""
    variant = _check(variant, order)
    if variant == "basic":
        raise InputError("detect() runs the floating-window detector; variant must be 'floating' or 'smoothed'")
    F, G, gx, gy, w = prepare(image, variant, a01, a11)
    xs, ys, horiz = edge_pixels(gx, gy, threshold)
    out = np.empty((xs.size, N_OUT))
    _points_at(F, G, gx, gy, xs, ys, horiz, variant == "smoothed", order, w, threshold, out)
    a = out[:, 0]
    x = np.where(horiz, xs, xs - a)
    y = np.where(horiz, ys - a, ys)
    return {"x": x, "y": y, "nx": out[:, 7], "ny": out[:, 8], "curv": out[:, 6],
            "i0": np.minimum(out[:, 3], out[:, 4]), "i1": np.maximum(out[:, 3], out[:, 4]),
            "valid": out[:, 5] > 0.5, "horizontal": horiz}


@njit(cache=True)
def _points_at(F, G, gx, gy, xs, ys, horiz, smoothed, order, w, threshold, out):
    for i in range(xs.shape[0]):
        if horiz[i]:
            floating_one(F, G, gx, gy, xs[i], ys[i], True, smoothed, order, w, threshold, out[i])
        else:
            floating_one(F, G, gy, gx, xs[i], ys[i], False, smoothed, order, w, threshold, out[i])


def _check(variant, order):
    variant = ALIASES.get(variant, variant)
    if variant not in VARIANTS:
        raise InputError(f"variant={variant!r}: choose one of {', '.join(VARIANTS)}")
    if order not in (1, 2):
        raise InputError(f"order={order}: 1 (straight line) or 2 (parabola)")
    return variant


def pae_refine(image, cand, variant: str = "floating", order: int = 2, a01: float = A01_DEFAULT,
               a11: float = A11_DEFAULT, threshold: float | None = None) -> Refinement:
    variant = _check(variant, order)
    n = len(cand)
    out = np.zeros((n, N_OUT))
    moved = np.zeros(n, np.int64)
    xi = cand.x.astype(np.int64)
    yi = cand.y.astype(np.int64)
    if variant == "basic":
        if n:
            _basic_kernel(np.ascontiguousarray(image, np.float64), xi, yi, cand.grad_x[yi, xi], cand.grad_y[yi, xi],
                          int(order), out)
    else:
        thr = float(cand.thresholds[0] if threshold is None else threshold)
        if not (np.isfinite(thr) and thr >= 0):
            raise InputError(f"threshold={threshold}: must be a number >= 0 (gray levels per px)")
        F, G, gx, gy, w = prepare(image, variant, a01, a11)
        if n:
            _floating_kernel(F, G, gx, gy, xi, yi, variant == "smoothed", int(order), w, thr, out, moved)
    conv = out[:, 5] > 0.5
    # offset along the window axis: the released detector's point is the pixel minus a, the basic one's plus a
    a = np.where(conv, out[:, 0] if variant == "basic" else -out[:, 0], 0.0)
    horiz = out[:, 9] < 0.5
    step = np.where(conv, out[:, 10], 0.0)
    step = np.where(np.isfinite(step), step, 0.0)
    # the point lies in the (possibly moved) pixel's line
    x = cand.x + np.where(horiz, 0.0, step + a)
    y = cand.y + np.where(horiz, step + a, 0.0)
    nx = np.where(conv, out[:, 7], cand.nx)
    ny = np.where(conv, out[:, 8], cand.ny)
    return Refinement(x, y, conv, nx, ny, extras={
        "offset": a, "slope": out[:, 1], "curvature_coef": out[:, 2], "curvature": out[:, 6],
        "level_a": out[:, 3], "level_b": out[:, 4], "axis": out[:, 9].astype(np.int64),
        "moved": step.astype(np.int64)})


def pae_footprint(cand, variant: str = "floating", **options):
    """basic: the 3 x 5 window in the candidate's orientation.  floating: the three lines +-6 rows around
    the (possibly moved, +-1) pixel -- windows to +-4, derivative comparisons to +-5, centred
    differences one further; smoothed: +-2 lines (second-edge test) and the patch, widened by the
    3x3 mask.  The floating variants' orientation comes from their own derivatives: both orientations."""
    variant = ALIASES.get(variant, variant)
    n = len(cand)
    if variant == "basic":
        xi, yi = cand.x.astype(np.int64), cand.y.astype(np.int64)
        horiz = np.abs(cand.grad_y[yi, xi]) >= np.abs(cand.grad_x[yi, xi])
        return np.where(horiz[:, None, None], FP.block_masks(n, 2, 1), FP.block_masks(n, 1, 2))
    along, across = (1, 7) if variant == "floating" else (3, 8)
    return FP.block_masks(n, across, along) | FP.block_masks(n, along, across)


@register("pae2013", "PAE2013", family="baseline", footprint=pae_footprint)
def pae2013(image, cand, variant: str = "floating", order: int = 2, a01: float = A01_DEFAULT,
            a11: float = A11_DEFAULT, threshold: float | None = None) -> Refinement:
    """PAE2013: the authors' floating-window partial-area detector (variant="smoothed": on the 3x3-smoothed
    image; variant="basic": the paper's fixed 3x5 window)."""
    return pae_refine(image, cand, variant, order, a01, a11, threshold)
