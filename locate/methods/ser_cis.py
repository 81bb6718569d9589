"""SER-CIS: converted intensity summation (CIS) inside a stable edge region (SER).

Reference: "Subpixel edge localization based on converted intensity
summation under stable edge region" (the study's [25]).  A pixel value is the
integral of the intensity curve over the pixel, so the sum of the values
over a run of pixels that starts on one plateau and ends on the other
measures how much of the run lies on each side of the edge:

    c = (sum I - n g_b) / (g_a - g_b) - 1/2,

g_b and g_a the two plateau (smooth-region) intensities, n the number of
pixels summed.  The seed study used "a SER-CIS-style implementation ...
according to the CIS and stable-region principles"; so does this module.

Profile and offset convention (derived here, checked by a test on an ideal
edge).  The samples are the shared normal profile I_k = I(p + t_k n),
t_k = -5..5, n pointing dark -> bright.  A region is the centred run
t_s = -h .. t_e = +h (n = 2h + 1 samples).  Model each sample as the mean
over [t_k - 1/2, t_k + 1/2] of a step at mu with levels g_b (t < mu) and g_a
(t > mu):  I_k = g_b + (g_a - g_b) clip(t_k + 1/2 - mu, 0, 1).  Then

    sum_k I_k = n g_b + (g_a - g_b) (t_e + 1/2 - mu)     (t_s - 1/2 <= mu <= t_e + 1/2)
    c = (sum I - n g_b) / (g_a - g_b) - 1/2 = t_e - mu,   so   mu = t_e - c = h - c:

c is the distance of the edge from the region's bright-end sample, i.e.
"measured from the region's start" when the region is read from its g_a
(bright) end -- our reading of the formula's convention (the paper itself
was not available here).  This is exact for any blur that
leaves the region's two ends on their plateaus (the blur only moves
intensity within the run), which is what the stable region is for.

Stable-region rule (the paper's exact rule is not available here; ours):
  * the smallest centred region h = h_min .. 5 (h_min = 4: n = 9 or 11
    samples) whose two end segments of ``segment`` = 2 samples each
    (t = -h, -h+1 and t = h-1, h) are flat:
        |I_{-h+1} - I_{-h}| <= tol  and  |I_h - I_{h-1}| <= tol,
        tol = max(k_noise * sqrt(2) * sigma_n, flat_rel * (g_a - g_b)),
    sigma_n the image noise (below), k_noise = 3 (a pure-noise difference
    of two samples has sd sqrt(2) sigma_n), flat_rel = 0.01 (a plateau
    still sloping by 1 % of the contrast per px biases g_b/g_a by < 1 %);
  * g_b, g_a = means of the dark / bright end segments, g_a - g_b > tol;
  * the smallest such region is taken: fewer summed samples means less
    noise in c (the plateau errors enter c multiplied by the number of
    samples on each side).  h_min = 4 because the edge may lie up to ~0.7 px
    from the candidate pixel and a 1-px blur needs ~3 px on each side to
    reach its plateau; with h_min = 3 the noise part of the tolerance lets
    still-sloping end segments pass as flat (measured on 1-px-blur edges at
    sigma_n/B = 0.02: RMSE 0.076 px and a -0.009 px bias, vs 0.060 px and
    no bias with h_min = 4; h_min = 5 gave 0.074 px).
  * no stable region up to h = 5, no contrast, or mu outside [t_s, t_e]:
    converged=False and the candidate pixel is kept.
Longer regions than 11 samples are not used (candidates guarantee only
|t| <= 5 inside the image).

Noise sigma_n: Immerkaer's estimator (sqrt(pi/2)/6 * mean |I * L|, L the
3x3 kernel [[1,-2,1],[-2,4,-2],[1,-2,1]]) over the pixels whose smoothed
gradient magnitude is below the Canny low threshold (edges excluded);
override with ``noise_sigma=``.

Extras: g_b, g_a, c, region (n samples), width (n, as a float, for
uniformity with the fits), noise_sigma, status.
"""
from __future__ import annotations

import math

import numpy as np

from edgetruth.errors import InputError
from edgetruth.locate.fit_status import NO_CONTRAST, NOT_CONVERGED, OK, OUT_OF_WINDOW
from edgetruth.locate.profiles import bilinear
from edgetruth.locate import footprints as FP
from edgetruth.locate.registry import register
from edgetruth.locate.result import Refinement
from edgetruth.jit import njit, prange  # numba, imported when a kernel is first called

PROFILE_HALF = 5
H_MIN = 4
SEGMENT = 2
K_NOISE = 3.0
FLAT_REL = 0.01

def image_noise_sigma(image, cand) -> float:
    """Immerkaer's noise estimate over the non-edge pixels of ``image`` (see module docstring)."""
    img = np.ascontiguousarray(image, np.float64)
    if min(img.shape) < 3:
        return 0.0
    low = float(cand.thresholds[0])
    total, count, total_all, count_all = _immerkaer_sums(img, np.ascontiguousarray(cand.grad_x, np.float64),
                                                        np.ascontiguousarray(cand.grad_y, np.float64), low)
    if count < 16:
        total, count = total_all, count_all
    return float(math.sqrt(math.pi / 2.0) / 6.0 * total / count)


