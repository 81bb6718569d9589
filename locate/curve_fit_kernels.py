"""Batched least-squares curve fits for the curve-fitting baselines (numba, parallel over points).

The same care as the ERF kernels (``edgetruth.locate.erf_kernels``): per point only scalars --
normal equations accumulated in one pass over the samples, a scalar Cholesky solve, no array
allocated per point -- and one transcendental call per sample.  One Levenberg-Marquardt serves
four models, chosen by a model code:

====  ==========  ===========================================  ======================  ==================
code  name        model y(t)                                   used by                 per sample
====  ==========  ===========================================  ======================  ==================
0     erf         A + B * Phi(z),           z = (t - mu) / w   HagaraAEF2011           one exp (+ a series)
1     arctan      A + B * (1/2 + atan(z) / pi)                 ArctanFit2016           one atan
2     logistic    A + B / (1 + exp(-z))                        SigmoidLogisticFit2023  one exp
3     gauss       a * exp(-z^2 / 2)   (no constant term)       GaussianFit2014         one exp
====  ==========  ===========================================  ======================  ==================

Step models (0-2) have parameters p = (A, B, mu, w): A the dark level, B the
contrast, mu the 50 % crossing (the edge), w the model's width.  The Gaussian
has p = (a, mu, w): amplitude, peak (the edge) and standard deviation.  The
model's derivative needs no second transcendental: Phi and Phi' come from the
same exp (``locate.normal_cdf``: erfc = exp(-x^2) erfcx(x), erfcx piecewise polynomial,
|Phi error| < 2e-13), atan' = 1 / (1 + z^2), logistic' = f (1 - f).

Samples are (t_k, y_k), k < n, with any abscissae (step fits use t = -5..5,
the Gaussian fit the half-integer positions of profile differences).

Initial values (``initial_guess``), from the data only, in closed form:
    step models: A = min y, B = max y - min y; mu and the second moment var
    of the positive differences y_{k+1} - y_k (as a distribution over the
    mid-points), var reduced by 1/12 for the unit sampling; w matched to a
    Gaussian of that variance by equal slope at the centre:
    erf w = sd, arctan w = sd * sqrt(2/pi), logistic w = sd * sqrt(2 pi) / 4.
    (The start decides which minimum a flat near-step fit lands in, so it is
    the replaced kernel's, unchanged.)
    gauss: the three-point log-parabola (Gaussian) interpolation through the
    largest sample and its neighbours gives mu, w and a; where it is
    undefined (a non-positive neighbour) mu = t of the largest sample, w = 1.

Levenberg-Marquardt: Marquardt's diagonal scaling (lambda (diag J^T J + 1e-12)),
lambda from 1e-4 (near Gauss-Newton from the data-driven start), x0.1 on an
accepted step, x10 on a rejected one; converged when a step moves mu by less
than ``tol`` (px) and w by less than W_TOL_FACTOR tol (step models; tol for the
Gaussian, whose width and peak are coupled) -- that step is taken
without evaluating its cost, the answer moving by < tol -- or when no step can
decrease the cost (lambda > 1e12: a minimum to machine precision).  w is kept
>= W_MIN.  The kernel this one replaced (kept in tests/support as the reference
it is tested against: same fits to < 1e-6 px) evaluated that last step and held
w to tol as well.

Output per point (``fit_profiles``): out[0:4] parameters (for the Gaussian
out[0:3] = a, mu, w and out[3] = 0), out[4] residual sum of squares, out[5] the
(mu, mu) element of (J^T J)^-1, out[6] iterations, out[7] status (``OK``,
``NOT_CONVERGED``, ``NO_CONTRAST``, ``OUT_OF_WINDOW``).
"""
from __future__ import annotations

import math

import numpy as np

from edgetruth.locate.erf_kernels import _chol4
from edgetruth.locate.normal_cdf import cdf_pdf
from edgetruth.locate.fit_status import NO_CONTRAST, NOT_CONVERGED, OK, OUT_OF_WINDOW
from edgetruth.locate.profiles import bilinear
from edgetruth.jit import njit, prange, variant  # numba, imported when a kernel is first called

ERF = 0
ARCTAN = 1
LOGISTIC = 2
GAUSS = 3
MODEL_NAMES = {ERF: "erf", ARCTAN: "arctan", LOGISTIC: "logistic", GAUSS: "gauss"}

