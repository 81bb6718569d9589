"""Cramér–Rao bound for the position of a pixel-integrated blurred step (BRIEF §6).

A row across an axis-aligned edge: pixel k (centre t_k, relative to the
window centre) integrates I(t) = A + B Phi((t - mu)/s) over [t_k - 1/2,
t_k + 1/2]; noise N(0, sigma_n^2) per pixel.  The pixel mean of Phi is
    m_k = s [G1(u+) - G1(u-)],  u+- = (t_k +- 1/2 - mu) / s,  G1(u) = u Phi(u) + phi(u)
with dm/dmu = -(Phi(u+) - Phi(u-)) and dm/ds = phi(u+) - phi(u-).
Fisher matrix F = J^T J / sigma_n^2 over (A, B, mu, s); the bound on
std(mu) is sqrt((F^-1)_mumu) (all four unknown) or 1/sqrt(F_mumu) (mu only).
"""
from __future__ import annotations

import numpy as np
from scipy.special import ndtr

_INV_SQRT2PI = 1.0 / np.sqrt(2.0 * np.pi)


def _jacobian(mu, s, window, B=1.0):
    """(..., window, 4) Jacobian of the pixel means w.r.t. (A, B, mu, s); mu, s broadcast."""
    half = (window - 1) / 2.0
    t = np.arange(window) - half
    mu = np.asarray(mu, float)[..., None]
    s = np.asarray(s, float)[..., None]
    up = (t + 0.5 - mu) / s
    um = (t - 0.5 - mu) / s
    g1 = lambda u: u * ndtr(u) + _INV_SQRT2PI * np.exp(-0.5 * u * u)
    phi = lambda u: _INV_SQRT2PI * np.exp(-0.5 * u * u)
    m = s * (g1(up) - g1(um))
    d_mu = -(ndtr(up) - ndtr(um))
    d_s = phi(up) - phi(um)
    return np.stack([np.ones_like(m), m, B * d_mu, B * d_s], axis=-1)


def position_std_bound(blur_px: float, noise_rel: float, window: int = 11, mu_px: float = 0.0,
                       unknowns: str = "4p") -> float:
    """Cramér-Rao bound on the SD of an edge's position from one row of pixels across an axis-aligned edge.

    The pixel-integrated blurred step A + B Phi(d / s) sampled at ``window`` pixels, Gaussian noise. This
    is the 11-sample reference figure of the reports; on oblique or curved edges use the per-point
    footprint bound (``footprint_bounds``; docs/bound.md).

    Parameters
    ----------
    blur_px : float
        The edge's Gaussian blur s, px.
    noise_rel : float
        Noise SD / contrast B.
    window : int, optional
        Pixels in the row (default 11; a large odd number, e.g. 201, for an unlimited row).
    mu_px : float, optional
        The edge's offset from the row's centre pixel, px.
    unknowns : str, optional
        ``"4p"`` (A, B, mu, s unknown; default), ``"2p"`` (mu, s) or ``"mu"`` (only mu).

    Returns
    -------
    float
        The least SD of an unbiased position estimate, px.
    """
    return float(position_std_bound_many(blur_px, noise_rel, mu_px, window, unknowns))


def position_std_bound_many(blur_px, noise_rel, mu_px, window: int = 11, unknowns: str = "4p") -> np.ndarray:
    """``position_std_bound`` over broadcast arrays of blur, noise and offset (batched Fisher matrices)."""
    blur, noise, mu = np.broadcast_arrays(np.asarray(blur_px, float), np.asarray(noise_rel, float),
                                          np.asarray(mu_px, float))
    J = _jacobian(mu, blur, window)
    if unknowns == "mu":
        return noise / np.sqrt(np.sum(J[..., 2] ** 2, axis=-1))
    cols = {"4p": [0, 1, 2, 3], "2p": [2, 3]}[unknowns]
    Jc = J[..., cols]
    F = np.swapaxes(Jc, -1, -2) @ Jc
    cov = np.linalg.inv(F)
    i = cols.index(2)
    return noise * np.sqrt(cov[..., i, i])


def continuous_mu_only_bound(blur_px: float, noise_rel: float) -> float:
    """The closed form (4 pi)^(1/4) (sigma_n/B) sqrt(s_eff), s_eff = sqrt(s^2 + 1/12), for an unlimited row."""
    s_eff = np.sqrt(blur_px**2 + 1.0 / 12.0)
    return float((4 * np.pi) ** 0.25 * noise_rel * np.sqrt(s_eff))


