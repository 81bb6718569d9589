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
one fused numba kernel per point (``_fit_points``: parallel over fixed chunks of points taken in the order
of their normals' direction, the patch gathered once, the model by ``esf_tables.patch_means`` -- the table
evaluator's steps (``pixel_mean``'s) over the patch, in passes the compiler vectorises, an arc's angle by a
polynomial within 2 ulp of libm's atan2 --, no allocation per point); a callable ``variance``
cannot be compiled into it and takes the batched path (``_fit_chunk``: per pass the shared table kernel over
the active points, numpy bookkeeping, small numba kernels), same steps (the answers agree to ~1e-11 px).  The
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
from edgetruth.locate import esf_tables as ET
from edgetruth.locate import exact_sum as XS
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
CHUNK = 4096  # a callable variance's batches (``_fit_batched``): the (points x pixels) arrays stay ~4 MB each
KAPPA_RADIUS_PX = 5.0  # the curvature is averaged over the candidates within this radius (``curvature``)
_SAME_EDGE_COS = math.cos(math.radians(30.0))
VAR_FLOOR, VAR_FLOOR_REL = 1e-9, 1e-3  # the pixel variance's floor (gray levels²; and relative to the patch's largest)
N_CHUNKS = PF.N_CHUNKS  # the fused kernel's parallel chunks of points (work arrays allocated once per chunk)
MAXPIX = FP.SIZE * FP.SIZE
_solve = _inverse_00 = None  # locate.small_linalg's, bound when the kernels first compile


@before_compile
def _bind_solver():
    global _solve, _inverse_00
    from edgetruth.locate.small_linalg import cholesky_solve, inverse_00

    _solve, _inverse_00 = cholesky_solve, inverse_00


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
        out[i] = _inverse_00(H[i], npar, np.empty((5, 5)), np.empty(5), np.empty(5))


# --- the fused per-point fit (tuple or no ``variance``) ---------------------------------------------------
# The same steps as ``_fit_chunk`` in the same floating-point order, so that a point's answer does not
# depend on the path (but for the model's last bits: ``esf_tables.patch_means``): the normal equations sum the
# used pixels in the union's order, and the trial cost (numpy's row sum there) is numpy's pairwise sum over the
# union's row, its unused pixels adding zero terms.

@njit(cache=True, forceinline=True)
def _sum_half(t, lo, n):
    if n <= 128:
        return XS.block_sum(t, lo, n)
    n2 = n // 2
    n2 -= n2 % 8
    return XS.block_sum(t, lo, n2) + XS.block_sum(t, lo + n2, n - n2)


@njit(cache=True)
def _pairwise_sum(t, n):
    """numpy's float64 row sum of t[:n] bit for bit (its pairwise summation; every n <= FP.SIZE² = 289 checked
    against np.sum: three levels of halving are enough there)."""
    if n <= 128:
        return 0.0 + XS.block_sum(t, 0, n)
    n2 = n // 2
    n2 -= n2 % 8
    return 0.0 + (_sum_half(t, 0, n2) + _sum_half(t, n2, n - n2))


@njit(cache=True, forceinline=True)
def _model(th, kind, radius, sgn, ox, oy, npix, P, dP, L, step_rad, half_px, k0, inv_h, sx2, sy2, vcir, wk, cell):
    """wk[4:10] <- (M, Jr, Jp, Jl, Lr, Lp) of the patch's pixels at theta ``th`` (wk[11:20], cell: the passes'
    work)."""
    ET.patch_means(kind, th[0], math.cos(th[1]), math.sin(th[1]), radius, sgn, ox, oy, npix, P, dP, L, step_rad,
                   half_px, k0, inv_h, sx2, sy2, vcir, wk[4:10], wk[11:20], cell)


@njit(cache=True, forceinline=True)
def _weights(th, wk, npix, nu, weighted, va, vb, vq):
    """wk[3] <- the pixel weights 1 / var(model mean) (``weights`` of ``_fit_chunk``; 1 unweighted)."""
    if not weighted:
        for k in range(npix):
            wk[3, k] = 1.0
        return
    A = th[2]
    B = th[3]
    dl = th[4] - 1.0
    top = 0.0 if npix < nu else -np.inf  # numpy's row max sees the unused pixels' 0
    nan = False
    for k in range(npix):
        m = A + B * (wk[4, k] + dl * wk[7, k])
        v = va + vb * m + vq * m * m
        wk[3, k] = v
        if v != v:
            nan = True
        elif v > top:
            top = v
    floor = max(VAR_FLOOR_REL * top, VAR_FLOOR)
    for k in range(npix):
        v = wk[3, k]
        wk[3, k] = np.nan if nan else 1.0 / (v if v > floor else floor)  # np.maximum: a NaN spreads


