"""patch_esf_fit: the patch fit of ``patch_psf_fit`` with the camera's exact edge-spread function.

For when the camera's PSF is known from its model (Airy ⊗ aberration ⊗ defocus disk ⊗ OLPF, box-integrated:
``edgetruth.evaluate.bound_psf.EdgeSpread`` tabulates it).  For each candidate p the method fits the same
pixels as ``patch_psf_fit`` -- the rectangle |t| <= 5 along the candidate's normal, |u| <= 2 along the edge
(its footprint) -- with the expected image the exact Cramér–Rao bound is computed from:

    m(x) = A + B * (P(x; rho, phi) + (lambda - 1) L(x; rho, phi))

- P: the tabulated unit edge (``locate.esf_tables``: cubic Hermite in the signed distance d, linear in the
  normal's direction), a line through p - rho n(phi), or an arc whose curvature comes from the candidates'
  gradient field (``patch_psf_fit.curvatures``, kappa = -div n, averaged over the neighbouring candidates:
  ``curvature``) with the bend of the pixel and of the PSF's tangential spread;
- L = lambda dP/dlambda, the PSF's scale to first order (the model is exact at lambda = 1, the camera's
  own PSF; the bound's Jacobian in lambda is this L): lambda is fitted unless ``blur_known``.

Unknowns (rho, phi, A, B, lambda) -- (rho, phi, A, B) with ``blur_known`` -- by Levenberg–Marquardt,
batched: every iteration evaluates the model of all still-active points in one pass of the shared table
kernel, their normal equations in one parallel numba kernel, and their damped steps in another.  The
Jacobian is the kernel's chain rule, the (lambda - 1) L term's slopes in rho and phi included (without
them the Gauss-Newton step's fixed point is not the cost's minimum where lambda is far from 1 -- per point
its scatter is ~0.1 --, steps are refused and the damping stalls: the points at the 3e-3 px tolerance lay
up to 3e-3 px from those at 1e-7; with them, 1.1e-3).  Noise weighting
(``variance``): the pixel variance as a function of its mean, var = a + b m (+ c m²) (EMVA: a = K² σd² +
1/12 - K·offset, b = K in DN), or a callable mean -> variance; evaluated at the model's mean (not the
data: no bias from the noise), held fixed within a step and renewed after each accepted one
(iteratively reweighted least squares), floored at 1e-3 of the patch's largest.  Without it the fit is
unweighted.  The start is ``patch_psf_fit``'s: a 7-sample 4P ERF fit of the normal profile (two steps),
lambda = 1.

Output: the foot point p - rho n on the edge, the fitted normal n(phi), ``se`` the position's standard
error (px): sqrt((F^-1)_rho,rho) with F = J^T W J at the solution when ``variance`` is given, else
sigma * sqrt((J^T J)^-1) with sigma² the pooled residual variance (as ``patch_psf_fit``).  Extras: A, B,
lambda, kappa, offset (-rho), rss (the weighted residual sum of squares), iterations, status, npix, se.
Failure (converged=False): no contrast, no convergence, |rho| > 2 px, B <= 0, lambda outside
(0.5, 2) (the first-order model's range).

Needs the camera (``esf``): the render study builds the tables from each image's JSON
(``evaluate.points.bound.esf_for_points``); the synthetic and board studies, which have no camera model,
leave it out (``register(..., needs_camera=True)``).  Docs: docs/bound.md, "patch_esf_fit".
"""
from __future__ import annotations

import math

import numpy as np

from edgetruth.errors import InputError
from edgetruth.jit import before_compile, njit, prange
from edgetruth.locate import erf_kernels as K
from edgetruth.locate import footprints as FP
from edgetruth.locate.esf_tables import EsfTables, means
from edgetruth.locate.fit_status import NO_CONTRAST, NOT_CONVERGED, OK, OUT_OF_WINDOW
from edgetruth.locate.methods import patch_psf_fit as PF
from edgetruth.locate.profiles import sample_profiles
from edgetruth.locate.registry import register
from edgetruth.locate.result import Refinement