@njit(cache=True)
def _immerkaer_sums(img, gx, gy, low):
    """Sum and count of |I * L| over the interior pixels with smoothed gradient magnitude below ``low``
    (all interior pixels when low <= 0), and over all interior pixels: one serial pass (memory-bound; a
    short parallel region waits for both threads, which on a loaded machine costs more than it saves)."""
    h, w = img.shape
    rows_sum = np.zeros(h)
    rows_n = np.zeros(h)
    rows_sum_all = np.zeros(h)
    for r in range(1, h - 1):
        acc = 0.0
        n = 0.0
        acc_all = 0.0
        for c in range(1, w - 1):
            v = (img[r - 1, c - 1] - 2.0 * img[r - 1, c] + img[r - 1, c + 1]
                 - 2.0 * img[r, c - 1] + 4.0 * img[r, c] - 2.0 * img[r, c + 1]
                 + img[r + 1, c - 1] - 2.0 * img[r + 1, c] + img[r + 1, c + 1])
            a = abs(v)
            acc_all += a
            if low <= 0.0 or gx[r, c] * gx[r, c] + gy[r, c] * gy[r, c] < low * low:
                acc += a
                n += 1.0
        rows_sum[r] = acc
        rows_n[r] = n
        rows_sum_all[r] = acc_all
    return rows_sum.sum(), rows_n.sum(), rows_sum_all.sum(), float((h - 2) * (w - 2))


@njit(cache=True)
def cis_one(prof, h_min, segment, tol_abs, flat_rel, out):
    """Stable region + CIS on one 11-sample profile; out <- [mu, g_b, g_a, c, n, status]."""
    c0 = PROFILE_HALF
    out[0] = 0.0
    out[1] = np.nan
    out[2] = np.nan
    out[3] = np.nan
    out[4] = 0.0
    out[5] = NOT_CONVERGED
    any_contrast = False
    for h in range(h_min, PROFILE_HALF + 1):
        lo = c0 - h
        hi = c0 + h
        g_b = 0.0
        g_a = 0.0
        for j in range(segment):
            g_b += prof[lo + j]
            g_a += prof[hi - j]
        g_b /= segment
        g_a /= segment
        contrast = g_a - g_b
        tol = max(tol_abs, flat_rel * contrast)
        if not contrast > tol:
            continue
        any_contrast = True
        flat = True
        for j in range(segment - 1):
            if abs(prof[lo + j + 1] - prof[lo + j]) > tol or abs(prof[hi - j] - prof[hi - j - 1]) > tol:
                flat = False
        if not flat:
            continue
        n = 2 * h + 1
        s = 0.0
        for k in range(lo, hi + 1):
            s += prof[k]
        c = (s - n * g_b) / contrast - 0.5
        mu = h - c
        out[1] = g_b
        out[2] = g_a
        out[3] = c
        out[4] = n
        if -h <= mu <= h:
            out[0] = mu
            out[5] = OK
        else:
            out[5] = OUT_OF_WINDOW
        return
    if not any_contrast:
        out[5] = NO_CONTRAST


@njit(cache=True, parallel=True)
def cis_batch(profiles, h_min, segment, tol_abs, flat_rel, out):
    for i in prange(profiles.shape[0]):
        cis_one(profiles[i], h_min, segment, tol_abs, flat_rel, out[i])


@njit(cache=True, parallel=True)
def _sample_and_cis(img, xs, ys, nxs, nys, h_min, segment, tol_abs, flat_rel, profiles, out):
    """Sample each 11-point normal profile (``locate.profiles.bilinear``) and apply ``cis_one``, in one pass."""
    for i in prange(xs.shape[0]):
        prof = profiles[i]
        for k in range(2 * PROFILE_HALF + 1):
            t = k - PROFILE_HALF
            prof[k] = bilinear(img, xs[i] + t * nxs[i], ys[i] + t * nys[i])
        cis_one(prof, h_min, segment, tol_abs, flat_rel, out[i])


@register("ser_cis", "SER-CIS", family="baseline", footprint=FP.profile(5))
def ser_cis(image, cand, noise_sigma: float | None = None, k_noise: float = K_NOISE, flat_rel: float = FLAT_REL,
            h_min: int = H_MIN, segment: int = SEGMENT):
    """SER-CIS: converted intensity summation over the smallest stable centred region of the normal profile."""
    if not (1 <= int(segment) and 2 * int(segment) <= 2 * int(h_min) + 1 and 1 <= int(h_min) <= PROFILE_HALF):
        raise InputError(f"h_min={h_min}, segment={segment}: need 1 <= h_min <= {PROFILE_HALF}, "
                         "1 <= segment, 2 segment <= 2 h_min + 1")
    sig = image_noise_sigma(image, cand) if noise_sigma is None else float(noise_sigma)
    if not (np.isfinite(sig) and sig >= 0):
        raise InputError(f"noise_sigma={noise_sigma}: must be a finite number >= 0")
    n = len(cand)
    out = np.empty((n, 6))
    if n:
        _sample_and_cis(np.ascontiguousarray(image, np.float64), cand.x, cand.y, cand.nx, cand.ny, int(h_min),
                        int(segment), float(k_noise) * math.sqrt(2.0) * sig, float(flat_rel), np.empty((n, 11)), out)
    status = out[:, 5].astype(np.int64)
    conv = status == OK
    region = out[:, 4].astype(np.int64)
    return Refinement.from_offset(
        cand, np.where(conv, out[:, 0], 0.0), conv, g_b=out[:, 1], g_a=out[:, 2], c=out[:, 3],
        region=region, width=region.astype(np.float64), noise_sigma=np.full(len(cand), sig), status=status)
