"""patch_psf_fit: a 2-D maximum-likelihood fit of the pixel-integrated, blurred edge over a patch.

For each candidate p (normal n from Canny) the method fits every pixel whose centre lies in the
rectangle |t| <= ``half_normal`` (along n), |u| <= ``half_tangent`` (along the edge) -- for the
defaults 5 x 2, 55 pixels on an axis-aligned edge, ~41 on a diagonal one -- with the exact model
of the image an edge makes:

    m(x) = A + B * M(d(x), psi(x); s)

- d(x): the signed distance of pixel centre x to the edge (bright side > 0); the edge is the line
  through p - rho n(phi) with normal n(phi), or, when the edge is curved, the arc of curvature
  kappa tangent to it there (kappa is taken from the candidates' gradient field: the divergence of
  its unit normal, kappa = -div n, exact for circles under any radially symmetric blur);
- M: the exact area mean over the pixel of Phi(d/s) (the second divided difference of its second
  antiderivative, as ``render.analytic``; Phi from a table, |error| < 3e-9), psi the direction of
  the local normal (the pixel box's projection on it); an arc's bend inside the pixel is taken to
  first order (1/(24 r));
- s: the PSF's Gaussian-equivalent scale in px (the pixel box is in M): estimated jointly, or known
  from the camera (option ``psf_sigma_px``).

Unknowns (rho, phi, A, B, s) -- (rho, phi, A, B) when the PSF is known -- by Levenberg-Marquardt
with the analytic Jacobian (derivatives of the divided differences: d/dd, d/ds by the heat
equation dF2/ds = s Phi, d/dpsi through the pixel box's half-widths |cos psi|/2, |sin psi|/2),
started from a 7-sample 4P ERF fit of the normal profile (its pixels lie inside the patch).

Output: the foot point p - rho n on the edge, the fitted normal n(phi), and per point
``se`` = sigma * sqrt((J^T J)^-1_rho,rho): sigma^2 the image's pooled residual variance, the
position's standard error sigma(mu) in px (Gaussian noise; unweighted least squares).
Extras: A, B, s, kappa, offset (-rho: along the candidate's normal), rss, iterations, status,
npix, se.  Failure (converged=False): no contrast, no convergence, |rho| > 2 px, s outside
(0.05, 10) px, B <= 0.

Speed (docs/bound.md, "patch_psf_fit: a locator at the bound"):

- the pixel loop (model, Jacobian, normal equations) is branch-free and vectorised by LLVM (AVX, 4
  pixels per instruction; Phi from a flat table by gathers; the line and the arc each have their own
  loop); the sums run in scalars and may be reassociated (fixed at compile time: bit-stable run to
  run and for any number of threads -- the points run in ``N_CHUNKS`` fixed chunks);
- the fit ends when a step moves rho, phi and s by less than ``tol_px`` (3e-3 px) and takes that step
  without another pass over the patch (~2.2 passes; 1e-4 px took ~3.1, 1e-7 ~6.5): every point
  within 3e-4 px of the 1e-7 fit (< 1 % of its bound; RMSE / bound unchanged to 2e-5 on the tests'
  Monte-Carlo set);
- the start's 7-sample ERF fit takes two Levenberg-Marquardt steps (a converged start saves no pass);
- work arrays are allocated once per chunk; the patch is gathered from its bounding box; the damped
  normal equations are solved by the shared ``locate.small_linalg.cholesky_solve``.

Docs: docs/bound.md (the bound this estimator attains).  Kernels below in numba (parallel over
points, no allocation inside the fit's inner loop).
"""
from __future__ import annotations

import math

import numpy as np

from edgetruth.errors import InputError
from edgetruth.locate import erf_kernels as K
from edgetruth.locate import footprints as FP
from edgetruth.locate.fit_status import NO_CONTRAST, NOT_CONVERGED, OK, OUT_OF_WINDOW
from edgetruth.jit import before_compile, njit, prange
from edgetruth.locate.profiles import bilinear
from edgetruth.locate.registry import register
from edgetruth.locate.result import Refinement

