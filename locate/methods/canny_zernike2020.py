"""Canny-Zernike2020: Canny candidates refined by Ghosal & Mehrotra's Zernike-moment edge operator.

S. Ghosal and R. Mehrotra, "Orthogonal moment operators for subpixel edge
detection", Pattern Recognition 26(2):295-306, 1993 -- the operator.  The
"Canny-Zernike" combination (Canny for pixel-level candidates, a 7x7
Zernike mask for the subpixel step) follows the 2020 variant the study
names (e.g. "Subpixel edge detection based on Canny-Zernike moment method",
J. Circuits, Systems and Computers 29(15), 2020); that paper's text was not
available here, so everything below is stated from Ghosal & Mehrotra's
model and the conventions common to its 7x7 variants.

Edge model: inside the unit disk, a straight step of height k at distance l
from the centre, the bright side in direction phi.  With
Z_nm = integral f V*_nm over the disk (no (n+1)/pi factor), V11 = rho e^{i theta},
V20 = 2 rho^2 - 1:

    Z11 e^{-i phi} = Z11' = 2k (1 - l^2)^{3/2} / 3   (real),
    Z20            = 2k l (1 - l^2)^{3/2} / 3,       so   l = Z20 / Z11'.

(Derived and checked in the tests: l > 0 puts the edge on the bright side of
the centre.)

Masks: the N x N (N = 7) pixel block centred on the candidate is scaled into
the unit disk by R = N/2 = 3.5 px (the disk is inscribed in the block).  Each
mask entry is the integral of the conjugate Zernike polynomial over the part of
that pixel inside the disk, in disk units:

    M11x = integral u,  M11y = integral v,  M20 = integral (2(u^2 + v^2) - 1),

u = (column offset)/R, v = (row offset)/R (OpenCV axes, y down), so Z11 =
sum f (M11x - i M11y) and we use the real pair (Cx, Cy) = (sum f M11x, sum f M11y):
phi = atan2(Cy, Cx), Z11' = hypot(Cx, Cy).  The masks are computed at import by
numeric integration (exact in v for each u, midpoint rule with 4000 nodes per
pixel in u; accuracy ~1e-7 per entry, limited by the sqrt edge of the disk), not typed in.

Point: p + R l (cos phi, sin phi) -- the scale factor N/2 converts l from disk
units to pixels.  The method's own normal (cos phi, sin phi) is returned.

Choices: the masks read the *unsmoothed* image (the operator is itself a
smoothing integral); no edge-strength / |l| threshold beyond the model's
domain: ``converged=False`` where Z11' = 0 or |l| >= 1 (the edge would not
cross the disk).  Ghosal & Mehrotra's ideal-step model ignores blur: on a
blurred edge the estimate is exact only when the edge passes through the
centre, and biased toward it otherwise (see the tests).

Extras: ``offset`` (R l, px along (cos phi, sin phi)), ``l``, ``k`` (step height
estimate 3 Z11' / (2 (1 - l^2)^{3/2})).
"""
from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from edgetruth.errors import InputError
from edgetruth.locate import footprints as FP
from edgetruth.locate.registry import register
from edgetruth.locate.result import Refinement
from edgetruth.jit import njit, prange  # numba, imported when a kernel is first called

MASK_SIZE = 7
_NODES_PER_PX = 4000


