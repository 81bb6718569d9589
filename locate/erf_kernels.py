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

import numba
import numpy as np

from locate.profiles import bilinear

PROFILE_LEN = 11
PROFILE_HALF = 5
_INV_SQRT2 = 1.0 / math.sqrt(2.0)
_INV_SQRT2PI = 1.0 / math.sqrt(2.0 * math.pi)
_LN_M = math.log(PROFILE_LEN - 1)
S_MIN = 0.05  # blur scale floor (px): below it the model is a step, mu is undetermined within a pixel

# status codes per point
OK = 0
NOT_CONVERGED = 1
NO_CONTRAST = 2
OUT_OF_WINDOW = 3


@numba.njit(cache=True, inline="always")
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


@numba.njit(cache=True, inline="always")
def window_from_entropy(h, tau1, tau2, tau3):
    if h < tau1:
        return 5
    if h < tau2:
        return 7
    if h < tau3:
        return 9
    return 11


@numba.njit(cache=True)
def _solve(m, n):
    """Solve the n x n system in the augmented array m[:n, :n+1] in place (partial pivoting).
    Returns False if singular; the solution is left in m[:, n]."""
    for c in range(n):
        piv = c
        best = abs(m[c, c])
        for r in range(c + 1, n):
            if abs(m[r, c]) > best:
                best = abs(m[r, c])
                piv = r
        if not best > 1e-300:
            return False
        if piv != c:
            for k in range(n + 1):
                tmp = m[c, k]
                m[c, k] = m[piv, k]
                m[piv, k] = tmp
        for r in range(c + 1, n):
            f = m[r, c] / m[c, c]
            for k in range(c, n + 1):
                m[r, k] -= f * m[c, k]
    for c in range(n - 1, -1, -1):
        acc = m[c, n]
        for k in range(c + 1, n):
            acc -= m[c, k] * m[k, n]
        m[c, n] = acc / m[c, c]
    return True


@numba.njit(cache=True)
def _normal_eq(prof, lo, w, t0, p, npar, jtj, jtr):
    """Accumulate J^T J, J^T r at params p; return the cost sum r^2.  Samples prof[lo:lo+w] at t0 + k."""
    for a in range(npar):
        jtr[a] = 0.0
        for b in range(npar):
            jtj[a, b] = 0.0
    A = p[0]
    B = p[1]
    mu = p[2]
    s = p[3]
    cost = 0.0
    jrow = np.empty(4)
    for k in range(w):
        t = t0 + k
        z = (t - mu) / s
        Phi = 0.5 * math.erfc(-z * _INV_SQRT2)
        phi = _INV_SQRT2PI * math.exp(-0.5 * z * z)
        r = A + B * Phi - prof[lo + k]
        cost += r * r
        if npar == 4:
            jrow[0] = 1.0
            jrow[1] = Phi
            jrow[2] = -B * phi / s
            jrow[3] = -B * phi * z / s
        else:
            jrow[0] = -B * phi / s
            jrow[1] = -B * phi * z / s
        for a in range(npar):
            jtr[a] += jrow[a] * r
            for b in range(a, npar):
                jtj[a, b] += jrow[a] * jrow[b]
    for a in range(npar):
        for b in range(a):
            jtj[a, b] = jtj[b, a]
    return cost


@numba.njit(cache=True)
def _cost(prof, lo, w, t0, A, B, mu, s):
    c = 0.0
    for k in range(w):
        z = (t0 + k - mu) / s
        r = A + B * 0.5 * math.erfc(-z * _INV_SQRT2) - prof[lo + k]
        c += r * r
    return c