HALF_NORMAL = PF.HALF_NORMAL
HALF_TANGENT = PF.HALF_TANGENT
MAXIT = 40
TOL_PX = 3e-3  # the step (rho px, phi rad, lambda relative) that ends the fit, taken without another pass
RHO_MAX = PF.RHO_MAX
LAMBDA_MIN, LAMBDA_MAX = 0.5, 2.0  # the first-order model in lambda: beyond this range it is not the PSF
CHUNK = 4096  # points per batch: the (points x patch pixels) work arrays stay ~4 MB each
KAPPA_RADIUS_PX = 5.0  # the curvature is averaged over the candidates within this radius (``curvature``)
_SAME_EDGE_COS = math.cos(math.radians(30.0))
VAR_FLOOR, VAR_FLOOR_REL = 1e-9, 1e-3  # the pixel variance's floor (gray levels²; and relative to the patch's largest)
_solve = None  # locate.small_linalg.cholesky_solve, bound when the kernels first compile


@before_compile
def _bind_solver():
    global _solve
    from edgetruth.locate.small_linalg import cholesky_solve

    _solve = cholesky_solve


@njit(cache=True, parallel=True)
def _normal_equations(vals, use, w, M, Jr, Jp, Jl, Lr, Lp, A, B, dl, npar, H, g, cost):
    """Per point: cost = sum w r², H = J^T W J, g = -J^T W r of the model A + B (M + dl Jl) against
    ``vals`` over the ``use`` pixels; J = (B (Jr + dl Lr), B (Jp + dl Lp), 1, M + dl Jl, B Jl)[:npar]."""
    n, npx = M.shape
    for i in prange(n):
        jac = np.empty(5)
        for a in range(npar):
            g[i, a] = 0.0
            for b in range(npar):
                H[i, a, b] = 0.0
        c = 0.0
        for k in range(npx):
            if not use[i, k]:
                continue
            mk = M[i, k] + dl[i] * Jl[i, k]
            r = A[i] + B[i] * mk - vals[i, k]
            wk = w[i, k]
            jac[0] = B[i] * (Jr[i, k] + dl[i] * Lr[i, k])
            jac[1] = B[i] * (Jp[i, k] + dl[i] * Lp[i, k])
            jac[2] = 1.0
            jac[3] = mk
            jac[4] = B[i] * Jl[i, k]
            c += wk * r * r
            for a in range(npar):
                wa = wk * jac[a]
                g[i, a] -= wa * r
                for b in range(a + 1):
                    H[i, a, b] += wa * jac[b]
        for a in range(npar):
            for b in range(a):
                H[i, b, a] = H[i, a, b]
        cost[i] = c


@njit(cache=True, parallel=True)
def _damped_steps(H, g, damp, npar, step, ok):
    """Solve (H + damp diag(H)) step = g per point (Cholesky); ok False where not positive definite."""
    for i in prange(H.shape[0]):
        Hs = np.empty((5, 5))
        x = np.empty(5)
        rhs = np.empty(5)
        for a in range(npar):
            rhs[a] = g[i, a]
            for b in range(npar):
                Hs[a, b] = H[i, a, b]
            Hs[a, a] = H[i, a, a] * (1.0 + damp[i]) + 1e-30
        ok[i] = _solve(Hs, rhs, npar, x)
        for a in range(npar):
            step[i, a] = x[a] if ok[i] else 0.0


@njit(cache=True, parallel=True)
def _rho_variance(H, npar, out):
    """(H^-1)_rho,rho per point (inf where H is not positive definite)."""
    for i in prange(H.shape[0]):
        Hs = np.empty((5, 5))
        x = np.empty(5)
        e = np.zeros(5)
        e[0] = 1.0
        for a in range(npar):
            for b in range(npar):
                Hs[a, b] = H[i, a, b]
        out[i] = x[0] if _solve(Hs, e, npar, x) else np.inf