W_MIN = 0.05  # width floor (px)
#: a step model's width, a nuisance, converges to W_TOL_FACTOR x tol (1e-5 px at the default 1e-7, the ERF
#: kernels' rule); the Gaussian's width is coupled to its peak and stays at tol
W_TOL_FACTOR = 100.0
OUT_LEN = 8
PROFILE_HALF = 5
PROFILE_LEN = 2 * PROFILE_HALF + 1

_INV_SQRT2PI = 1.0 / math.sqrt(2.0 * math.pi)
_INV_PI = 1.0 / math.pi
# equal central slope with a Gaussian of unit sd
_W_ARCTAN = math.sqrt(2.0 / math.pi)
_W_LOGISTIC = math.sqrt(2.0 * math.pi) / 4.0

__all__ = ["ERF", "ARCTAN", "LOGISTIC", "GAUSS", "OK", "NOT_CONVERGED", "NO_CONTRAST", "OUT_OF_WINDOW",
           "model_value", "initial_guess", "fit_profiles", "refine_step_model", "refine_gauss_differences"]


@njit(cache=True, inline="always")
def _shape(model, z):
    """F(z) and F'(z) of a step model, one transcendental call."""
    if model == ERF:
        return cdf_pdf(z)
    if model == ARCTAN:
        return 0.5 + math.atan(z) * _INV_PI, _INV_PI / (1.0 + z * z)
    e = math.exp(-abs(z))  # logistic, overflow-free
    f = 1.0 / (1.0 + e) if z >= 0.0 else e / (1.0 + e)
    return f, f * (1.0 - f)


@njit(cache=True)
def model_value(model, p, t):
    """y(t) of ``model`` at parameters ``p``."""
    if model == GAUSS:
        z = (t - p[1]) / p[2]
        return p[0] * math.exp(-0.5 * z * z)
    f, _ = _shape(model, (t - p[2]) / p[3])
    return p[0] + p[1] * f


@njit(cache=True, inline="always")
def _eval_step(model, t, y, n, A, B, mu, w):
    """One pass: cost, J^T J (lower triangle, 10 scalars) and J^T r of a step model."""
    c = 0.0
    h10 = h11 = h20 = h21 = h22 = h30 = h31 = h32 = h33 = 0.0
    g0 = g1 = g2 = g3 = 0.0
    inv_w = 1.0 / w
    for k in range(n):
        z = (t[k] - mu) * inv_w
        f, d = _shape(model, z)
        r = A + B * f - y[k]
        c += r * r
        j2 = -B * d * inv_w
        j3 = j2 * z
        h10 += f
        h11 += f * f
        h20 += j2
        h21 += f * j2
        h22 += j2 * j2
        h30 += j3
        h31 += f * j3
        h32 += j2 * j3
        h33 += j3 * j3
        g0 += r
        g1 += f * r
        g2 += j2 * r
        g3 += j3 * r
    return c, float(n), h10, h11, h20, h21, h22, h30, h31, h32, h33, g0, g1, g2, g3


@njit(cache=True, inline="always")
def _eval_gauss(t, y, n, a, mu, w):
    """One pass: cost, J^T J (6 scalars) and J^T r of a * exp(-z^2/2)."""
    c = 0.0
    h00 = h10 = h11 = h20 = h21 = h22 = 0.0
    g0 = g1 = g2 = 0.0
    inv_w = 1.0 / w
    for k in range(n):
        z = (t[k] - mu) * inv_w
        e = math.exp(-0.5 * z * z)
        r = a * e - y[k]
        c += r * r
        j1 = a * e * z * inv_w
        j2 = j1 * z
        h00 += e * e
        h10 += j1 * e
        h11 += j1 * j1
        h20 += j2 * e
        h21 += j2 * j1
        h22 += j2 * j2
        g0 += e * r
        g1 += j1 * r
        g2 += j2 * r
    return c, h00, h10, h11, h20, h21, h22, g0, g1, g2


@njit(cache=True, inline="always")
def _chol3(m00, m10, m11, m20, m21, m22, b0, b1, b2):
    """Solve a symmetric positive-definite 3x3 system by Cholesky, in scalars: (ok, x0, x1, x2)."""
    if not m00 > 0.0:
        return False, 0.0, 0.0, 0.0
    l00 = math.sqrt(m00)
    l10 = m10 / l00
    l20 = m20 / l00
    d = m11 - l10 * l10
    if not d > 0.0:
        return False, 0.0, 0.0, 0.0
    l11 = math.sqrt(d)
    l21 = (m21 - l20 * l10) / l11
    d = m22 - l20 * l20 - l21 * l21
    if not d > 0.0:
        return False, 0.0, 0.0, 0.0
    l22 = math.sqrt(d)
    y0 = b0 / l00
    y1 = (b1 - l10 * y0) / l11
    y2 = (b2 - l20 * y0 - l21 * y1) / l22
    x2 = y2 / l22
    x1 = (y1 - l21 * x2) / l11
    x0 = (y0 - l10 * x1 - l20 * x2) / l00
    return True, x0, x1, x2