HALF_NORMAL = 5.0
HALF_TANGENT = 2.0
MAXIT = 40
TOL_PX = 3e-3  # the step (rho, phi, s) that ends the fit, taken without another pass (module docstring)
N_CHUNKS = 256  # parallel chunks of candidates (work arrays allocated once per chunk)
S_MIN = 0.05
S_MAX = 10.0
RHO_MAX = 2.0
KAPPA_MAX = 0.25  # |curvature| (1/px) above which the arc is not trusted: radius < 4 px
MAXPIX = FP.SIZE * FP.SIZE
_INIT_WINDOW = 7  # its bilinear samples (|t| <= 3) read pixels with |t| <= 4.42, |u| <= 1.42: inside the patch
_INIT_MAXIT = 2  # the start's ERF fit: two steps (more do not save a pass of the patch fit)
_solve = _inverse_00 = None  # the shared Cholesky solves (locate.small_linalg), bound before the kernels compile


@before_compile
def _bind_solver():
    """Bind the shared solvers when the kernels first compile (small_linalg imports numba)."""
    global _solve, _inverse_00
    from edgetruth.locate.small_linalg import cholesky_solve, inverse_00

    _solve, _inverse_00 = cholesky_solve, inverse_00


# Phi and phi from a table (1/32 steps on [-8.5, 8.5], cubic Hermite with the exact derivatives): no exp
# per call, |error| < 4e-9 (A&S 7.1.26, erf_kernels.cdf_pdf: 1.5e-7).  Flat (Phi_0, phi_0, Phi_1, ...): the
# vectorised pixel loop gathers its four values per corner
_CDF_STEP = 1.0 / 32.0
_CDF_ZMAX = 8.5
_CDF_N = int(round(2 * _CDF_ZMAX / _CDF_STEP)) + 1
_CDF_TABLE = None
# the pixel loop is vectorised (AVX: 4 pixels per instruction): its sums may be reassociated (the order is
# fixed at compile time: a point is the same bit for bit run to run), and divisions are not checked for
# zero (a branch per division stops the vectoriser; a * b >= B_MIN / 2, and a pixel at an arc's centre,
# r = 0, gives a NaN cost, which the fit rejects like any worse step)
_FAST = {"reassoc", "contract", "nsz", "arcp"}
B_MIN = 1e-4  # the pixel box's smaller half-width on the normal, floored (an axis-aligned edge without a
# branch): M within 2.2e-7 of the exact box mean at s = 0.05-1 (measured; the table's 3e-9 error divided by
# 2b, and b^2 M''/6 < 1e-9 / s), i.e. < 1e-6 px on the fitted position


@before_compile
def _bind_cdf_table():
    """(Phi, phi) at the table's nodes (the kernels read it as a global constant)."""
    global _CDF_TABLE
    from scipy.special import ndtr

    z = -_CDF_ZMAX + np.arange(_CDF_N) * _CDF_STEP
    _CDF_TABLE = np.ascontiguousarray(np.column_stack([ndtr(z), np.exp(-0.5 * z * z) / math.sqrt(2 * math.pi)])
                                      .ravel())


@njit(cache=True, inline="always")
def _cdf_pdf(z):
    """(Phi(z), phi(z)) from ``_CDF_TABLE``; (0, 0) below the table, (1, 0) above it.  Branch-free (selects)."""
    x = (z + _CDF_ZMAX) * (1.0 / _CDF_STEP)
    i = int(min(max(x, 0.0), _CDF_N - 1.5))
    t = x - i
    z0 = -_CDF_ZMAX + i * _CDF_STEP
    P0 = _CDF_TABLE[2 * i]
    f0 = _CDF_TABLE[2 * i + 1]
    P1 = _CDF_TABLE[2 * i + 2]
    f1 = _CDF_TABLE[2 * i + 3]
    t2 = t * t
    t3 = t2 * t
    h00 = 2.0 * t3 - 3.0 * t2 + 1.0
    h10 = (t3 - 2.0 * t2 + t) * _CDF_STEP
    h01 = 1.0 - h00
    h11 = (t3 - t2) * _CDF_STEP
    Phi = h00 * P0 + h10 * f0 + h01 * P1 + h11 * f1
    pdf = h00 * f0 - h10 * z0 * f0 + h01 * f1 - h11 * (z0 + _CDF_STEP) * f1
    below = not x > 0.0
    above = x >= _CDF_N - 1
    Phi = 0.0 if below else (1.0 if above else Phi)
    pdf = 0.0 if (below or above) else pdf
    return Phi, pdf


