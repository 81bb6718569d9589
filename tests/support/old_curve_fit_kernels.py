"""The curve-fit kernels as they were before the scalar rewrite (as of edgetruth commit 667f105), kept only as
the reference the new kernels (locate/curve_fit_kernels.py) are tested against: a generic
Levenberg-Marquardt with small arrays allocated per point, libm erfc, Gaussian elimination.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from edgetruth.locate.fit_status import NO_CONTRAST, NOT_CONVERGED, OK, OUT_OF_WINDOW
from edgetruth.locate.small_linalg import solve_small as _solve

ERF = 0
ARCTAN = 1
LOGISTIC = 2
GAUSS = 3
MODEL_NAMES = {ERF: "erf", ARCTAN: "arctan", LOGISTIC: "logistic", GAUSS: "gauss"}

W_MIN = 0.05  # width floor (px)
OUT_LEN = 8

_INV_SQRT2 = 1.0 / math.sqrt(2.0)
_INV_SQRT2PI = 1.0 / math.sqrt(2.0 * math.pi)
_INV_PI = 1.0 / math.pi
# equal central slope with a Gaussian of unit sd
_W_ARCTAN = math.sqrt(2.0 / math.pi)
_W_LOGISTIC = math.sqrt(2.0 * math.pi) / 4.0

__all__ = ["ERF", "ARCTAN", "LOGISTIC", "GAUSS", "OK", "NOT_CONVERGED", "NO_CONTRAST", "OUT_OF_WINDOW",
           "model_value", "initial_guess", "fit_one", "fit_batch", "fit_profiles"]


@numba.njit(cache=True, inline="always")
def _shape(model, z):
    """F(z) and F'(z) of a step model."""
    if model == ERF:
        return 0.5 * math.erfc(-z * _INV_SQRT2), _INV_SQRT2PI * math.exp(-0.5 * z * z)
    if model == ARCTAN:
        return 0.5 + math.atan(z) * _INV_PI, _INV_PI / (1.0 + z * z)
    # logistic, overflow-free
    if z >= 0.0:
        e = math.exp(-z)
        f = 1.0 / (1.0 + e)
    else:
        e = math.exp(z)
        f = e / (1.0 + e)
    return f, f * (1.0 - f)


@numba.njit(cache=True)
def model_value(model, p, t):
    """y(t) of ``model`` at parameters ``p``."""
    if model == GAUSS:
        z = (t - p[1]) / p[2]
        return p[0] * math.exp(-0.5 * z * z)
    f, _ = _shape(model, (t - p[2]) / p[3])
    return p[0] + p[1] * f


@numba.njit(cache=True)
def _jac_row(model, p, t, jrow):
    """Fill d y / d p at t; return y(t)."""
    if model == GAUSS:
        a = p[0]
        w = p[2]
        z = (t - p[1]) / w
        e = math.exp(-0.5 * z * z)
        jrow[0] = e
        jrow[1] = a * e * z / w
        jrow[2] = a * e * z * z / w
        return a * e
    B = p[1]
    w = p[3]
    z = (t - p[2]) / w
    f, d = _shape(model, z)
    jrow[0] = 1.0
    jrow[1] = f
    jrow[2] = -B * d / w
    jrow[3] = -B * d * z / w
    return p[0] + B * f


@numba.njit(cache=True)
def _normal_eq(model, t, y, n, p, npar, jtj, jtr, jrow):
    for a in range(npar):
        jtr[a] = 0.0
        for b in range(npar):
            jtj[a, b] = 0.0
    cost = 0.0
    for k in range(n):
        r = _jac_row(model, p, t[k], jrow) - y[k]
        cost += r * r
        for a in range(npar):
            jtr[a] += jrow[a] * r
            for b in range(a, npar):
                jtj[a, b] += jrow[a] * jrow[b]
    for a in range(npar):
        for b in range(a):
            jtj[a, b] = jtj[b, a]
    return cost


@numba.njit(cache=True)
def _cost(model, t, y, n, p):
    c = 0.0
    for k in range(n):
        r = model_value(model, p, t[k]) - y[k]
        c += r * r
    return c