@njit(cache=True, forceinline=True)
def _normal_eq(th, wk, npix, npar, weighted, H, g):
    """H = J^T W J, g = -J^T W r; returns the cost (``_normal_equations`` for one point, the same sums in the same
    order, held in registers; unweighted the products with the weight 1 left out: they are exact)."""
    A = th[2]
    B = th[3]
    dl = th[4] - 1.0
    c = 0.0
    g0 = g1 = g2 = g3 = g4 = 0.0
    h00 = h10 = h11 = h20 = h21 = h22 = h30 = h31 = h32 = h33 = h40 = h41 = h42 = h43 = h44 = 0.0
    for k in range(npix):
        mk = wk[4, k] + dl * wk[7, k]
        r = A + B * mk - wk[2, k]
        j0 = B * (wk[5, k] + dl * wk[8, k])
        j1 = B * (wk[6, k] + dl * wk[9, k])
        j3 = mk
        j4 = B * wk[7, k]
        if weighted:
            wt = wk[3, k]
            c += wt * r * r
            w0 = wt * j0
            w1 = wt * j1
            w2 = wt * 1.0
            w3 = wt * j3
            w4 = wt * j4
        else:
            c += r * r
            w0 = j0
            w1 = j1
            w2 = 1.0
            w3 = j3
            w4 = j4
        g0 -= w0 * r
        g1 -= w1 * r
        g2 -= w2 * r
        g3 -= w3 * r
        g4 -= w4 * r
        h00 += w0 * j0
        h10 += w1 * j0
        h11 += w1 * j1
        h20 += w2 * j0
        h21 += w2 * j1
        h22 += w2 * 1.0
        h30 += w3 * j0
        h31 += w3 * j1
        h32 += w3 * 1.0
        h33 += w3 * j3
        h40 += w4 * j0
        h41 += w4 * j1
        h42 += w4 * 1.0
        h43 += w4 * j3
        h44 += w4 * j4
    g[0], g[1], g[2], g[3], g[4] = g0, g1, g2, g3, g4
    H[0, 0] = h00
    H[1, 0] = H[0, 1] = h10
    H[1, 1] = h11
    H[2, 0] = H[0, 2] = h20
    H[2, 1] = H[1, 2] = h21
    H[2, 2] = h22
    H[3, 0] = H[0, 3] = h30
    H[3, 1] = H[1, 3] = h31
    H[3, 2] = H[2, 3] = h32
    H[3, 3] = h33
    if npar == 5:
        H[4, 0] = H[0, 4] = h40
        H[4, 1] = H[1, 4] = h41
        H[4, 2] = H[2, 4] = h42
        H[4, 3] = H[3, 4] = h43
        H[4, 4] = h44
    return c


@njit(cache=True, forceinline=True)
def _in_patch(fx, fy, nx, ny, half_normal, half_tangent):
    """Is the pixel at offset (fx, fy) in the candidate's patch?  ``footprints.patch_masks``' predicate, the
    same operations in the same order, so the same pixels bit for bit (numpy's masks cost ~20 % of the fit)."""
    t = fx * nx + fy * ny
    u = fy * nx - fx * ny
    return abs(t) <= half_normal and abs(u) <= half_tangent


@njit(cache=True)
def _patch_union(nxs, nys, half_normal, half_tangent, out):
    """out (SIZE, SIZE) <- the union of the points' patches: an offset is in it once one point's patch holds it
    (the search ends there); an offset beyond every patch's reach is not searched (t² + u² = |offset|² |n|², so
    |offset|² min |n|² > hn² + ht² rules it out; the margin 1e-9 is far above the rounding of t and u)."""
    nn = np.inf
    for i in range(nxs.shape[0]):
        v = nxs[i] * nxs[i] + nys[i] * nys[i]
        if v < nn:
            nn = v
    reach2 = (half_normal * half_normal + half_tangent * half_tangent) * (1.0 + 1e-9)
    R = FP.RADIUS
    for yy in range(FP.SIZE):
        for xx in range(FP.SIZE):
            fx = float(xx - R)
            fy = float(yy - R)
            out[yy, xx] = False
            if (fx * fx + fy * fy) * nn > reach2:
                continue
            for i in range(nxs.shape[0]):
                if _in_patch(fx, fy, nxs[i], nys[i], half_normal, half_tangent):
                    out[yy, xx] = True
                    break