@njit(cache=True, inline="always")
def _pm(d0, psi_c, psi_s, s, inv_s):
    """Area mean M of Phi(d/s) over a pixel whose centre is at signed distance d0 from a straight
    edge with normal direction (psi_c, psi_s), and dM/dd0, dM/ds, dM/dpsi (inv_s = 1 / s).

    The box projects on the normal to a trapezoid with half-widths a >= b (|cos|/2, |sin|/2): M is the
    second divided difference of F2(d) = s^2 ((u^2 + 1) Phi(u) + u phi(u)) / 2, u = d / s, over its four
    corners d +- a +- b; b is floored at B_MIN (the axis-aligned limit, without a branch)."""
    flip = d0 > 0.0
    D = -abs(d0)  # evaluated on the dark side: M(d0) = 1 - M(-d0) for a symmetric profile
    ac = 0.5 * abs(psi_c)
    bs = 0.5 * abs(psi_s)
    swap = bs > ac
    a = max(ac, bs)
    b = max(min(ac, bs), B_MIN)
    u1 = (D + a + b) * inv_s
    u2 = (D + a - b) * inv_s
    u3 = (D - a + b) * inv_s
    u4 = (D - a - b) * inv_s
    P1, p1 = _cdf_pdf(u1)
    P2, p2 = _cdf_pdf(u2)
    P3, p3 = _cdf_pdf(u3)
    P4, p4 = _cdf_pdf(u4)
    G1a = u1 * P1 + p1
    G1b = u2 * P2 + p2
    G1c = u3 * P3 + p3
    G1d = u4 * P4 + p4
    F2 = 0.5 * s * s * (((u1 * u1 + 1.0) * P1 + u1 * p1) - ((u2 * u2 + 1.0) * P2 + u2 * p2)
                        - ((u3 * u3 + 1.0) * P3 + u3 * p3) + ((u4 * u4 + 1.0) * P4 + u4 * p4))
    iab = 1.0 / (a * b)
    i4 = 0.25 * iab
    M = F2 * i4
    dD = s * (G1a - G1b - G1c + G1d) * i4
    ds = s * (P1 - P2 - P3 + P4) * i4
    da = s * (G1a - G1b + G1c - G1d) * i4 - M * b * iab
    db = s * (G1a + G1b - G1c - G1d) * i4 - M * a * iab
    # back to the half-widths of (|cos|, |sin|) and to psi
    dac = db if swap else da
    dbs = da if swap else db
    sc = 1.0 if psi_c >= 0.0 else -1.0
    ss = 1.0 if psi_s >= 0.0 else -1.0
    dpsi = dac * (-0.5 * sc * psi_s) + dbs * (0.5 * ss * psi_c)
    M = 1.0 - M if flip else M
    ds = -ds if flip else ds
    dpsi = -dpsi if flip else dpsi
    return M, dD, ds, dpsi


@njit(cache=True, inline="always")
def _arc(dx, dy, k, c, s, sgn, R):
    """(d, psi_c, psi_s, dd/drho, dd/dphi, dpsi/drho, dpsi/dphi) of pixel offset (dx, dy) for the arc of
    curvature sgn / R through p - rho n(phi) with normal n(phi) = (c, s); k = sgn R - rho: the centre is
    at k n(phi) from p."""
    vx = dx - k * c
    vy = dy - k * s
    r = math.sqrt(vx * vx + vy * vy)
    ir = 1.0 / r
    d = sgn * (R - r - ir / 24.0)
    f = -sgn * (1.0 - ir * ir / 24.0) * ir
    vn = vx * c + vy * s
    vt = vx * s - vy * c
    return (d, vx * ir, vy * ir, f * vn, f * k * vt, vt * ir * ir, -k * vn * ir * ir)


