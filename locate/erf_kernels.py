"""Batched ERF edge-profile fits (numba, parallel over points).

Model along the normal: I(t) = A + B * Phi((t - mu) / s), Phi the standard
normal CDF.  4P fits (A, B, mu, s) by Levenberg-Marquardt; 2P fixes A, B
from the window's extrema (A = min, B = max - min) and fits (mu, s).

The fits work on an 11-sample profile (t = -5..5) and a centred window of
``w`` samples (w in {5, 7, 9, 11}).  The dynamic method picks ``w`` from the
normalised gradient entropy of the 11-sample profile and thresholds
tau1 < tau2 < tau3 (BRIEF §2).

Why numba: one point is ~5 iterations x 11 samples of erfc/exp; per-point
Python (scipy) costs ~1 ms, numpy batching wastes work on converged points;
a compiled loop per point, parallel over points, needs ~1 us.
"""
from __future__ import annotations

import math

import numpy as np

from edgetruth.locate.profiles import bilinear

PROFILE_LEN = 11
PROFILE_HALF = 5
_INV_SQRT2 = 1.0 / math.sqrt(2.0)
_INV_SQRT2PI = 1.0 / math.sqrt(2.0 * math.pi)
_LN_M = math.log(PROFILE_LEN - 1)
S_MIN = 0.05  # blur scale floor (px): below it the model is a step, mu is undetermined within a pixel

from edgetruth.locate.fit_status import NO_CONTRAST, NOT_CONVERGED, OK, OUT_OF_WINDOW  # noqa: E402
from edgetruth.jit import njit, prange  # numba, imported when a kernel is first called


@njit(cache=True, forceinline=True)
def normalised_entropy(prof):
    """H = -sum p ln p / ln M over g_k = |I_{k+1} - I_k|, M = len(prof) - 1; NaN for a flat profile."""
    m = prof.shape[0] - 1
    tot = 0.0
    for k in range(m):
        tot += abs(prof[k + 1] - prof[k])
    if not tot > 0.0:
        return np.nan
    h = 0.0
    for k in range(m):
        p = abs(prof[k + 1] - prof[k]) / tot
        if p > 0.0:
            h -= p * math.log(p)
    return h / math.log(m)


@njit(cache=True, forceinline=True)
def window_from_entropy(h, tau1, tau2, tau3):
    if h < tau1:
        return 5
    if h < tau2:
        return 7
    if h < tau3:
        return 9
    return 11


# Abramowitz & Stegun 7.1.26: erfc(x) = t (a1 + t (a2 + ...)) exp(-x^2), t = 1 / (1 + p x), x >= 0,
# |error| < 1.5e-7.  Its exp(-x^2) with x = z / sqrt(2) is the Gaussian density's exponential, so one
# exp per sample yields both Phi and phi (libm erfc + exp cost twice as much).  The error moves a
# fitted mu by < 1e-6 px (checked against scipy in the tests and the benchmark).
_AS_P = 0.3275911
_AS_A1 = 0.254829592
_AS_A2 = -0.284496736
_AS_A3 = 1.421413741
_AS_A4 = -1.453152027
_AS_A5 = 1.061405429


@njit(cache=True, forceinline=True)
def cdf_pdf(z):
    """(Phi(z), phi(z)) of the standard normal with a single exp."""
    e = math.exp(-0.5 * z * z)
    x = abs(z) * _INV_SQRT2
    t = 1.0 / (1.0 + _AS_P * x)
    half_erfc = 0.5 * t * (_AS_A1 + t * (_AS_A2 + t * (_AS_A3 + t * (_AS_A4 + t * _AS_A5)))) * e
    Phi = half_erfc if z < 0.0 else 1.0 - half_erfc
    return Phi, _INV_SQRT2PI * e