def _variance_fn(variance):
    """The pixel variance (gray levels²) as a function of the mean: None (unweighted), (a, b[, c]) or a callable."""
    if variance is None:
        return None
    if callable(variance):
        return variance
    try:
        coef = [float(v) for v in variance]
    except (TypeError, ValueError):
        coef = []
    if len(coef) not in (2, 3) or not all(math.isfinite(v) for v in coef):
        raise InputError(f"variance={variance!r}: give (a, b) or (a, b, c) for var = a + b*mean (+ c*mean^2) in "
                         "gray levels^2 (EMVA: a = K^2 sigma_d^2 + 1/12 - K*offset, b = K), a callable, or None")
    a, b = coef[0], coef[1]
    c = coef[2] if len(coef) == 3 else 0.0
    return lambda m: a + b * m + c * m * m


def _tables(esf, bin_index, n: int):
    """(list of EsfTables, (n,) bin index) from the method's ``esf`` / ``bin_index`` options."""
    if esf is None:
        raise InputError("patch_esf_fit needs the camera's edge-spread tables: pass esf=EsfTables (e.g. "
                         "evaluate.bound_psf.EdgeSpread(optics).tables()); without a camera model use patch_psf_fit")
    tabs = [esf] if isinstance(esf, EsfTables) else list(esf)
    if not tabs or not all(isinstance(t, EsfTables) for t in tabs):
        raise InputError("esf: give an EsfTables or a sequence of them (one per field-height bin)")
    for t in tabs:
        if not (t.P.shape == t.dP.shape == t.L.shape and t.P.ndim == 2 and t.P.shape[0] >= 2):
            raise InputError("esf: P, dP and L must be (angle bins + 1, distances) arrays of one shape")
        if not np.all(t.P.any(axis=1)):  # a row EdgeSpread.stack did not build (all 0): tables(bins=None) builds all
            raise InputError("esf: some angle rows are empty; build every row (EdgeSpread.tables() with bins=None)")
    if bin_index is None:
        if len(tabs) > 1:
            raise InputError(f"esf has {len(tabs)} tables: pass bin_index, one table index per candidate")
        return tabs, np.zeros(n, np.int64)
    idx = np.asarray(bin_index)
    bad = idx.shape != (n,) or not np.issubdtype(idx.dtype, np.integer)
    if bad or (n and (idx.min() < 0 or idx.max() >= len(tabs))):
        raise InputError(f"bin_index: {n} integers in [0, {len(tabs)}) (one table index per candidate)")
    return tabs, idx.astype(np.int64)


def curvature(cand, radius_px: float = KAPPA_RADIUS_PX) -> np.ndarray:
    """kappa (1/px) per candidate: ``patch_psf_fit``'s -div n, averaged over the candidates within ``radius_px``
    whose normals agree within 30° (the same edge).  One pixel's -div n of a noisy gradient field scatters by
    ~0.02/px at SNR ~25, and an arc's bend over the patch (|u| <= 2) moves rho by ~kappa px (RMSE / bound 1.16
    on a straight edge, 1.19 on a circle); the mean over a 5-px radius cuts that scatter ~6x (0.022 -> 0.0036/px
    rms on straight edges; RMSE / bound 1.00 and 1.01; a 3-px radius: 0.006/px, 1.03 and 1.05)."""
    n = len(cand)
    kappa = np.zeros(n)
    if not n:
        return kappa
    PF.curvatures(cand.grad_x, cand.grad_y, cand.x, cand.y, kappa)
    if not radius_px > 0 or n < 2:
        return kappa
    from scipy.spatial import cKDTree

    pairs = cKDTree(np.column_stack([cand.x, cand.y])).query_pairs(float(radius_px), output_type="ndarray")
    a, b = pairs[:, 0], pairs[:, 1]
    same = cand.nx[a] * cand.nx[b] + cand.ny[a] * cand.ny[b] > _SAME_EDGE_COS
    a, b = a[same], b[same]
    total = kappa + np.bincount(a, kappa[b], n) + np.bincount(b, kappa[a], n)
    count = 1.0 + np.bincount(a, None, n) + np.bincount(b, None, n)
    return total / count