@njit(cache=True, inline="always")
def _accumulate(M, dD, dS, dP, d_rho, d_phi, p_rho, p_phi, r, B, acc):
    """One pixel's terms of the cost, J^T J and -J^T r (acc: 20 scalars, returned updated)."""
    (cost, h00, h10, h11, h20, h21, h30, h31, h32, h33, h40, h41, h42, h43, h44, g0, g1, g3, g4, g2) = acc
    j0 = B * (dD * d_rho + dP * p_rho)
    j1 = B * (dD * d_phi + dP * p_phi)
    j4 = B * dS
    return (cost + r * r, h00 + j0 * j0, h10 + j1 * j0, h11 + j1 * j1, h20 + j0, h21 + j1, h30 + M * j0,
            h31 + M * j1, h32 + M, h33 + M * M, h40 + j4 * j0, h41 + j4 * j1, h42 + j4, h43 + j4 * M,
            h44 + j4 * j4, g0 - j0 * r, g1 - j1 * r, g3 - M * r, g4 - j4 * r, g2 - r)


@njit(cache=True, fastmath=_FAST, error_model="numpy")
def _normal_equations(vals, ox, oy, rho, phi, A, B, s, kappa, H, g):
    """Cost, J^T J (in H) and -J^T r (in g) of the patch model at (rho, phi, A, B, s), all five
    unknowns (a fit with s known uses the leading 4 x 4 block).  The line (kappa = 0) and the arc
    have a loop each; the sums run in scalars (numba cannot keep an array's entries in registers),
    so that the loop vectorises.  The arrays hold the patch's pixels only (slices: an int argument could
    be typed as a literal first and compile this kernel twice)."""
    npix = vals.shape[0]
    c = math.cos(phi)
    sn = math.sin(phi)
    inv_s = 1.0 / s
    acc = (0.0,) * 20
    if abs(kappa) < 1e-7:
        d_phi_x = -sn
        for k in range(npix):
            d = ox[k] * c + oy[k] * sn + rho
            M, dD, dS, dP = _pm(d, c, sn, s, inv_s)
            acc = _accumulate(M, dD, dS, dP, 1.0, oy[k] * c + ox[k] * d_phi_x, 0.0, 1.0, A + B * M - vals[k], B,
                              acc)
    else:
        sgn = 1.0 if kappa > 0.0 else -1.0
        R = 1.0 / abs(kappa)
        k0 = sgn * R - rho
        for k in range(npix):
            d, pc, ps, d_rho, d_phi, p_rho, p_phi = _arc(ox[k], oy[k], k0, c, sn, sgn, R)
            M, dD, dS, dP = _pm(d, pc, ps, s, inv_s)
            acc = _accumulate(M, dD, dS, dP, d_rho, d_phi, p_rho, p_phi, A + B * M - vals[k], B, acc)
    (cost, h00, h10, h11, h20, h21, h30, h31, h32, h33, h40, h41, h42, h43, h44, g0, g1, g3, g4, g2) = acc
    H[0, 0] = h00
    H[1, 0] = H[0, 1] = h10
    H[1, 1] = h11
    H[2, 0] = H[0, 2] = h20
    H[2, 1] = H[1, 2] = h21
    H[2, 2] = float(npix)
    H[3, 0] = H[0, 3] = h30
    H[3, 1] = H[1, 3] = h31
    H[3, 2] = H[2, 3] = h32
    H[3, 3] = h33
    H[4, 0] = H[0, 4] = h40
    H[4, 1] = H[1, 4] = h41
    H[4, 2] = H[2, 4] = h42
    H[4, 3] = H[3, 4] = h43
    H[4, 4] = h44
    g[0] = g0
    g[1] = g1
    g[2] = g2
    g[3] = g3
    g[4] = g4
    return cost