@njit(cache=True)
def _fit_point(img, x, y, nx, ny, half_normal, half_tangent, uoff, nu, fit, th, kind, radius, sgn, P, dP, L, step_rad,
               half_px, k0, inv_h, sx2, sy2, vcir, npar, weighted, va, vb, vq, maxit, tol, out, wk, iw, mat, vec):
    """One candidate: th (5,) = (rho, phi, A, B, lambda) updated in place; out <- [status, iterations, cost,
    c_rhorho, npix].  uoff (2, nu): the union's offsets (x, y), row-major.  Work arrays: wk (20, MAXPIX) = offsets
    x, y, values, weights, the model's six arrays, the trial cost's terms, ``patch_means``' passes; iw (3, MAXPIX)
    each pixel's place in the union, its table cell; mat (2, 5, 5); vec (5, 5)."""
    upos = iw[0]
    cell = iw[1:3]
    h, w = img.shape
    ix = int(x)
    iy = int(y)
    npix = 0
    for u in range(nu):  # the union holds every patch, in its order (row-major, np.nonzero)
        fx = uoff[0, u]
        fy = uoff[1, u]
        if not _in_patch(float(fx), float(fy), nx, ny, half_normal, half_tangent):
            continue
        X = ix + fx
        Y = iy + fy
        if 0 <= X < w and 0 <= Y < h:
            wk[0, npix] = fx
            wk[1, npix] = fy
            wk[2, npix] = img[Y, X]
            upos[npix] = u
            npix += 1
    out[4] = npix
    if not fit or npix <= npar:
        out[0] = NO_CONTRAST
        out[1] = 0
        out[2] = np.nan
        out[3] = np.nan
        return
    ox = wk[0]
    oy = wk[1]
    H = mat[0]
    Hs = mat[1]
    g = vec[0]
    step = vec[1]
    trial = vec[2]
    rhs = vec[4]
    status = NOT_CONVERGED
    it = 0
    damp = 1e-3
    _model(th, kind, radius, sgn, ox, oy, npix, P, dP, L, step_rad, half_px, k0, inv_h, sx2, sy2, vcir, wk, cell)
    _weights(th, wk, npix, nu, weighted, va, vb, vq)
    cost = _normal_eq(th, wk, npix, npar, weighted, H, g)
    for _ in range(maxit):
        it += 1
        for a in range(npar):
            rhs[a] = g[a]
            for b in range(npar):
                Hs[a, b] = H[a, b]
            Hs[a, a] = H[a, a] * (1.0 + damp) + 1e-30
        ok = _solve(Hs, rhs, npar, step)
        for a in range(5):
            trial[a] = th[a]
        if ok:
            for a in range(npar):
                trial[a] += step[a]
            small = abs(step[0]) < tol and abs(step[1]) < tol and (npar < 5 or abs(step[4]) < tol)
            if small:  # converged: take this step without another pass (module docstring)
                for a in range(5):
                    th[a] = trial[a]
                status = OK
                break
            _model(trial, kind, radius, sgn, ox, oy, npix, P, dP, L, step_rad, half_px, k0, inv_h, sx2, sy2, vcir,
                   wk, cell)
            # the trial cost with the current point's weights (one cost to compare), summed as numpy did
            A = trial[2]
            B = trial[3]
            dl = trial[4] - 1.0
            r0 = A + B * (0.0 + dl * 0.0) - 0.0
            t0 = 0.0 * r0 * r0
            for u in range(nu):
                wk[10, u] = t0
            for k in range(npix):
                r = A + B * (wk[4, k] + dl * wk[7, k]) - wk[2, k]
                wk[10, upos[k]] = wk[3, k] * r * r
            ncost = _pairwise_sum(wk[10], nu)
            if math.isfinite(ncost) and ncost <= cost:
                for a in range(5):
                    th[a] = trial[a]
                _weights(th, wk, npix, nu, weighted, va, vb, vq)
                cost = _normal_eq(th, wk, npix, npar, weighted, H, g)
                damp = max(damp * 0.1, 1e-12)
            else:
                damp *= 10.0
        else:  # not positive definite: more damping
            damp *= 10.0
        if damp > 1e10:
            break
    out[0] = status
    out[1] = it
    out[2] = cost
    out[3] = _inverse_00(H, npar, Hs, rhs, step)