def _evaluate(tabs, bidx, geo, off, use):
    """(M, Jr, Jp, Jl, Lr, Lp) of the points of ``geo`` (each with its field bin's tables)."""
    n = geo["rho"].size
    if len(tabs) == 1:
        return means(tabs[0], geo, off, use, l_derivatives=True)
    out = tuple(np.zeros((n, off.shape[0])) for _ in range(6))
    for b in np.unique(bidx):  # the field-height bins (a few per image), not the points
        sel = np.nonzero(bidx == b)[0]
        part = means(tabs[b], {k: v[sel] for k, v in geo.items()}, off, use[sel], l_derivatives=True)
        for o, p in zip(out, part):
            o[sel] = p
    return out


def _fit_chunk(vals, use, geo, tabs, bidx, off, theta, npar, var_fn, maxit, tol):
    """Levenberg–Marquardt of every point of a chunk at once.  theta (n, 5) = (rho, phi, A, B, lambda) is
    updated in place; returns (status, iterations, cost, c_rhorho)."""
    n = theta.shape[0]
    status = np.full(n, NOT_CONVERGED, np.int64)
    iters = np.zeros(n, np.int64)
    cost = np.zeros(n)
    H = np.zeros((n, npar, npar))
    g = np.zeros((n, npar))
    damp = np.full(n, 1e-3)

    def model_at(idx, th):
        g_ = dict(geo_sub(idx), rho=th[:, 0], phi=th[:, 1])
        return _evaluate(tabs, bidx[idx], g_, off, use[idx])

    def geo_sub(idx):
        return {k: v[idx] for k, v in geo.items()}

    def weights(idx, th, Mv, Jl):
        if var_fn is None:
            return use[idx].astype(float)
        mean = th[:, 2:3] + th[:, 3:4] * (Mv + (th[:, 4:5] - 1.0) * Jl)
        var = np.where(use[idx], np.asarray(var_fn(mean), float), 0.0)
        # a model that gives ~0 (or less) somewhere (a linear one below the dark offset) would let one pixel weigh
        # without bound: floored at VAR_FLOOR_REL of the point's largest pixel variance
        var = np.maximum(var, np.maximum(VAR_FLOOR_REL * var.max(axis=1, keepdims=True), VAR_FLOOR))
        return np.where(use[idx], 1.0 / var, 0.0)

    def normal_eq(idx, th, d, w):
        Mv, Jr, Jp, Jl, Lr, Lp = d
        c = np.empty(idx.size)
        Hh = np.empty((idx.size, npar, npar))
        gg = np.empty((idx.size, npar))
        _normal_equations(vals[idx], use[idx], w, Mv, Jr, Jp, Jl, Lr, Lp, np.ascontiguousarray(th[:, 2]),
                          np.ascontiguousarray(th[:, 3]), np.ascontiguousarray(th[:, 4] - 1.0), npar, Hh, gg, c)
        return c, Hh, gg

    act = np.arange(n)
    d = model_at(act, theta)
    w_act = weights(act, theta, d[0], d[3])
    cost[act], H[act], g[act] = normal_eq(act, theta, d, w_act)
    W = np.zeros(vals.shape)
    W[act] = w_act
    for _ in range(maxit):
        if not act.size:
            break
        iters[act] += 1
        step = np.zeros((act.size, npar))
        ok = np.zeros(act.size, np.bool_)
        _damped_steps(np.ascontiguousarray(H[act]), np.ascontiguousarray(g[act]), damp[act], npar, step, ok)
        trial = theta[act].copy()
        trial[:, :npar] += step
        small = ok & (np.abs(step[:, 0]) < tol) & (np.abs(step[:, 1]) < tol)
        if npar == 5:
            small &= np.abs(step[:, 4]) < tol
        # converged: take this step without another pass (against 1e-7 px: points within 1.1e-3 px, RMSE / bound
        # unchanged to 1e-4; docs/bound.md)
        done = act[small]
        theta[done] = trial[small]
        status[done] = OK
        # not positive definite: more damping
        bad = act[~ok]
        damp[bad] *= 10.0
        go = ok & ~small
        idx = act[go]
        if idx.size:
            th = trial[go]
            dt = model_at(idx, th)
            Mv, Jl = dt[0], dt[3]
            r = th[:, 2:3] + th[:, 3:4] * (Mv + (th[:, 4:5] - 1.0) * Jl) - vals[idx]
            ncost = (W[idx] * r * r).sum(axis=1)  # the weights of the current point: one cost to compare
            better = np.isfinite(ncost) & (ncost <= cost[idx])
            acc = idx[better]
            if acc.size:
                theta[acc] = th[better]
                sub = tuple(v[better] for v in dt)
                wn = weights(acc, theta[acc], sub[0], sub[3])
                W[acc] = wn
                cost[acc], H[acc], g[acc] = normal_eq(acc, theta[acc], sub, wn)
                damp[acc] = np.maximum(damp[acc] * 0.1, 1e-12)
            damp[idx[~better]] *= 10.0
        act = act[(status[act] == NOT_CONVERGED) & (damp[act] <= 1e10)]
    c_rr = np.empty(n)
    if n:
        _rho_variance(np.ascontiguousarray(H), npar, c_rr)
    return status, iters, cost, c_rr