@njit(cache=True)
def fit_patch(img, px, py, nx, ny, kappa, half_normal, half_tangent, psf_sigma, maxit, tol, out, pix, vec, mat):
    """Fit one candidate.  out <- [rho, phi, A, B, s, rss, c_rhorho, iterations, status, npix].
    Work arrays (reused from point to point: no allocation per point): pix (3, MAXPIX), vec (8, 16),
    mat (2, 5, 5)."""
    h, w = img.shape
    ix = int(px)
    iy = int(py)
    ox = pix[0]
    oy = pix[1]
    vals = pix[2]
    npix = 0
    rr = FP.RADIUS
    # the rectangle's bounding box (the same pixels, in the same order, as scanning the whole square)
    rx = min(rr, int(math.floor(half_normal * abs(nx) + half_tangent * abs(ny) + 1e-9)))
    ry = min(rr, int(math.floor(half_normal * abs(ny) + half_tangent * abs(nx) + 1e-9)))
    for ddy in range(-ry, ry + 1):
        for ddx in range(-rx, rx + 1):
            fx = float(ddx)
            fy = float(ddy)
            t = fx * nx + fy * ny
            u = fy * nx - fx * ny
            if abs(t) <= half_normal and abs(u) <= half_tangent:
                yy = iy + ddy
                xx = ix + ddx
                if 0 <= yy < h and 0 <= xx < w:
                    ox[npix] = fx
                    oy[npix] = fy
                    vals[npix] = img[yy, xx]
                    npix += 1
    out[9] = npix
    # start: a 7-sample 4P ERF fit of the normal profile
    prof = vec[0, :K.PROFILE_LEN]
    for k in range(K.PROFILE_LEN):
        prof[k] = 0.0
    hw = (_INIT_WINDOW - 1) // 2
    for k in range(-hw, hw + 1):
        prof[K.PROFILE_HALF + k] = bilinear(img, px + k * nx, py + k * ny)
    init = vec[1]
    # typed arguments, not literals: the erf methods' compiled fit_one serves (a literal compiles another)
    K.fit_one(prof, np.int64(_INIT_WINDOW), np.bool_(True), np.int64(_INIT_MAXIT), 1e-4, init)
    fixed_s = psf_sigma > 0.0
    npar = 4 if fixed_s else 5
    if init[7] == NO_CONTRAST or npix <= npar:
        for k in range(9):
            out[k] = np.nan
        out[7] = 0
        out[8] = NO_CONTRAST
        return
    A = init[0]
    B = init[1]
    rho = -init[2]
    if not (abs(rho) <= hw and B > 0.0 and np.isfinite(rho)):  # a poor start: the candidate itself
        rho = 0.0
        A = prof[K.PROFILE_HALF - hw]
        B = prof[K.PROFILE_HALF + hw] - A
        if not B > 0.0:
            B = 1e-3 + abs(B)
    if fixed_s:
        s = psf_sigma
    else:
        v = init[3] * init[3] - 1.0 / 12.0
        s = math.sqrt(v) if v > 0.04 else 0.2
        if s > 5.0:
            s = 5.0
    phi = math.atan2(ny, nx)
    H = mat[0]
    Hs = mat[1]
    g = vec[2]
    gs = vec[3]
    step = vec[4]
    cost = _normal_equations(vals[:npix], ox[:npix], oy[:npix], rho, phi, A, B, s, kappa, H, g)
    lam = 1e-3
    status = NOT_CONVERGED
    it = 0
    while it < maxit:
        it += 1
        for i in range(npar):
            for j in range(npar):
                Hs[i, j] = H[i, j]
            Hs[i, i] = H[i, i] * (1.0 + lam) + 1e-30
        if not _solve(Hs, g, npar, step):
            lam *= 10.0
            if lam > 1e10:
                break
            continue
        nrho = rho + step[0]
        nphi = phi + step[1]
        nA = A + step[2]
        nB = B + step[3]
        ns = s + step[4] if npar == 5 else s
        if ns < S_MIN:
            ns = S_MIN
        if abs(step[0]) < tol and abs(step[1]) < tol and abs(ns - s) < tol:
            # converged: Gauss-Newton's next step would be ~tol^2.  Take this one without a new pass (the
            # normal equations and the cost stay those of the previous point, a step < tol away)
            rho = nrho
            phi = nphi
            A = nA
            B = nB
            s = ns
            status = OK
            break
        ncost = _normal_equations(vals[:npix], ox[:npix], oy[:npix], nrho, nphi, nA, nB, ns, kappa, Hs, gs)
        if ncost <= cost:
            rho = nrho
            phi = nphi
            A = nA
            B = nB
            s = ns
            cost = ncost
            for i in range(npar):
                g[i] = gs[i]
                for j in range(npar):
                    H[i, j] = Hs[i, j]
            lam = max(lam * 0.1, 1e-12)
        else:
            lam *= 10.0
            if lam > 1e10:
                break
    c_rr = _inverse_00(H, npar, Hs, gs, step)  # (J^T J)^-1 rho,rho at the solution
    if status == OK and not (abs(rho) <= RHO_MAX and B > 0.0 and S_MIN < s < S_MAX):
        status = OUT_OF_WINDOW
    out[0] = rho
    out[1] = phi
    out[2] = A
    out[3] = B
    out[4] = s
    out[5] = cost
    out[6] = c_rr
    out[7] = it
    out[8] = status