@njit(cache=True, inline="always")
def _step_guess(model, t, y, n):
    """Closed-form start of a step model: (ok, A, B, mu, w) (module docstring)."""
    ymin = y[0]
    ymax = y[0]
    for k in range(n):
        if y[k] < ymin:
            ymin = y[k]
        if y[k] > ymax:
            ymax = y[k]
    B = ymax - ymin
    if not B > 0.0:
        return False, 0.0, 0.0, 0.0, 0.0
    g_sum = 0.0
    g_t = 0.0
    for k in range(n - 1):
        g = y[k + 1] - y[k]
        if g > 0.0:
            g_sum += g
            g_t += g * 0.5 * (t[k] + t[k + 1])
    if not g_sum > 0.0:
        return False, 0.0, 0.0, 0.0, 0.0
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
    return True, ymin, B, mu, sd


@njit(cache=True, inline="always")
def _gauss_guess(t, y, n):
    """Closed-form start of the Gaussian: the log-parabola through the largest sample: (ok, a, mu, w)."""
    kmax = 0
    for k in range(1, n):
        if y[k] > y[kmax]:
            kmax = k
    a = y[kmax]
    if not a > 0.0:
        return False, 0.0, 0.0, 0.0
    mu = t[kmax]
    w = 1.0
    if 0 < kmax < n - 1 and y[kmax - 1] > 0.0 and y[kmax + 1] > 0.0:
        lm = math.log(y[kmax - 1])
        l0 = math.log(a)
        lp = math.log(y[kmax + 1])
        den = lm - 2.0 * l0 + lp
        h = t[kmax + 1] - t[kmax]
        if den < 0.0:
            off = 0.5 * (lm - lp) / den
            mu = t[kmax] + off * h
            w = max(h * math.sqrt(-1.0 / den), W_MIN)
            a = math.exp(l0 - 0.25 * (lm - lp) * off)
    return True, a, mu, w


@njit(cache=True)
def initial_guess(model, t, y, n, p):
    """Data-driven start into p (see module docstring); returns False if the samples have no contrast."""
    if model == GAUSS:
        ok, a, mu, w = _gauss_guess(t, y, n)
        if ok:
            p[0] = a
            p[1] = mu
            p[2] = w
        return ok
    ok, A, B, mu, w = _step_guess(model, t, y, n)
    if ok:
        p[0] = A
        p[1] = B
        p[2] = mu
        p[3] = w
    return ok


# Reassociation and fused multiply-adds (no NaN/Inf assumptions: the checks keep their meaning) let LLVM
# schedule the per-sample sums freely: 10-50 % faster, answers unchanged beyond rounding -- except on
# the erf model's flat near-step fits (w ~ 0.1 px), where rounding can pick another of its minima
# within the pixel: the erf model keeps strict arithmetic.
_FAST = {"contract", "reassoc"}