# numba's inline="always" kept here (elsewhere forceinline: LLVM inlines one compiled copy, quicker to compile):
# curve_fit_kernels' fastmath fit inlines _chol4, and what fastmath code computes depends on where it lands
@njit(cache=True, inline="always")
def _chol4(m00, m10, m11, m20, m21, m22, m30, m31, m32, m33, b0, b1, b2, b3):
    """Solve a symmetric positive-definite 4x4 system by Cholesky, in scalars (no allocation).
    Returns (ok, x0, x1, x2, x3)."""
    if not m00 > 0.0:
        return False, 0.0, 0.0, 0.0, 0.0
    l00 = math.sqrt(m00)
    l10 = m10 / l00
    l20 = m20 / l00
    l30 = m30 / l00
    d = m11 - l10 * l10
    if not d > 0.0:
        return False, 0.0, 0.0, 0.0, 0.0
    l11 = math.sqrt(d)
    l21 = (m21 - l20 * l10) / l11
    l31 = (m31 - l30 * l10) / l11
    d = m22 - l20 * l20 - l21 * l21
    if not d > 0.0:
        return False, 0.0, 0.0, 0.0, 0.0
    l22 = math.sqrt(d)
    l32 = (m32 - l30 * l20 - l31 * l21) / l22
    d = m33 - l30 * l30 - l31 * l31 - l32 * l32
    if not d > 0.0:
        return False, 0.0, 0.0, 0.0, 0.0
    l33 = math.sqrt(d)
    y0 = b0 / l00
    y1 = (b1 - l10 * y0) / l11
    y2 = (b2 - l20 * y0 - l21 * y1) / l22
    y3 = (b3 - l30 * y0 - l31 * y1 - l32 * y2) / l33
    x3 = y3 / l33
    x2 = (y2 - l32 * x3) / l22
    x1 = (y1 - l21 * x2 - l31 * x3) / l11
    x0 = (y0 - l10 * x1 - l20 * x2 - l30 * x3) / l00
    return True, x0, x1, x2, x3


@njit(cache=True, forceinline=True)
def _eval4(prof, lo, w, t0, A, B, mu, s):
    """One pass over the window: cost and the normal equations (J^T J, J^T r) of the 4P model."""
    c = 0.0
    h00 = h10 = h11 = h20 = h21 = h22 = h30 = h31 = h32 = h33 = 0.0
    g0 = g1 = g2 = g3 = 0.0
    inv_s = 1.0 / s
    for k in range(w):
        z = (t0 + k - mu) * inv_s
        Phi, phi = cdf_pdf(z)
        r = A + B * Phi - prof[lo + k]
        c += r * r
        j2 = -B * phi * inv_s
        j3 = j2 * z
        h10 += Phi
        h11 += Phi * Phi
        h20 += j2
        h21 += Phi * j2
        h22 += j2 * j2
        h30 += j3
        h31 += Phi * j3
        h32 += j2 * j3
        h33 += j3 * j3
        g0 += r
        g1 += Phi * r
        g2 += j2 * r
        g3 += j3 * r
    h00 = float(w)
    return c, h00, h10, h11, h20, h21, h22, h30, h31, h32, h33, g0, g1, g2, g3


@njit(cache=True, forceinline=True)
def _eval2(prof, lo, w, t0, A, B, mu, s):
    """Cost and normal equations of the 2P model (A, B fixed; unknowns mu, s)."""
    c = 0.0
    h22 = h32 = h33 = 0.0
    g2 = g3 = 0.0
    inv_s = 1.0 / s
    for k in range(w):
        z = (t0 + k - mu) * inv_s
        Phi, phi = cdf_pdf(z)
        r = A + B * Phi - prof[lo + k]
        c += r * r
        j2 = -B * phi * inv_s
        j3 = j2 * z
        h22 += j2 * j2
        h32 += j2 * j3
        h33 += j3 * j3
        g2 += j2 * r
        g3 += j3 * r
    return c, h22, h32, h33, g2, g3