@njit(cache=True, parallel=True)
def fit_patches(img, xs, ys, nxs, nys, kappas, half_normal, half_tangent, psf_sigma, maxit, tol, out, n_chunks):
    """Every candidate, in ``n_chunks`` parallel chunks that each allocate their work arrays once."""
    n = xs.shape[0]
    for c in prange(n_chunks):
        pix = np.empty((3, MAXPIX))
        vec = np.empty((8, 16))
        mat = np.empty((2, 5, 5))
        for i in range(c * n // n_chunks, (c + 1) * n // n_chunks):
            fit_patch(img, xs[i], ys[i], nxs[i], nys[i], kappas[i], half_normal, half_tangent, psf_sigma,
                      maxit, tol, out[i], pix, vec, mat)


@njit(cache=True, inline="always")
def _unit(gx, gy, yy, xx):
    a = gx[yy, xx]
    b = gy[yy, xx]
    m = math.hypot(a, b)
    if not m > 0.0:
        m = np.inf
    return a / m, b / m


@njit(cache=True)
def curvatures(gx, gy, xs, ys, out):
    """``curvature_at`` in numba (the same arithmetic, point by point: out <- kappa)."""
    h, w = gx.shape
    for i in range(xs.shape[0]):
        x = int(xs[i])
        y = int(ys[i])
        xm = min(max(x - 1, 0), w - 1)
        xp = min(max(x + 1, 0), w - 1)
        ym = min(max(y - 1, 0), h - 1)
        yp = min(max(y + 1, 0), h - 1)
        ux_p = _unit(gx, gy, y, xp)[0]
        ux_m = _unit(gx, gy, y, xm)[0]
        uy_p = _unit(gx, gy, yp, x)[1]
        uy_m = _unit(gx, gy, ym, x)[1]
        kappa = -((ux_p - ux_m) / max(xp - xm, 1) + (uy_p - uy_m) / max(yp - ym, 1))
        out[i] = kappa if (np.isfinite(kappa) and abs(kappa) <= KAPPA_MAX) else 0.0


def curvature_at(cand) -> np.ndarray:
    """kappa = -div(n) at each candidate, n = grad / |grad| of the candidates' smoothed gradient field
    (central differences of the unit field at the neighbouring pixel centres); > 0 where the edge bends
    round its bright side (a bright disk), 0 where the field is too weak to say.  (The numpy reference of
    ``curvatures``, which the fit uses.)"""
    gx, gy = cand.grad_x, cand.grad_y
    h, w = gx.shape
    x = cand.x.astype(np.intp)
    y = cand.y.astype(np.intp)
    xm, xp = np.clip(x - 1, 0, w - 1), np.clip(x + 1, 0, w - 1)
    ym, yp = np.clip(y - 1, 0, h - 1), np.clip(y + 1, 0, h - 1)

    def unit(yy, xx):
        m = np.hypot(gx[yy, xx], gy[yy, xx])
        m = np.where(m > 0, m, np.inf)
        return gx[yy, xx] / m, gy[yy, xx] / m

    ux_p, _ = unit(y, xp)
    ux_m, _ = unit(y, xm)
    _, uy_p = unit(yp, x)
    _, uy_m = unit(ym, x)
    div = (ux_p - ux_m) / np.maximum(xp - xm, 1) + (uy_p - uy_m) / np.maximum(yp - ym, 1)
    kappa = -div
    return np.where(np.isfinite(kappa) & (np.abs(kappa) <= KAPPA_MAX), kappa, 0.0)


def patch_refine(image, cand, psf_sigma_px=None, half_normal: float = HALF_NORMAL, half_tangent: float = HALF_TANGENT,
                 curved: bool = True, maxit: int = MAXIT, tol_px: float = TOL_PX):
    if psf_sigma_px is not None:
        psf_sigma_px = float(psf_sigma_px)
        if not (np.isfinite(psf_sigma_px) and S_MIN <= psf_sigma_px < S_MAX):
            raise InputError(f"psf_sigma_px={psf_sigma_px}: the PSF's Gaussian-equivalent sigma in px, "
                             f"in [{S_MIN}, {S_MAX})")
    half_normal = float(half_normal)
    half_tangent = float(half_tangent)
    if not (1.0 <= half_normal <= FP.RADIUS and 0.0 <= half_tangent <= FP.RADIUS):
        raise InputError(f"half_normal={half_normal}, half_tangent={half_tangent}: need 1 <= half_normal <= "
                         f"{FP.RADIUS} and 0 <= half_tangent <= {FP.RADIUS} px")
    n = len(cand)
    kappa = np.zeros(n)
    if curved and n:
        curvatures(cand.grad_x, cand.grad_y, cand.x, cand.y, kappa)
    out = np.empty((n, 10))
    img = np.ascontiguousarray(image, np.float64)
    fit_patches(img, cand.x, cand.y, cand.nx, cand.ny, kappa, half_normal, half_tangent,
                -1.0 if psf_sigma_px is None else psf_sigma_px, int(maxit), float(tol_px), out,
                max(1, min(n, N_CHUNKS)))
    rho, phi = out[:, 0], out[:, 1]
    status = out[:, 8].astype(np.int64)
    conv = status == OK
    npix = out[:, 9].astype(np.int64)
    npar = 4 if psf_sigma_px is not None else 5
    dof = npix - npar
    use = conv & (dof > 0) & np.isfinite(out[:, 5])
    sigma2 = out[use, 5].sum() / dof[use].sum() if use.any() else np.nan
    c_rr = out[:, 6]
    se = np.sqrt(sigma2 * np.where(c_rr > 0, c_rr, np.nan))
    rho0 = np.where(conv, rho, 0.0)
    nx = np.where(conv, np.cos(phi), cand.nx)
    ny = np.where(conv, np.sin(phi), cand.ny)
    return Refinement(cand.x - rho0 * nx, cand.y - rho0 * ny, conv, nx, ny,
                      extras={"A": out[:, 2], "B": out[:, 3], "s": out[:, 4], "kappa": kappa, "offset": -rho0,
                              "rss": out[:, 5], "iterations": out[:, 7].astype(np.int64), "status": status,
                              "npix": npix, "se": np.where(conv, se, np.nan)})


@register("patch_psf_fit", "PatchPSFFit", family="edgetruth", footprint=FP.patch(HALF_NORMAL, HALF_TANGENT))
def patch_psf_fit(image, cand, psf_sigma_px=None, half_normal: float = HALF_NORMAL,
                  half_tangent: float = HALF_TANGENT, curved: bool = True, maxit: int = MAXIT,
                  tol_px: float = TOL_PX):
    """PatchPSFFit: 2-D ML fit of the pixel-integrated blurred edge (line or arc) over a patch along the edge."""
    return patch_refine(image, cand, psf_sigma_px, half_normal, half_tangent, curved, maxit, tol_px)