@njit(cache=True)
def fit_step(model, t, y, n, A, B, mu, w, maxit, tol, out):
    """LM fit of a step model to (t[:n], y[:n]) from (A, B, mu, w); out as in the module docstring."""
    lam = 1e-4
    c, h00, h10, h11, h20, h21, h22, h30, h31, h32, h33, g0, g1, g2, g3 = _eval_step(model, t, y, n, A, B, mu, w)
    status = NOT_CONVERGED
    it = 0
    while it < maxit:
        it += 1
        ok, d0, d1, d2, d3 = _chol4(h00 + lam * (h00 + 1e-12), h10, h11 + lam * (h11 + 1e-12), h20, h21,
                                    h22 + lam * (h22 + 1e-12), h30, h31, h32, h33 + lam * (h33 + 1e-12),
                                    -g0, -g1, -g2, -g3)
        if not ok:
            lam *= 10.0
            if lam > 1e12:
                break
            continue
        nw = w + d3
        if nw < W_MIN:
            nw = W_MIN
        if abs(d2) < tol and abs(nw - w) < W_TOL_FACTOR * tol:
            # the last step: taken without evaluating its cost (the answer moves by < tol)
            A += d0
            B += d1
            mu += d2
            w = nw
            status = OK
            break
        e = _eval_step(model, t, y, n, A + d0, B + d1, mu + d2, nw)
        if e[0] <= c:
            step_mu = abs(d2)
            step_w = abs(nw - w)
            A += d0
            B += d1
            mu += d2
            w = nw
            c, h00, h10, h11, h20, h21, h22, h30, h31, h32, h33, g0, g1, g2, g3 = e
            lam = max(lam * 0.1, 1e-12)
            if step_mu < tol and step_w < W_TOL_FACTOR * tol:
                status = OK
                break
        else:
            lam *= 10.0
            if lam > 1e12:
                status = OK  # no decrease possible: a minimum to machine precision
                break
    ok, x0, x1, x2, x3 = _chol4(h00, h10, h11, h20, h21, h22, h30, h31, h32, h33, 0.0, 0.0, 1.0, 0.0)
    c_mumu = x2 if ok else np.inf
    if status == OK:
        if not (t[0] <= mu <= t[n - 1] and W_MIN < w < 2.0 * (t[n - 1] - t[0]) and B > 0.0):
            status = OUT_OF_WINDOW
    out[0] = A
    out[1] = B
    out[2] = mu
    out[3] = w
    out[4] = c
    out[5] = c_mumu
    out[6] = it
    out[7] = status


#: ``fit_step`` with reassociated sums (the arctangent and logistic models)
fit_step_fast = variant(fit_step, "fit_step_fast", fastmath=_FAST)


@njit(cache=True, fastmath=_FAST)
def fit_gauss(t, y, n, a, mu, w, maxit, tol, out):
    """LM fit of a * exp(-((t - mu)/w)^2 / 2) to (t[:n], y[:n]) from (a, mu, w)."""
    lam = 1e-4
    c, h00, h10, h11, h20, h21, h22, g0, g1, g2 = _eval_gauss(t, y, n, a, mu, w)
    status = NOT_CONVERGED
    it = 0
    while it < maxit:
        it += 1
        ok, d0, d1, d2 = _chol3(h00 + lam * (h00 + 1e-12), h10, h11 + lam * (h11 + 1e-12), h20, h21,
                                h22 + lam * (h22 + 1e-12), -g0, -g1, -g2)
        if not ok:
            lam *= 10.0
            if lam > 1e12:
                break
            continue
        nw = w + d2
        if nw < W_MIN:
            nw = W_MIN
        if abs(d1) < tol and abs(nw - w) < tol:
            a += d0
            mu += d1
            w = nw
            status = OK
            break
        e = _eval_gauss(t, y, n, a + d0, mu + d1, nw)
        if e[0] <= c:
            step_mu = abs(d1)
            step_w = abs(nw - w)
            a += d0
            mu += d1
            w = nw
            c, h00, h10, h11, h20, h21, h22, g0, g1, g2 = e
            lam = max(lam * 0.1, 1e-12)
            if step_mu < tol and step_w < tol:
                status = OK
                break
        else:
            lam *= 10.0
            if lam > 1e12:
                status = OK
                break
    ok, x0, x1, x2 = _chol3(h00, h10, h11, h20, h21, h22, 0.0, 1.0, 0.0)
    c_mumu = x1 if ok else np.inf
    if status == OK:
        if not (t[0] <= mu <= t[n - 1] and W_MIN < w < 2.0 * (t[n - 1] - t[0]) and a > 0.0):
            status = OUT_OF_WINDOW
    out[0] = a
    out[1] = mu
    out[2] = w
    out[3] = 0.0
    out[4] = c
    out[5] = c_mumu
    out[6] = it
    out[7] = status


@njit(cache=True, inline="always")
def _no_contrast(out):
    for a in range(OUT_LEN):
        out[a] = 0.0
    out[5] = np.inf
    out[7] = NO_CONTRAST


@njit(cache=True)
def fit_auto(model, t, y, n, maxit, tol, out):
    """``initial_guess`` then the fit; NO_CONTRAST when the guess is undefined."""
    if model == GAUSS:
        ok, a, mu, w = _gauss_guess(t, y, n)
        if not ok:
            _no_contrast(out)
            return
        fit_gauss(t, y, n, a, mu, w, maxit, tol, out)
        return
    ok, A, B, mu, w = _step_guess(model, t, y, n)
    if not ok:
        _no_contrast(out)
        return
    if model == ERF:
        fit_step(model, t, y, n, A, B, mu, w, maxit, tol, out)
    else:
        fit_step_fast(model, t, y, n, A, B, mu, w, maxit, tol, out)