@lru_cache(maxsize=None)
def zernike_masks(n: int = MASK_SIZE, nodes_per_px: int = _NODES_PER_PX):
    """(M11x, M11y, M20), each (n, n) float64 [row, col], for the n x n block in the unit disk of radius n/2 px.

    Integration: for each column of pixels, u on a midpoint grid of ``nodes_per_px`` nodes per pixel;
    for each u the v-integral over the pixel's v-range clipped to |v| <= sqrt(1 - u^2) is exact."""
    r = n / 2.0
    half = n // 2
    du = 1.0 / (r * nodes_per_px)
    mx = np.zeros((n, n))
    my = np.zeros((n, n))
    m20 = np.zeros((n, n))
    for jc in range(n):
        u0 = (jc - half - 0.5) / r
        u = u0 + (np.arange(nodes_per_px) + 0.5) * du
        vmax = np.sqrt(np.clip(1.0 - u * u, 0.0, None))
        for ir in range(n):
            lo = np.maximum((ir - half - 0.5) / r, -vmax)
            hi = np.minimum((ir - half + 0.5) / r, vmax)
            ln = np.clip(hi - lo, 0.0, None)
            hi = lo + ln
            i0 = ln
            i1 = 0.5 * (hi * hi - lo * lo)
            i2 = (hi ** 3 - lo ** 3) / 3.0
            mx[ir, jc] = np.sum(u * i0) * du
            my[ir, jc] = np.sum(i1) * du
            m20[ir, jc] = np.sum((2.0 * u * u - 1.0) * i0 + 2.0 * i2) * du
    for m in (mx, my, m20):
        m.setflags(write=False)
    return mx, my, m20


@njit(cache=True, parallel=True)
def _zernike_kernel(img, xs, ys, mx, my, m20, out):
    n = mx.shape[0]
    half = n // 2
    r = n / 2.0
    for i in prange(xs.shape[0]):
        x = int(xs[i])
        y = int(ys[i])
        cx = 0.0
        cy = 0.0
        z20 = 0.0
        for a in range(n):
            for b in range(n):
                f = img[y - half + a, x - half + b]
                cx += f * mx[a, b]
                cy += f * my[a, b]
                z20 += f * m20[a, b]
        z11 = math.sqrt(cx * cx + cy * cy)
        out[i, 4] = 0.0
        if not z11 > 0.0:
            out[i, 0] = 0.0
            out[i, 1] = math.nan
            out[i, 2] = math.nan
            out[i, 3] = math.nan
            continue
        c = cx / z11
        s = cy / z11
        l = z20 / z11
        out[i, 0] = r * l
        out[i, 1] = l
        out[i, 2] = c
        out[i, 3] = s
        if abs(l) < 1.0 and math.isfinite(l):
            out[i, 4] = 1.0
        out[i, 5] = 1.5 * z11 / (1.0 - l * l) ** 1.5 if abs(l) < 1.0 else math.nan


def zernike_footprint(cand, mask_size: int = MASK_SIZE, **options):
    """The pixels with a non-zero weight in any of the three masks (the block less its outer corners)."""
    mx, my, m20 = zernike_masks(int(mask_size))
    return FP.pattern_masks(len(cand), (mx != 0) | (my != 0) | (m20 != 0))


@register("canny_zernike2020", "Canny–Zernike2020", family="baseline", footprint=zernike_footprint)
def canny_zernike2020(image, cand, mask_size: int = MASK_SIZE, **options) -> Refinement:
    """Canny–Zernike2020: Ghosal-Mehrotra Z11/Z20 step on a 7x7 mask; point p + (N/2) l (cos phi, sin phi)."""
    mask_size = int(mask_size)
    if mask_size not in (5, 7):
        raise InputError(f"mask_size={mask_size}: choose 5 or 7 (the candidates keep a 3-px margin)")
    mx, my, m20 = zernike_masks(mask_size)
    n = len(cand)
    out = np.zeros((n, 6))
    if n:
        _zernike_kernel(np.ascontiguousarray(image, np.float64), cand.x, cand.y, mx, my, m20, out)
    conv = out[:, 4] > 0.5
    off = np.where(conv, out[:, 0], 0.0)
    nx = np.where(conv, out[:, 2], cand.nx)
    ny = np.where(conv, out[:, 3], cand.ny)
    return Refinement(cand.x + off * nx, cand.y + off * ny, conv, nx, ny,
                      extras={"offset": off, "l": out[:, 1], "k": out[:, 5]})