@numba.njit(cache=True)
def fit_one(prof, w, four_param, maxit, tol, out):
    """Fit the centred ``w``-sample window of an 11-sample profile.

    out <- [A, B, mu, s, rss, c_mumu, iterations, status]
    c_mumu is the (mu, mu) element of (J^T J)^-1 at the solution: the
    position variance is sigma_noise^2 * c_mumu.
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
    B = ymax - ymin
    if not B > 0.0:
        out[0] = ymin; out[1] = 0.0; out[2] = 0.0; out[3] = 1.0
        out[4] = 0.0; out[5] = np.inf; out[6] = 0; out[7] = NO_CONTRAST
        return
    # initial mu, s from the (positive) gradient distribution of the window
    g_sum = 0.0
    g_t = 0.0
    for k in range(w - 1):
        g = prof[lo + k + 1] - prof[lo + k]
        if g > 0.0:
            g_sum += g
            g_t += g * (t0 + k + 0.5)
    mu = g_t / g_sum if g_sum > 0.0 else 0.0
    g_var = 0.0
    for k in range(w - 1):
        g = prof[lo + k + 1] - prof[lo + k]
        if g > 0.0:
            d = t0 + k + 0.5 - mu
            g_var += g * d * d
    var = g_var / g_sum - 1.0 / 12.0 if g_sum > 0.0 else 1.0
    s = math.sqrt(var) if var > 0.09 else 0.3
    if s > w:
        s = float(w)

    npar = 4 if four_param else 2
    p = np.empty(4)
    p[0] = ymin
    p[1] = B
    p[2] = mu
    p[3] = s
    trial = np.empty(4)
    jtj = np.empty((4, 4))
    jtr = np.empty(4)
    m = np.empty((4, 5))
    lam = 1e-3
    cost = _normal_eq(prof, lo, w, t0, p, npar, jtj, jtr)
    status = NOT_CONVERGED
    it = 0
    off = 4 - npar  # index of the first fitted parameter in p
    while it < maxit:
        it += 1
        for a in range(npar):
            for b in range(npar):
                m[a, b] = jtj[a, b]
            m[a, a] += lam * (jtj[a, a] + 1e-12)
            m[a, npar] = -jtr[a]
        if not _solve(m, npar):
            lam *= 10.0
            if lam > 1e12:
                break
            continue
        for a in range(4):
            trial[a] = p[a]
        for a in range(npar):
            trial[off + a] = p[off + a] + m[a, npar]
        if trial[3] < S_MIN:
            trial[3] = S_MIN
        new_cost = _cost(prof, lo, w, t0, trial[0], trial[1], trial[2], trial[3])
        if new_cost <= cost:
            step_mu = abs(trial[2] - p[2])
            step_s = abs(trial[3] - p[3])
            for a in range(4):
                p[a] = trial[a]
            cost = _normal_eq(prof, lo, w, t0, p, npar, jtj, jtr)
            lam = max(lam * 0.1, 1e-12)
            if step_mu < tol and step_s < tol:
                status = OK
                break
        else:
            lam *= 10.0
            if lam > 1e12:
                # no decrease possible: we sit at a minimum to machine precision
                status = OK
                break
    # covariance of the undamped problem at the solution
    for a in range(npar):
        for b in range(npar):
            m[a, b] = 0.0
        m[a, a] = 1.0
    # invert jtj column for mu: solve jtj x = e_mu
    mu_idx = 2 - off
    for a in range(npar):
        for b in range(npar):
            m[a, b] = jtj[a, b]
        m[a, npar] = 1.0 if a == mu_idx else 0.0
    c_mumu = m[mu_idx, npar] if _solve(m, npar) else np.inf
    if status == OK:
        if not (abs(p[2]) <= half and p[3] > S_MIN and p[3] < 2.0 * w and p[1] > 0.0):
            status = OUT_OF_WINDOW
    out[0] = p[0]
    out[1] = p[1]
    out[2] = p[2]
    out[3] = p[3]
    out[4] = cost
    out[5] = c_mumu
    out[6] = it
    out[7] = status


@numba.njit(cache=True, parallel=True)
def fit_profiles(profiles, windows, four_param, maxit, tol, out):
    """Fit every profile (N, 11) with its window size windows[i]; out (N, 8) as in ``fit_one``."""
    for i in numba.prange(profiles.shape[0]):
        fit_one(profiles[i], windows[i], four_param, maxit, tol, out[i])


@numba.njit(cache=True, parallel=True)
def refine_erf(img, xs, ys, nxs, nys, fixed_window, tau1, tau2, tau3, four_param, maxit, tol,
               profiles, entropy, windows, out):
    """Sample, choose the window (fixed_window > 0 forces it), fit: all points in parallel."""
    for i in numba.prange(xs.shape[0]):
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