@numba.njit(cache=True)
def initial_guess(model, t, y, n, p):
    """Data-driven start (see module docstring); returns False if the samples have no contrast."""
    if model == GAUSS:
        kmax = 0
        for k in range(1, n):
            if y[k] > y[kmax]:
                kmax = k
        a = y[kmax]
        if not a > 0.0:
            return False
        p[0] = a
        p[1] = t[kmax]
        p[2] = 1.0
        if 0 < kmax < n - 1 and y[kmax - 1] > 0.0 and y[kmax + 1] > 0.0:
            lm = math.log(y[kmax - 1])
            l0 = math.log(a)
            lp = math.log(y[kmax + 1])
            den = lm - 2.0 * l0 + lp
            h = t[kmax + 1] - t[kmax]
            if den < 0.0:
                off = 0.5 * (lm - lp) / den
                p[1] = t[kmax] + off * h
                w = h * math.sqrt(-1.0 / den)
                p[2] = max(w, W_MIN)
                p[0] = math.exp(l0 - 0.25 * (lm - lp) * off)
        return True
    ymin = y[0]
    ymax = y[0]
    for k in range(n):
        if y[k] < ymin:
            ymin = y[k]
        if y[k] > ymax:
            ymax = y[k]
    B = ymax - ymin
    if not B > 0.0:
        return False
    g_sum = 0.0
    g_t = 0.0
    for k in range(n - 1):
        g = y[k + 1] - y[k]
        if g > 0.0:
            g_sum += g
            g_t += g * 0.5 * (t[k] + t[k + 1])
    if not g_sum > 0.0:
        return False
    mu = g_t / g_sum
    g_var = 0.0
    for k in range(n - 1):
        g = y[k + 1] - y[k]
        if g > 0.0:
            d = 0.5 * (t[k] + t[k + 1]) - mu
            g_var += g * d * d
    var = g_var / g_sum - 1.0 / 12.0
    sd = math.sqrt(var) if var > 0.09 else 0.3
    span = t[n - 1] - t[0]
    if sd > span:
        sd = span
    if model == ARCTAN:
        sd *= _W_ARCTAN
    elif model == LOGISTIC:
        sd *= _W_LOGISTIC
    p[0] = ymin
    p[1] = B
    p[2] = mu
    p[3] = sd
    return True


@numba.njit(cache=True)
def fit_one(model, t, y, n, p0, maxit, tol, out):
    """LM fit of ``model`` to (t[:n], y[:n]) from ``p0``; results in ``out`` (module docstring)."""
    npar = 3 if model == GAUSS else 4
    imu = npar - 2  # index of mu; the width follows it
    p = np.empty(4)
    trial = np.empty(4)
    for a in range(4):
        p[a] = p0[a] if a < npar else 0.0
        trial[a] = p[a]
    jtj = np.empty((4, 4))
    jtr = np.empty(4)
    jtj_t = np.empty((4, 4))  # normal equations at the trial point: one pass gives cost and J
    jtr_t = np.empty(4)
    jrow = np.empty(4)
    m = np.empty((4, 5))
    lam = 1e-4  # as locate.erf_kernels: near Gauss-Newton from a data-driven start
    cost = _normal_eq(model, t, y, n, p, npar, jtj, jtr, jrow)
    status = NOT_CONVERGED
    it = 0
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
        for a in range(npar):
            trial[a] = p[a] + m[a, npar]
        if trial[imu + 1] < W_MIN:
            trial[imu + 1] = W_MIN
        new_cost = _normal_eq(model, t, y, n, trial, npar, jtj_t, jtr_t, jrow)
        if new_cost <= cost:
            step_mu = abs(trial[imu] - p[imu])
            step_w = abs(trial[imu + 1] - p[imu + 1])
            for a in range(npar):
                p[a] = trial[a]
                jtr[a] = jtr_t[a]
                for b in range(npar):
                    jtj[a, b] = jtj_t[a, b]
            cost = new_cost
            lam = max(lam * 0.1, 1e-12)
            if step_mu < tol and step_w < tol:
                status = OK
                break
        else:
            lam *= 10.0
            if lam > 1e12:
                status = OK  # no decrease possible: a minimum to machine precision
                break
    # (J^T J)^-1_{mu,mu} of the undamped problem at the solution
    for a in range(npar):
        for b in range(npar):
            m[a, b] = jtj[a, b]
        m[a, npar] = 1.0 if a == imu else 0.0
    c_mumu = m[imu, npar] if _solve(m, npar) else np.inf
    if status == OK:
        amp = p[0] if model == GAUSS else p[1]
        if not (t[0] <= p[imu] <= t[n - 1] and W_MIN < p[imu + 1] < 2.0 * (t[n - 1] - t[0]) and amp > 0.0):
            status = OUT_OF_WINDOW
    for a in range(4):
        out[a] = p[a]
    out[4] = cost
    out[5] = c_mumu
    out[6] = it
    out[7] = status