@njit(cache=True, parallel=True)
def _fit_points(img, xs, ys, nxs, nys, half_normal, half_tangent, uoff, nu, fit, idx, theta, kind, radius, sgn, P, dP,
                L, step_rad, half_px, k0, inv_h, sx2, sy2, vcir, npar, weighted, va, vb, vq, maxit, tol, out, n_chunks):
    """The points ``idx`` (one table's), in ``n_chunks`` parallel chunks that each allocate their work arrays
    once."""
    n = idx.shape[0]
    for c in prange(n_chunks):
        wk = np.empty((20, MAXPIX))
        iw = np.empty((3, MAXPIX), np.int64)
        mat = np.empty((2, 5, 5))
        vec = np.empty((5, 5))
        for j in range(c * n // n_chunks, (c + 1) * n // n_chunks):
            i = idx[j]
            _fit_point(img, xs[i], ys[i], nxs[i], nys[i], half_normal, half_tangent, uoff, nu, fit[i], theta[i],
                       kind[i], radius[i], sgn[i], P, dP, L, step_rad, half_px, k0, inv_h, sx2, sy2, vcir, npar,
                       weighted, va, vb, vq, maxit, tol, out[i], wk, iw, mat, vec)


def _variance_fn(variance):
    """The pixel variance (gray levels²) as a function of the mean: None (unweighted), (a, b[, c]) or a callable."""
    coef = _variance_coef(variance)
    if coef is None or callable(coef):
        return coef
    a, b, c = coef
    return lambda m: a + b * m + c * m * m


def _variance_coef(variance):
    """None (unweighted), (a, b, c) of var = a + b m + c m² (the fused kernel's), or the callable."""
    if variance is None or callable(variance):
        return variance
    try:
        coef = [float(v) for v in variance]
    except (TypeError, ValueError):
        coef = []
    if len(coef) not in (2, 3) or not all(math.isfinite(v) for v in coef):
        raise InputError(f"variance={variance!r}: give (a, b) or (a, b, c) for var = a + b*mean (+ c*mean^2) in "
                         "gray levels^2 (EMVA: a = K^2 sigma_d^2 + 1/12 - K*offset, b = K), a callable, or None")
    return coef[0], coef[1], (coef[2] if len(coef) == 3 else 0.0)


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
    out = np.empty(n)
    _same_edge_mean(np.ascontiguousarray(cand.x, np.float64), np.ascontiguousarray(cand.y, np.float64),
                    np.ascontiguousarray(cand.nx, np.float64), np.ascontiguousarray(cand.ny, np.float64), kappa,
                    float(radius_px), _SAME_EDGE_COS, out)
    return out


@njit(cache=True, parallel=True)
def _same_edge_mean(xs, ys, nxs, nys, kappa, radius, cos_same, out):
    """out[i] <- the mean of kappa over point i and the points within ``radius`` of it whose normals agree
    (n_i . n_j > cos_same): the points bucketed in square cells of side >= ``radius``, the 3 x 3 cells around each
    searched (a k-d tree's pairs cost ~3x this)."""
    n = xs.shape[0]
    x0 = np.inf
    y0 = np.inf
    x1 = -np.inf
    y1 = -np.inf
    for i in range(n):
        if math.isfinite(xs[i]) and math.isfinite(ys[i]):
            x0 = min(x0, xs[i])
            y0 = min(y0, ys[i])
            x1 = max(x1, xs[i])
            y1 = max(y1, ys[i])
    ax = x1 - x0 if x1 >= x0 else 0.0
    ay = y1 - y0 if y1 >= y0 else 0.0
    # cells of side >= radius, and at most ~12 n of them however far apart the points lie
    side = max(radius, math.sqrt(ax * ay / (4.0 * n)), max(ax, ay) / (4.0 * n))
    ncx = int(ax / side) + 1
    ncy = int(ay / side) + 1
    cell = np.full(n, -1, np.int64)
    start = np.zeros(ncx * ncy + 1, np.int64)
    for i in range(n):
        if math.isfinite(xs[i]) and math.isfinite(ys[i]):
            cx = min(int((xs[i] - x0) / side), ncx - 1)
            cy = min(int((ys[i] - y0) / side), ncy - 1)
            cell[i] = cy * ncx + cx
            start[cell[i] + 1] += 1
    for c in range(ncx * ncy):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    members = np.empty(n, np.int64)
    for i in range(n):
        if cell[i] >= 0:
            members[fill[cell[i]]] = i
            fill[cell[i]] += 1
    r2 = radius * radius
    for i in prange(n):
        total = kappa[i]
        count = 1.0
        if cell[i] >= 0:
            cx = cell[i] % ncx
            cy = cell[i] // ncx
            for yy in range(max(cy - 1, 0), min(cy + 2, ncy)):
                for xx in range(max(cx - 1, 0), min(cx + 2, ncx)):
                    c = yy * ncx + xx
                    for m in range(start[c], start[c + 1]):
                        j = members[m]
                        dx = xs[i] - xs[j]
                        dy = ys[i] - ys[j]
                        if j != i and dx * dx + dy * dy <= r2 and nxs[i] * nxs[j] + nys[i] * nys[j] > cos_same:
                            total += kappa[j]
                            count += 1.0
        out[i] = total / count


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


def _fit_batched(img, cand, masks, union, geo, tabs, bidx, init, theta, npar, var_fn, maxit, tol_px, status, iters,
                 rss, c_rr, npix):
    """The fit with a callable ``variance``: ``_fit_chunk`` over chunks of CHUNK points (outputs in place)."""
    n = len(cand)
    h, w = img.shape
    iy, ix = np.nonzero(union)
    off = np.stack([ix - FP.RADIUS, iy - FP.RADIUS], axis=1).astype(float)
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


def esf_refine(image, cand, esf=None, bin_index=None, blur_known: bool = False, variance=None,
               half_normal: float = HALF_NORMAL, half_tangent: float = HALF_TANGENT, curved: bool = True,
               kappa_radius_px: float = KAPPA_RADIUS_PX, maxit: int = MAXIT, tol_px: float = TOL_PX) -> Refinement:
    coef = _variance_coef(variance)
    var_fn = _variance_fn(coef)
    half_normal = float(half_normal)
    half_tangent = float(half_tangent)
    if not (1.0 <= half_normal <= FP.RADIUS and 0.0 <= half_tangent <= FP.RADIUS):
        raise InputError(f"half_normal={half_normal}, half_tangent={half_tangent}: need 1 <= half_normal <= "
                         f"{FP.RADIUS} and 0 <= half_tangent <= {FP.RADIUS} px")
    n = len(cand)  # (a spec check's stand-in candidates stop here: the tables are checked at run time)
    tabs, bidx = _tables(esf, bin_index, n)
    npar = 4 if blur_known else 5
    img = np.ascontiguousarray(image, np.float64)
    # the patch: patch_psf_fit's footprint; the union of its offsets over the points fixes the order of the sums
    nxs = np.ascontiguousarray(cand.nx, np.float64)
    nys = np.ascontiguousarray(cand.ny, np.float64)
    union = np.zeros((FP.SIZE, FP.SIZE), bool)
    if n:
        _patch_union(nxs, nys, half_normal, half_tangent, union)
    iy, ix = np.nonzero(union)
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
    if callable(coef):  # a Python callable cannot be compiled into the fused kernel
        _fit_batched(img, cand, FP.patch_masks(cand, half_normal, half_tangent), union, geo, tabs, bidx, init, theta,
                     npar, var_fn, maxit, tol_px, status, iters, rss, c_rr, npix)
    elif n:
        uoff = np.stack([ix - FP.RADIUS, iy - FP.RADIUS]).astype(np.int64)
        fit = init[:, 7] != NO_CONTRAST
        out = np.empty((n, 5))
        va, vb, vq = coef if coef is not None else (0.0, 0.0, 0.0)
        # the points in the order of their normal's direction (folded as the tables are): the points a thread
        # fits in turn read the same few table rows, which stay in its cache (in raster order: 2x the time)
        order = np.argsort(np.arctan2(np.abs(nys), np.abs(nxs)), kind="stable")
        for b in np.unique(bidx):  # the field-height bins (a few per image): one table per kernel call
            sel = order[bidx[order] == b] if len(tabs) > 1 else order
            t = tabs[b]
            _fit_points(img, np.ascontiguousarray(cand.x, np.float64), np.ascontiguousarray(cand.y, np.float64),
                        nxs, nys, half_normal, half_tangent, uoff, int(iy.size), fit, sel, theta, geo["kind"],
                        geo["radius"], geo["sgn"], t.P, t.dP, t.L, float(t.step_rad), float(t.half_px), float(t.k0),
                        float(t.inv_h), float(t.sx2), float(t.sy2), float(t.vc), npar, coef is not None, float(va),
                        float(vb), float(vq), int(maxit), float(tol_px), out, max(1, min(sel.size, N_CHUNKS)))
        status[:] = out[:, 0]
        iters[:] = out[:, 1]
        rss[:] = out[:, 2]
        c_rr[:] = out[:, 3]
        npix[:] = out[:, 4]
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