# ---------------------------------------------------------------- the footprint bound
#
# Per candidate p and per method: the Fisher information of the pixels the method reads
# (its footprint, ``edgetruth.locate.footprints``) about the edge's position, under the true
# pixel-integrated edge.  Unknowns theta = (rho, phi, A, B, s) -- s the blur scale (both sides'
# blurs scale together; ``blur_unknowns="both"`` frees them separately) -- with rho = d(p), the signed distance of the candidate's
# pixel centre to the true edge (what every method's error measures), phi the direction of the
# edge normal (the circle turns about p with it), A the dark level, B the contrast.  Pixel i's
# mean is m_i = A + B M_i + (known background), M_i the exact area mean of the unit profile
# (straight edges: closed form; circles: the closed form of the tangent line at each pixel
# centre, i.e. the true distance and direction per pixel, with the bend inside the pixel to first
# order; checked against the renderer's quadrature, see tests/evaluate/test_crb.py).
# F = sum_i J_i J_i^T / var_i;  bound = sqrt((F^-1)_rho,rho).  Docs: docs/bound.md.

import math as _math

import numba as _numba

from edgetruth.jit import njit, prange  # noqa: E402

#: parameter columns of the Jacobian
COLUMNS = ("rho", "phi", "A", "B", "s_dark", "s_bright")
_H_RHO = 1e-6  # forward-difference steps (px, rad, relative): Jacobian to ~1e-6 relative
_H_PHI = 1e-6
_H_S_REL = 1e-6
_S_FLOOR = 1e-6  # as render.analytic.S_FLOOR_PX
_SQRT1_2 = 1.0 / _math.sqrt(2.0)
_ISQ2PI = 1.0 / _math.sqrt(2.0 * _math.pi)


@_numba.njit(cache=True, inline="always")
def _g1(u):
    return u * 0.5 * _math.erfc(-u * _SQRT1_2) + _ISQ2PI * _math.exp(-0.5 * u * u)


@_numba.njit(cache=True, inline="always")
def _g2(u):
    return 0.5 * ((u * u + 1.0) * 0.5 * _math.erfc(-u * _SQRT1_2) + u * _ISQ2PI * _math.exp(-0.5 * u * u))


@_numba.njit(cache=True)
def _f1(d, s1, s2):
    if d < 0.0:
        return s1 * _g1(d / s1)
    f10 = s1 * _ISQ2PI
    return f10 + s2 * (_g1(d / s2) - _ISQ2PI)


@_numba.njit(cache=True)
def _f2(d, s1, s2):
    if d < 0.0:
        return s1 * s1 * _g2(d / s1)
    f10 = s1 * _ISQ2PI
    f20 = s1 * s1 * 0.25
    return f20 + f10 * d + s2 * s2 * (_g2(d / s2) - 0.25 - _ISQ2PI * d / s2)


@_numba.njit(cache=True)
def _mean_nonpositive(d0, c, s, s1, s2):
    a = 0.5 * abs(c)
    b = 0.5 * abs(s)
    if b > a:
        a, b = b, a
    if b < 1e-5:
        return (_f1(d0 + a, s1, s2) - _f1(d0 - a, s1, s2)) / (2.0 * a)
    return (_f2(d0 + a + b, s1, s2) - _f2(d0 + a - b, s1, s2) - _f2(d0 - a + b, s1, s2)
            + _f2(d0 - a - b, s1, s2)) / (4.0 * a * b)


@_numba.njit(cache=True)
def pixel_mean(d0, c, s, s_dark, s_bright):
    """Area mean of the unit step over a pixel whose centre is at signed distance d0 from a straight
    edge with normal (c, s) (render.analytic.StepProfile.pixel_mean_straight, in numba)."""
    s1 = max(s_dark, _S_FLOOR)
    s2 = max(s_bright, _S_FLOOR)
    if d0 <= 0.0:
        return _mean_nonpositive(d0, c, s, s1, s2)
    return 1.0 - _mean_nonpositive(-d0, c, s, s2, s1)