def esf_refine(image, cand, esf=None, bin_index=None, blur_known: bool = False, variance=None,
               half_normal: float = HALF_NORMAL, half_tangent: float = HALF_TANGENT, curved: bool = True,
               kappa_radius_px: float = KAPPA_RADIUS_PX, maxit: int = MAXIT, tol_px: float = TOL_PX) -> Refinement:
    var_fn = _variance_fn(variance)
    half_normal = float(half_normal)
    half_tangent = float(half_tangent)
    if not (1.0 <= half_normal <= FP.RADIUS and 0.0 <= half_tangent <= FP.RADIUS):
        raise InputError(f"half_normal={half_normal}, half_tangent={half_tangent}: need 1 <= half_normal <= "
                         f"{FP.RADIUS} and 0 <= half_tangent <= {FP.RADIUS} px")
    n = len(cand)  # (a spec check's stand-in candidates stop here: the tables are checked at run time)
    tabs, bidx = _tables(esf, bin_index, n)
    npar = 4 if blur_known else 5
    img = np.ascontiguousarray(image, np.float64)
    h, w = img.shape
    # the patch: patch_psf_fit's footprint, over the union of its offsets (one table pass per point)
    masks = FP.patch_masks(cand, half_normal, half_tangent)
    union = masks.any(axis=0) if n else np.zeros((FP.SIZE, FP.SIZE), bool)
    iy, ix = np.nonzero(union)
    off = np.stack([ix - FP.RADIUS, iy - FP.RADIUS], axis=1).astype(float)
    kappa = curvature(cand, kappa_radius_px) if curved else np.zeros(n)
    curved_pt = np.abs(kappa) >= 1e-7  # patch_psf_fit's line / arc rule
    geo = {"kind": curved_pt.astype(np.int64), "rho": np.zeros(n), "phi": np.arctan2(cand.ny, cand.nx),
           "radius": np.where(curved_pt, 1.0 / np.where(curved_pt, np.abs(kappa), 1.0), 0.0),
           "sgn": np.where(kappa > 0, 1.0, -1.0)}
    # the start: patch_psf_fit's (a 7-sample 4P ERF fit of the normal profile, two steps)
    prof = sample_profiles(img, cand) if n else np.zeros((0, 2 * K.PROFILE_HALF + 1))
    init = np.empty((n, 8))
    if n:
        K.fit_profiles(prof, np.full(n, PF._INIT_WINDOW, np.int64), True, PF._INIT_MAXIT, 1e-4, init)
    hw = (PF._INIT_WINDOW - 1) // 2
    rho0, A0, B0 = -init[:, 2], init[:, 0], init[:, 1]
    poor = ~((np.abs(rho0) <= hw) & (B0 > 0) & np.isfinite(rho0))  # a poor start: the candidate itself
    Ap = prof[:, K.PROFILE_HALF - hw]
    Bp = prof[:, K.PROFILE_HALF + hw] - Ap
    Bp = np.where(Bp > 0, Bp, 1e-3 + np.abs(Bp))
    theta = np.column_stack([np.where(poor, 0.0, rho0), geo["phi"], np.where(poor, Ap, A0), np.where(poor, Bp, B0),
                             np.ones(n)])
    status = np.full(n, NO_CONTRAST, np.int64)
    iters = np.zeros(n, np.int64)
    rss = np.full(n, np.nan)
    c_rr = np.full(n, np.nan)
    npix = np.zeros(n, np.int64)
    for c0 in range(0, n, CHUNK):
        sl = slice(c0, min(n, c0 + CHUNK))
        m = masks[sl][:, union]
        px = cand.x[sl].astype(np.int64)[:, None] + ix[None, :] - FP.RADIUS
        py = cand.y[sl].astype(np.int64)[:, None] + iy[None, :] - FP.RADIUS
        inside = (px >= 0) & (px < w) & (py >= 0) & (py < h)
        use = m & inside
        vals = np.where(use, img[np.clip(py, 0, h - 1), np.clip(px, 0, w - 1)], 0.0)
        npix[sl] = use.sum(axis=1)
        fit = (init[sl, 7] != NO_CONTRAST) & (npix[sl] > npar)
        k = np.nonzero(fit)[0]
        if not k.size:
            continue
        th = theta[sl][k]
        st, it, cs, cr = _fit_chunk(np.ascontiguousarray(vals[k]), np.ascontiguousarray(use[k]),
                                    {kk: v[sl][k] for kk, v in geo.items()}, tabs, bidx[sl][k], off, th, npar,
                                    var_fn, int(maxit), float(tol_px))
        gi = c0 + k
        theta[gi] = th
        status[gi], iters[gi], rss[gi], c_rr[gi] = st, it, cs, cr
    rho, phi, A, B, lam = theta.T
    out_of = (status == OK) & ~((np.abs(rho) <= RHO_MAX) & (B > 0) & (lam > LAMBDA_MIN) & (lam < LAMBDA_MAX))
    status = np.where(out_of, OUT_OF_WINDOW, status)
    conv = status == OK
    if var_fn is None:  # unweighted: the noise level from the residuals, pooled over the image
        dof = npix - npar
        ok = conv & (dof > 0) & np.isfinite(rss)
        sigma2 = rss[ok].sum() / dof[ok].sum() if ok.any() else np.nan
    else:
        sigma2 = 1.0
    se = np.sqrt(sigma2 * np.where(c_rr > 0, c_rr, np.nan))
    fail = status == NO_CONTRAST
    rho0 = np.where(conv, rho, 0.0)
    nx = np.where(conv, np.cos(phi), cand.nx)
    ny = np.where(conv, np.sin(phi), cand.ny)
    nan = lambda v: np.where(fail, np.nan, v)  # noqa: E731
    return Refinement(cand.x - rho0 * nx, cand.y - rho0 * ny, conv, nx, ny,
                      extras={"A": nan(A), "B": nan(B), "lambda": nan(lam), "kappa": kappa, "offset": -rho0,
                              "rss": rss, "iterations": iters, "status": status, "npix": npix,
                              "se": np.where(conv, se, np.nan)})


@register("patch_esf_fit", "PatchESFFit", family="edgetruth", footprint=FP.patch(HALF_NORMAL, HALF_TANGENT),
          needs_camera=True)
def patch_esf_fit(image, cand, esf=None, bin_index=None, blur_known: bool = False, variance=None,
                  half_normal: float = HALF_NORMAL, half_tangent: float = HALF_TANGENT, curved: bool = True,
                  kappa_radius_px: float = KAPPA_RADIUS_PX, maxit: int = MAXIT, tol_px: float = TOL_PX):
    """PatchESFFit: patch_psf_fit's 2-D fit with the camera's exact tabulated edge spread (needs the camera)."""
    return esf_refine(image, cand, esf, bin_index, blur_known, variance, half_normal, half_tangent, curved,
                      kappa_radius_px, maxit, tol_px)
