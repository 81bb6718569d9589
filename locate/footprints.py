"""Footprints: the pixels a method reads to refine one candidate.

A footprint is a function ``fp(cand, **options) -> masks`` with ``masks`` a bool array
(N, SIZE, SIZE): masks[i, R + dy, R + dx] is True when the method's answer for candidate i
may depend on pixel (y + dy, x + dx), R = ``RADIUS``.  It is declared next to each method
(``register(..., footprint=...)``) and used by the per-point Cramér-Rao bound
(``edgetruth.evaluate.crb``), which counts exactly these pixels' information.

Rules: a pixel counts when any weight the method gives it can be non-zero (a bilinear
sample's four neighbours with a non-zero weight; every pixel a smoothing kernel reaches);
where the pixels depend on the data (a floating window, a data-chosen axis), the union over
the choices.  The candidate's position and normal are given: the pixels that produced them
(Canny on the smoothed gradient) count only for a method whose answer *is* the candidate.
"""
from __future__ import annotations

import numpy as np

RADIUS = 8
SIZE = 2 * RADIUS + 1


def _empty(n: int) -> np.ndarray:
    return np.zeros((n, SIZE, SIZE), bool)


def gaussian_radius_px(sigma_px: float) -> int:
    """Half-size of OpenCV's Gaussian kernel for float images: ksize = round(8 sigma + 1) | 1."""
    k = int(round(sigma_px * 8 + 1)) | 1
    return (k - 1) // 2


def dilate(masks: np.ndarray, r: int) -> np.ndarray:
    """Every pixel within a (2r+1)^2 square of a masked pixel (a smoothing kernel's reach)."""
    if r <= 0:
        return masks
    out = masks.copy()
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            if dx or dy:
                out |= np.roll(np.roll(masks, dy, axis=1), dx, axis=2)
    return out


def profile_masks(cand, half: int, step_px: float = 1.0) -> np.ndarray:
    """Pixels with a non-zero bilinear weight in the samples p + t n, |t| <= half (``locate.profiles``)."""
    n = len(cand)
    m = _empty(n)
    if not n:
        return m
    rows = np.arange(n)
    eps = 1e-12
    for k in range(-half, half + 1):
        t = k * step_px
        ox = t * cand.nx
        oy = t * cand.ny
        x0 = np.floor(ox)
        y0 = np.floor(oy)
        fx = ox - x0
        fy = oy - y0
        ix = x0.astype(np.int64) + RADIUS
        iy = y0.astype(np.int64) + RADIUS
        for ddx, wx in ((0, 1.0 - fx), (1, fx)):
            for ddy, wy in ((0, 1.0 - fy), (1, fy)):
                use = (wx > eps) & (wy > eps)
                m[rows[use], iy[use] + ddy, ix[use] + ddx] = True
    return m


def block_masks(n: int, half_rows: int, half_cols: int) -> np.ndarray:
    """The same (2 half_rows + 1) x (2 half_cols + 1) block around every candidate."""
    m = _empty(n)
    m[:, RADIUS - half_rows:RADIUS + half_rows + 1, RADIUS - half_cols:RADIUS + half_cols + 1] = True
    return m


def pattern_masks(n: int, pattern: np.ndarray) -> np.ndarray:
    """A fixed odd-sized boolean pattern centred on every candidate."""
    pattern = np.asarray(pattern, bool)
    h, w = pattern.shape
    m = _empty(n)
    m[:, RADIUS - h // 2:RADIUS + h // 2 + 1, RADIUS - w // 2:RADIUS + w // 2 + 1] = pattern
    return m


# ---- footprint functions (``fp(cand, **options)``), one per kind of reading ----

def profile(half: int = 5, option: str | None = None):
    """The normal profile p + t n, |t| <= half (or the method's option ``option`` when given)."""
    def fp(cand, **options):
        h = int(options.get(option, half)) if option else half
        return profile_masks(cand, h)
    fp.__doc__ = f"bilinear normal profile, |t| <= {half}" + (f" (option {option})" if option else "")
    return fp


def neighbourhood(cand, **options) -> np.ndarray:
    """Every pixel within RADIUS: the conservative footprint of a method that declares none."""
    return block_masks(len(cand), RADIUS, RADIUS)


def candidate_decision(cand, **options) -> np.ndarray:
    """What decides a Canny candidate: non-maximum suppression (3x3) of the Sobel gradient (3x3) of
    the Gaussian-smoothed image."""
    r = min(RADIUS, 2 + gaussian_radius_px(cand.sigma_px))
    return block_masks(len(cand), r, r)



def patch_masks(cand, half_normal: float, half_tangent: float) -> np.ndarray:
    """Pixels whose centre lies in the rectangle |t| <= half_normal, |u| <= half_tangent around each
    candidate, t along its normal and u along the edge (``locate.methods.patch_psf_fit``)."""
    n = len(cand)
    m = _empty(n)
    if not n:
        return m
    d = np.arange(-RADIUS, RADIUS + 1, dtype=np.float64)
    dx = d[None, None, :]
    dy = d[None, :, None]
    nx = np.asarray(cand.nx, np.float64)[:, None, None]
    ny = np.asarray(cand.ny, np.float64)[:, None, None]
    t = dx * nx + dy * ny
    u = dy * nx - dx * ny
    return (np.abs(t) <= half_normal) & (np.abs(u) <= half_tangent)


def patch(half_normal: float, half_tangent: float):
    """A rectangle along the edge, options ``half_normal`` / ``half_tangent`` override the defaults."""
    def fp(cand, **options):
        return patch_masks(cand, float(options.get("half_normal", half_normal)),
                           float(options.get("half_tangent", half_tangent)))
    fp.__doc__ = f"patch |t| <= {half_normal}, |u| <= {half_tangent} around the candidate"
    return fp