@_numba.njit(cache=True)
def _unit_mean(kind, dx, dy, rho, phi, radius, sgn, s1, s2):
    cp = _math.cos(phi)
    sp = _math.sin(phi)
    if kind == 0:
        return pixel_mean(dx * cp + dy * sp + rho, cp, sp, s1, s2)
    # circle with centre p + (sgn R - rho) n(phi); d = sgn (R - |x - c|), local normal along x - c
    k = sgn * radius - rho
    vx = dx - k * cp
    vy = dy - k * sp
    r = _math.sqrt(vx * vx + vy * vy)
    if not r > 0.0:
        return pixel_mean(sgn * radius, 1.0, 0.0, s1, s2)
    # the circle's bend inside the pixel: |x - c| grows by u_t^2 / (2r) along the tangent, mean 1/(24 r)
    return pixel_mean(sgn * (radius - r - 1.0 / (24.0 * r)), vx / r, vy / r, s1, s2)


@njit(cache=True, parallel=True)  # edgetruth.jit's: on one numba thread, its serial copy (same bits)
def _jacobian_kernel(kind, rho, phi, radius, sgn, A, B, s1, s2, union, J, M):
    """J[i, k, :] = d m / d theta at footprint pixel k = (dy, dx) flattened; M[i, k] the unit mean."""
    size = union.shape[1]
    r0 = size // 2
    for i in prange(rho.shape[0]):
        hs1 = _H_S_REL * max(s1[i], 1e-3)
        hs2 = _H_S_REL * max(s2[i], 1e-3)
        for iy in range(size):
            for ix in range(size):
                if not union[i, iy, ix]:
                    continue
                k = iy * size + ix
                dx = float(ix - r0)
                dy = float(iy - r0)
                m0 = _unit_mean(kind[i], dx, dy, rho[i], phi[i], radius[i], sgn[i], s1[i], s2[i])
                mr = _unit_mean(kind[i], dx, dy, rho[i] + _H_RHO, phi[i], radius[i], sgn[i], s1[i], s2[i])
                mp = _unit_mean(kind[i], dx, dy, rho[i], phi[i] + _H_PHI, radius[i], sgn[i], s1[i], s2[i])
                m1 = _unit_mean(kind[i], dx, dy, rho[i], phi[i], radius[i], sgn[i], s1[i] + hs1, s2[i])
                m2 = _unit_mean(kind[i], dx, dy, rho[i], phi[i], radius[i], sgn[i], s1[i], s2[i] + hs2)
                M[i, k] = m0
                J[i, k, 0] = B[i] * (mr - m0) / _H_RHO
                J[i, k, 1] = B[i] * (mp - m0) / _H_PHI
                J[i, k, 2] = 1.0
                J[i, k, 3] = m0
                J[i, k, 4] = B[i] * (m1 - m0) / hs1
                J[i, k, 5] = B[i] * (m2 - m0) / hs2


@njit(cache=True)
def _fisher_kernel(wm, J, F):
    """F[i, k, l] = sum_p wm[i, p] J[i, p, k] J[i, p, l]: ``np.einsum("np,npk,npl->nkl", wm, J, J)`` bit for bit
    (its products left to right, summed over p in order from 0.0), ~3x faster (tests/evaluate/test_crb.py)."""
    n, n_pix, k_par = J.shape
    for i in range(n):
        for k in range(k_par):
            for j in range(k_par):
                acc = 0.0
                for p in range(n_pix):
                    acc += wm[i, p] * J[i, p, k] * J[i, p, j]
                F[i, k, j] = acc


def edge_geometry(truth, x, y) -> dict:
    """rho = d(p), phi = direction of the true normal at p, and the curvature data of a true edge
    (``render.edge_truth.StraightEdge`` / ``CircleEdge``) at pixel centres (x, y)."""
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    nx, ny = truth.normal_at(x, y)
    n = x.size
    circle = getattr(truth, "kind", "line") == "circle"
    return {"kind": np.full(n, 1 if circle else 0, np.int64), "rho": truth.signed_distance(x, y),
            "phi": np.arctan2(ny, nx), "radius": np.full(n, truth.radius_px if circle else 0.0),
            "sgn": np.full(n, (1.0 if truth.bright_inside else -1.0) if circle else 1.0)}