@numba.njit(cache=True)
def fit_auto(model, t, y, n, maxit, tol, out):
    """``initial_guess`` then ``fit_one``; NO_CONTRAST when the guess is undefined."""
    p0 = np.zeros(4)
    if not initial_guess(model, t, y, n, p0):
        for a in range(OUT_LEN):
            out[a] = 0.0
        out[5] = np.inf
        out[7] = NO_CONTRAST
        return
    fit_one(model, t, y, n, p0, maxit, tol, out)


@numba.njit(cache=True, parallel=True)
def fit_batch(model, t, ys, maxit, tol, out):
    """Fit every row of ``ys`` (N, n) at abscissae ``t`` (n,); out (N, 8)."""
    n = t.shape[0]
    for i in numba.prange(ys.shape[0]):
        fit_auto(model, t, ys[i], n, maxit, tol, out[i])


@numba.njit(cache=True, parallel=True)
def fit_batch_from(model, t, ys, p0s, maxit, tol, out):
    """Fit every row of ``ys`` from the given start parameters ``p0s`` (N, 4)."""
    n = t.shape[0]
    for i in numba.prange(ys.shape[0]):
        fit_one(model, t, ys[i], n, p0s[i], maxit, tol, out[i])


def fit_profiles(ys, t, model: int, maxit: int = 100, tol: float = 1e-10, p0=None) -> np.ndarray:
    """Python entry: fit rows of ``ys`` (N, n) sampled at ``t`` (n,) with ``model``; returns (N, 8)."""
    ys = np.ascontiguousarray(np.atleast_2d(ys), np.float64)
    t = np.ascontiguousarray(t, np.float64)
    if ys.shape[1] != t.shape[0]:
        raise ValueError(f"profiles have {ys.shape[1]} samples but t has {t.shape[0]}")
    if model not in MODEL_NAMES:
        raise ValueError(f"model code {model}: choose one of {sorted(MODEL_NAMES)}")
    out = np.empty((ys.shape[0], OUT_LEN))
    if ys.shape[0] == 0:
        return out
    if p0 is None:
        fit_batch(int(model), t, ys, int(maxit), float(tol), out)
    else:
        p0s = np.zeros((ys.shape[0], 4))
        p0 = np.atleast_2d(np.asarray(p0, np.float64))
        p0s[:, :p0.shape[1]] = p0
        fit_batch_from(int(model), t, ys, p0s, int(maxit), float(tol), out)
    return out


def refine_step_model(image, cand, model: int, maxit: int = 100, tol: float = 1e-7):
    """Fit a step model (ERF, ARCTAN, LOGISTIC) to each candidate's 11-sample normal profile.

    Returns ``Refinement`` with the edge at p + mu n where the fit converged
    inside the window (else the candidate pixel, converged=False); extras A,
    B, width (model width w, px), offset, rss, iterations, status, se (standard
    error of mu from the image's pooled residual variance, as in
    ``edgetruth.locate.methods.erf``).
    """
    from edgetruth.locate.profiles import profile_offsets, sample_profiles

    if model == GAUSS:
        raise ValueError("refine_step_model fits step models only")
    t = profile_offsets()
    prof = sample_profiles(image, cand)
    out = fit_profiles(prof, t, model, maxit, tol)
    return finish(cand, out, t.size, 4, mu_index=2, width_index=3, amp_names=("A", "B"))


def finish(cand, out, n_samples: int, npar: int, mu_index: int, width_index: int, amp_names, **extras):
    from edgetruth.locate.result import Refinement

    status = out[:, 7].astype(np.int64)
    conv = status == OK
    mu = np.where(conv, out[:, mu_index], 0.0)
    dof = n_samples - npar
    use = conv & np.isfinite(out[:, 4]) & np.isfinite(out[:, 5])
    sigma2 = out[use, 4].sum() / (dof * use.sum()) if use.any() else np.nan
    c_mumu = out[:, 5]
    se = np.where(conv & (c_mumu > 0), np.sqrt(sigma2 * np.where(c_mumu > 0, c_mumu, np.nan)), np.nan)
    named = {name: out[:, i] for i, name in enumerate(amp_names)}
    return Refinement.from_offset(
        cand, mu, conv, **named, width=out[:, width_index], rss=out[:, 4],
        iterations=out[:, 6].astype(np.int64), status=status, se=se, **extras)