@njit(cache=True, parallel=True)
def _fit_batch(model, t, ys, maxit, tol, out):
    n = t.shape[0]
    for i in prange(ys.shape[0]):
        fit_auto(model, t, ys[i], n, maxit, tol, out[i])


@njit(cache=True, parallel=True)
def _fit_batch_from(model, t, ys, p0s, maxit, tol, out):
    n = t.shape[0]
    for i in prange(ys.shape[0]):
        p = p0s[i]
        if model == GAUSS:
            fit_gauss(t, ys[i], n, p[0], p[1], p[2], maxit, tol, out[i])
        elif model == ERF:
            fit_step(model, t, ys[i], n, p[0], p[1], p[2], p[3], maxit, tol, out[i])
        else:
            fit_step_fast(model, t, ys[i], n, p[0], p[1], p[2], p[3], maxit, tol, out[i])


@njit(cache=True, parallel=True)
def _refine_kernel(model, img, xs, ys, nxs, nys, t, work, maxit, tol, out):
    """Sample each candidate's 11-point normal profile into its row of ``work`` and fit it (step models),
    or fit the Gaussian to its 10 differences at the mid-points ``t`` (GAUSS): all points in parallel."""
    n = t.shape[0]  # typed, not the literal PROFILE_LEN: one compiled fit_auto serves both branches (and fit_profiles)
    for i in prange(xs.shape[0]):
        prof = work[i]
        for k in range(PROFILE_LEN):
            tk = float(k - PROFILE_HALF)
            prof[k] = bilinear(img, xs[i] + tk * nxs[i], ys[i] + tk * nys[i])
        if model == GAUSS:
            for k in range(PROFILE_LEN - 1):
                prof[k] = prof[k + 1] - prof[k]
            fit_auto(model, t, prof, n, maxit, tol, out[i])
        else:
            fit_auto(model, t, prof, n, maxit, tol, out[i])


_T_STEP = np.arange(-PROFILE_HALF, PROFILE_HALF + 1, dtype=np.float64)
_T_DIFF = 0.5 * (_T_STEP[1:] + _T_STEP[:-1])


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
        _fit_batch(int(model), t, ys, int(maxit), float(tol), out)
    else:
        p0s = np.zeros((ys.shape[0], 4))
        p0 = np.atleast_2d(np.asarray(p0, np.float64))
        p0s[:, :p0.shape[1]] = p0
        _fit_batch_from(int(model), t, ys, p0s, int(maxit), float(tol), out)
    return out


def _refine(image, cand, model, maxit, tol):
    out = np.empty((len(cand), OUT_LEN))
    if len(cand):
        work = np.empty((len(cand), PROFILE_LEN))
        _refine_kernel(int(model), np.ascontiguousarray(image, np.float64), cand.x, cand.y, cand.nx, cand.ny,
                       _T_DIFF if model == GAUSS else _T_STEP, work, int(maxit), float(tol), out)
    return out


def refine_step_model(image, cand, model: int, maxit: int = 100, tol: float = 1e-7):
    """Fit a step model (ERF, ARCTAN, LOGISTIC) to each candidate's 11-sample normal profile.

    Returns ``Refinement`` with the edge at p + mu n where the fit converged
    inside the window (else the candidate pixel, converged=False); extras A,
    B, width (model width w, px), offset, rss, iterations, status, se (standard
    error of mu from the image's pooled residual variance, as in
    ``edgetruth.locate.methods.erf``).
    """
    if model == GAUSS:
        raise ValueError("refine_step_model fits step models only")
    out = _refine(image, cand, model, maxit, tol)
    return finish(cand, out, PROFILE_LEN, 4, mu_index=2, width_index=3, amp_names=("A", "B"))


def refine_gauss_differences(image, cand, maxit: int = 100, tol: float = 1e-7):
    """Gaussian fit of the 10 differences of each candidate's 11-sample normal profile (GaussianFit2014)."""
    out = _refine(image, cand, GAUSS, maxit, tol)
    return finish(cand, out, PROFILE_LEN - 1, 3, mu_index=1, width_index=2, amp_names=("amplitude",))


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