def footprint_jacobian(geometry: dict, A, B, s_dark, s_bright, union: np.ndarray):
    """(J (N, SIZE*SIZE, 6), M (N, SIZE*SIZE)): Jacobian of the pixel means over the union footprint
    (zero elsewhere) w.r.t. COLUMNS, and the unit-step means."""
    n = geometry["rho"].size
    size = union.shape[1]
    bc = lambda v: np.ascontiguousarray(np.broadcast_to(np.asarray(v, float), (n,)))
    J = np.zeros((n, size * size, len(COLUMNS)))
    M = np.zeros((n, size * size))
    if n:
        _jacobian_kernel(geometry["kind"], bc(geometry["rho"]), bc(geometry["phi"]), bc(geometry["radius"]),
                         bc(geometry["sgn"]), bc(A), bc(B), bc(s_dark), bc(s_bright),
                         np.ascontiguousarray(union, bool), J, M)
    return J, M


def bound_from_fisher(F: np.ndarray, drop_rel: float = 1e-9) -> np.ndarray:
    """sqrt((F^-1)_00) for stacked Fisher matrices (..., K, K), parameter 0 = rho (px).

    A nuisance the footprint carries (almost) no information on -- a rotation seen by one row of
    pixels -- is dropped (treated as known: the bound only gets smaller, so it stays a bound) when
    its information is below ``drop_rel`` x F_rho,rho (per px or rad squared)."""
    F = np.array(F, float)
    diag = np.einsum("...kk->...k", F)
    weak = diag < drop_rel * diag[..., :1]
    weak[..., 0] = False
    k = F.shape[-1]
    eye = np.eye(k, dtype=bool)
    # replace dropped rows/columns by the identity: they decouple from rho
    F = np.where(weak[..., :, None] | weak[..., None, :], np.where(eye, 1.0, 0.0), F)
    d = np.sqrt(np.clip(np.einsum("...kk->...k", F), 1e-300, None))
    Fn = F / (d[..., :, None] * d[..., None, :])
    inv = np.linalg.pinv(Fn, rcond=1e-12, hermitian=True)
    v = inv[..., 0, 0] / d[..., 0] ** 2
    return np.sqrt(np.where(v > 0, v, np.inf))


def footprint_bounds(geometry: dict, A, B, s_dark, s_bright, masks: dict, noise_var=None,
                     variance_fn=None, background=0.0, blur_unknowns: str = "scale") -> dict:
    """The per-point bound (px) of each footprint in ``masks`` (name -> (N, SIZE, SIZE) bool).

    Noise: ``noise_var`` (gray levels^2, scalar or per point) for Gaussian noise, or ``variance_fn``
    mapping the pixel means (N, P) to their variances (a sensor's signal-dependent noise, e.g.
    K^2 (sigma_d^2 + mu_e) + 1/12 in DN^2; ``background`` is added to the means first).
    Blur: ``"scale"`` (default) -- one unknown, the scale of both sides' blurs, their ratio known
    (for a symmetric edge: the blur s); ``"both"`` -- s_dark and s_bright unknown separately."""
    if blur_unknowns not in ("scale", "both"):
        raise ValueError(f"blur_unknowns={blur_unknowns!r}: 'scale' or 'both'")
    if not masks:
        return {}
    stack = np.stack([np.asarray(m, bool) for m in masks.values()])
    union = stack.any(axis=0)
    J, M = footprint_jacobian(geometry, A, B, s_dark, s_bright, union)
    n = J.shape[0]
    if variance_fn is not None:
        mean = np.asarray(A, float).reshape(-1, 1) + np.asarray(B, float).reshape(-1, 1) * M + background
        w = 1.0 / np.asarray(variance_fn(mean), float)
    else:
        w = np.broadcast_to(1.0 / np.asarray(noise_var, float).reshape(-1, 1), M.shape)
    if blur_unknowns == "scale":
        # d m / d lambda at lambda = 1 for (s_dark, s_bright) = lambda (s_dark0, s_bright0)
        sd = np.broadcast_to(np.asarray(s_dark, float), (n,))[:, None]
        sb = np.broadcast_to(np.asarray(s_bright, float), (n,))[:, None]
        Jp = np.concatenate([J[:, :, :4], (sd * J[:, :, 4] + sb * J[:, :, 5])[:, :, None]], axis=2)
    else:
        Jp = J
    out = {}
    for name, m in zip(masks, stack):
        wm = np.ascontiguousarray(w * m.reshape(n, -1))
        F = np.empty((n, Jp.shape[2], Jp.shape[2]))
        _fisher_kernel(wm, np.ascontiguousarray(Jp), F)
        out[name] = bound_from_fisher(F)
    return out