@njit(cache=True)
def fit_one(prof, w, four_param, maxit, tol, out):
    """Fit the centred ``w``-sample window of an 11-sample profile (Levenberg-Marquardt).

    out <- [A, B, mu, s, rss, c_mumu, iterations, status]
    c_mumu is the (mu, mu) element of (J^T J)^-1 at the solution: the
    position variance is sigma_noise^2 * c_mumu.  Everything is scalar
    arithmetic: no allocation per point.
    """
    half = (w - 1) // 2
    lo = PROFILE_HALF - half
    t0 = -float(half)
    ymin = prof[lo]
    ymax = prof[lo]
    for k in range(w):
        v = prof[lo + k]
        if v < ymin:
            ymin = v
        if v > ymax:
            ymax = v
    A = ymin
    B = ymax - ymin
    if not B > 0.0:
        out[0] = ymin; out[1] = 0.0; out[2] = 0.0; out[3] = 1.0
        out[4] = 0.0; out[5] = np.inf; out[6] = 0; out[7] = NO_CONTRAST
        return
    # initial mu, s: mean and spread of the positive gradient over the window
    g_sum = 0.0
    g_t = 0.0
    g_tt = 0.0
    for k in range(w - 1):
        g = prof[lo + k + 1] - prof[lo + k]
        if g > 0.0:
            tm = t0 + k + 0.5
            g_sum += g
            g_t += g * tm
            g_tt += g * tm * tm
    mu = g_t / g_sum
    var = g_tt / g_sum - mu * mu - 1.0 / 12.0
    s = math.sqrt(var) if var > 0.09 else 0.3
    if s > w:
        s = float(w)

    lam = 1e-4
    status = NOT_CONVERGED
    it = 0
    if four_param:
        c, h00, h10, h11, h20, h21, h22, h30, h31, h32, h33, g0, g1, g2, g3 = _eval4(prof, lo, w, t0, A, B, mu, s)
        while it < maxit:
            it += 1
            f = 1.0 + lam
            ok, d0, d1, d2, d3 = _chol4(h00 * f, h10, h11 * f, h20, h21, h22 * f, h30, h31, h32, h33 * f,
                                        -g0, -g1, -g2, -g3)
            if not ok:
                lam *= 10.0
                if lam > 1e10:
                    break
                continue
            nA = A + d0
            nB = B + d1
            nmu = mu + d2
            ns = s + d3
            if ns < S_MIN:
                ns = S_MIN
            small = abs(d2) < tol and abs(ns - s) < tol
            e = _eval4(prof, lo, w, t0, nA, nB, nmu, ns)
            if e[0] <= c:
                A = nA; B = nB; mu = nmu; s = ns
                c, h00, h10, h11, h20, h21, h22, h30, h31, h32, h33, g0, g1, g2, g3 = e
                lam = max(lam * 0.1, 1e-12)
                if small:
                    status = OK
                    break
            else:
                if small:  # no decrease along a negligible step: at the minimum
                    status = OK
                    break
                lam *= 10.0
                if lam > 1e10:
                    break
        ok, x0, x1, x2, x3 = _chol4(h00, h10, h11, h20, h21, h22, h30, h31, h32, h33, 0.0, 0.0, 1.0, 0.0)
        c_mumu = x2 if ok else np.inf
    else:
        c, h22, h32, h33, g2, g3 = _eval2(prof, lo, w, t0, A, B, mu, s)
        while it < maxit:
            it += 1
            f = 1.0 + lam
            a = h22 * f
            d = h33 * f
            det = a * d - h32 * h32
            if not det > 0.0:
                lam *= 10.0
                if lam > 1e10:
                    break
                continue
            d2 = (-g2 * d + g3 * h32) / det
            d3 = (-g3 * a + g2 * h32) / det
            nmu = mu + d2
            ns = s + d3
            if ns < S_MIN:
                ns = S_MIN
            small = abs(d2) < tol and abs(ns - s) < tol
            e = _eval2(prof, lo, w, t0, A, B, nmu, ns)
            if e[0] <= c:
                mu = nmu; s = ns
                c, h22, h32, h33, g2, g3 = e
                lam = max(lam * 0.1, 1e-12)
                if small:
                    status = OK
                    break
            else:
                if small:
                    status = OK
                    break
                lam *= 10.0
                if lam > 1e10:
                    break
        det = h22 * h33 - h32 * h32
        c_mumu = h33 / det if det > 0.0 else np.inf
    if status == OK:
        if not (abs(mu) <= half and s > S_MIN and s < 2.0 * w and B > 0.0):
            status = OUT_OF_WINDOW
    out[0] = A
    out[1] = B
    out[2] = mu
    out[3] = s
    out[4] = c
    out[5] = c_mumu
    out[6] = it
    out[7] = status


@njit(cache=True, parallel=True)
def fit_profiles(profiles, windows, four_param, maxit, tol, out):
    """Fit every profile (N, 11) with its window size windows[i]; out (N, 8) as in ``fit_one``."""
    for i in prange(profiles.shape[0]):
        fit_one(profiles[i], windows[i], four_param, maxit, tol, out[i])


@njit(cache=True, parallel=True)
def refine_erf(img, xs, ys, nxs, nys, fixed_window, tau1, tau2, tau3, four_param, maxit, tol,
               profiles, entropy, windows, out):
    """Sample, choose the window (fixed_window > 0 forces it), fit: all points in parallel."""
    for i in prange(xs.shape[0]):
        prof = profiles[i]
        for k in range(PROFILE_LEN):
            t = k - PROFILE_HALF
            prof[k] = bilinear(img, xs[i] + t * nxs[i], ys[i] + t * nys[i])
        h = normalised_entropy(prof)
        entropy[i] = h
        if fixed_window > 0:
            w = fixed_window
        elif h != h:  # flat profile
            w = PROFILE_LEN
        else:
            w = window_from_entropy(h, tau1, tau2, tau3)
        windows[i] = w
        fit_one(prof, w, four_param, maxit, tol, out[i])
