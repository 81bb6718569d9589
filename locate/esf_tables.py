"""Tabulated edge-spread functions: the pixel means of a unit edge and their derivatives, from tables.

A camera's edge-spread function P_psi(d) -- the pixel box ⊗ PSF projected on the edge's normal, at
signed distance d (px, > 0 bright) and normal direction psi -- has no closed form.  It is tabulated
(``edgetruth.evaluate.bound_psf.EdgeSpread`` builds the tables from the camera's OTF) on a regular
grid of d per angle bin of psi in [0, 90°], with its slope P' and L = lambda dP/dlambda (the PSF's
scale lambda, relative).  This module holds the tables (``EsfTables``) and evaluates them for lines
and circles at pixel offsets from each point (``means``): cubic Hermite in d, linear in psi, the
derivatives by the chain rule through the tables.  The exact bound (``evaluate.bound_psf``) and the
locator ``patch_esf_fit`` share this one kernel, so the locator fits the model the bound is of (the locator
by ``patch_means``: the same steps over a patch, an arc's angle within 2 ulp of the bound's).

Geometry (as ``evaluate.crb.edge_geometry``): per point, ``kind`` 0 line / 1 circle, ``rho`` the
signed distance (px) of the point to the edge, ``phi`` the normal's direction (rad, towards the bright
side), ``radius`` (px) and ``sgn`` (+1: bright inside) of a circle, whose centre lies at
(sgn radius - rho) n(phi) from the point.  A circle's pixel uses its tangent line (its true distance
and local normal) with the bend seen by the pixel's and the kernel's tangential spread, to first order
in 1/r: P(d - sgn (1/12 + v_t) / 2r), v_t = sx2 sin² + sy2 cos² + vc (docs/bound.md).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from edgetruth.jit import njit


@dataclass(frozen=True)
class EsfTables:
    """The arrays the kernel reads: P, dP (1/px) and L = lambda dP/dlambda, each (n_bins + 1, n_d), row j
    the normal direction j * ``step_rad``, column i the distance (i - ``k0``) / ``inv_h`` px; beyond
    ``half_px`` the plateaus 0 / 1.  ``sx2``, ``sy2``, ``vc``: the PSF's tangential variances (px², the
    aberration along x and y, and the isotropic rest: defocus disk, OLPF), for a circle's bend."""

    P: np.ndarray
    dP: np.ndarray
    L: np.ndarray
    step_rad: float
    half_px: float
    k0: float
    inv_h: float
    sx2: float = 0.0
    sy2: float = 0.0
    vc: float = 0.0

    def angle_bins(self, phi) -> np.ndarray:
        """The two angle rows a line of normal direction ``phi`` (rad) reads."""
        a = np.arctan2(np.abs(np.sin(phi)), np.abs(np.cos(phi)))
        j = np.clip(np.floor(a / self.step_rad).astype(np.int64), 0, self.P.shape[0] - 2)
        return np.concatenate([j, j + 1])


# Per point i and offset k: the unit mean M and its derivatives by the chain rule through the tables --
# dM/drho = P_d dd/drho + P_psi dpsi/drho, likewise for phi, and dM/dlambda = L + P_d dd/dlambda (the
# circle's bend grows with the PSF's tangential variance) -- P_d from the cubic Hermite in d, P_psi the
# slope of the linear interpolation in psi (as a central difference across a bin boundary gives), L
# linear in d.

@njit(cache=True, forceinline=True)
def _column(d, k0, inv_h, nd):
    """(column i, fraction t) of distance d in a table of nd columns: the Hermite cell [i, i + 1]."""
    x = d * inv_h + k0
    i = int(math.floor(x))
    if i < 0:
        i = 0
    if i > nd - 2:
        i = nd - 2
    return i, x - i


@njit(cache=True, forceinline=True)
def _hermite(p0, p1, q0, q1, t, inv_h):
    """(value, slope) of the cubic Hermite through (p0, slope q0), (p1, q1) at fraction t of the cell."""
    h = 1.0 / inv_h
    m0 = q0 * h
    m1 = q1 * h
    t2 = t * t
    t3 = t2 * t
    val = (2 * t3 - 3 * t2 + 1) * p0 + (t3 - 2 * t2 + t) * m0 + (-2 * t3 + 3 * t2) * p1 + (t3 - t2) * m1
    der = ((6 * t2 - 6 * t) * p0 + (3 * t2 - 4 * t + 1) * m0 + (-6 * t2 + 6 * t) * p1
           + (3 * t2 - 2 * t) * m1) * inv_h
    return val, der


@njit(cache=True, forceinline=True)
def line_bin(c, s, step_rad, nb):
    """(row, weight, sign of dpsi/dphi) of a line of normal (c, s): the same at every pixel, once per point."""
    la = math.atan2(abs(s), abs(c))
    lda = 1.0 if (s >= 0.0) == (c >= 0.0) else -1.0
    lx = la / step_rad
    lj = min(max(int(math.floor(lx)), 0), nb - 1)
    return lj, lx - lj, lda


@njit(cache=True, forceinline=True)
def arc_geometry(rho, c, s, radius, sgn, dx, dy, sx2, sy2, vc):
    """A circle's pixel at offset (dx, dy): (d, dd/drho, dd/dphi, dpsi/drho, dpsi/dphi, dd/dlambda, |sin psi|,
    |cos psi|, the sign of dpsi) -- psi the local normal's direction, read from the tables as atan2 of the two."""
    g = sgn
    kk = g * radius - rho
    vx = dx - kk * c
    vy = dy - kk * s
    r = math.sqrt(vx * vx + vy * vy)
    if r < 1e-9:
        r = 1e-9
    sn = vy / r
    cs = vx / r
    vt = sx2 * sn * sn + sy2 * cs * cs + vc
    ct = 1.0 / 12.0 + vt
    d = g * (radius - r - ct / (2.0 * r))
    r_r = (vx * c + vy * s) / r
    r_p = kk * (vx * s - vy * c) / r
    s_r = (vx * s - vy * c) / (r * r)
    s_p = -kk * (vx * c + vy * s) / (r * r)
    dd_r = g * (-1.0 + ct / (2.0 * r * r))
    dd_s = -g * (2.0 * sn * cs * (sx2 - sy2)) / (2.0 * r)
    d_r = dd_r * r_r + dd_s * s_r
    d_p = dd_r * r_p + dd_s * s_p
    d_l = -g * vt / r
    da = 1.0 if (sn >= 0.0) == (cs >= 0.0) else -1.0
    return d, d_r, d_p, s_r, s_p, d_l, abs(sn), abs(cs), da


@njit(cache=True, forceinline=True)
def _angle_row(x, nb):
    """(row j, weight of row j + 1) at angle coordinate x = psi / step_rad, of nb + 1 rows."""
    j = min(max(int(math.floor(x)), 0), nb - 1)
    return j, x - j


@njit(cache=True, forceinline=True)
def _rows(w, da, t, v0, e0, v1, e1, l00, l01, l10, l11, step_rad, inv_h):
    """The two angle rows' Hermite values and slopes (v, e) and L's cell corners, interpolated with weight w of
    the second (da the sign of dpsi): (P, dP/dd, dP/dpsi, L, dL/dd, dL/dpsi)."""
    l0 = l00 * (1.0 - t) + l01 * t
    l1 = l10 * (1.0 - t) + l11 * t
    return ((1.0 - w) * v0 + w * v1, (1.0 - w) * e0 + w * e1, (v1 - v0) / step_rad * da, (1.0 - w) * l0 + w * l1,
            ((1.0 - w) * (l01 - l00) + w * (l11 - l10)) * inv_h, (l1 - l0) / step_rad * da)


@njit(cache=True, forceinline=True)
def _chain(d, d_r, d_p, s_r, s_p, d_l, m, pd, pa, lm, ld, la, half_px, with_l):
    """``pixel_mean``'s values by the chain rule from ``_rows``' and the distance's and angle's slopes; the
    plateaus 0 / 1 beyond ``half_px``."""
    if d <= -half_px or d >= half_px:
        return (0.0 if d < 0 else 1.0), 0.0, 0.0, 0.0, 0.0, 0.0
    lr = 0.0
    lp = 0.0
    if with_l:
        lr = ld * d_r + la * s_r
        lp = ld * d_p + la * s_p
    return m, pd * d_r + pa * s_r, pd * d_p + pa * s_p, lm + pd * d_l, lr, lp


@njit(cache=True, forceinline=True)
def pixel_mean(kind, rho, c, s, radius, sgn, dx, dy, lj, lw, lda, P, dP, L, step_rad, half_px, k0, inv_h,
               sx2, sy2, vc, with_l):
    """(M, dM/drho, dM/dphi, lambda dM/dlambda, dL/drho, dL/dphi) of one point at the pixel offset (dx, dy):
    (c, s) = n(phi), (lj, lw, lda) its ``line_bin``; dL/drho and dL/dphi are 0 unless ``with_l``.  The
    per-pixel body of ``_means_kernel``; ``patch_means`` runs the same steps over a patch."""
    if kind == 0:
        d = dx * c + dy * s + rho
        d_r, d_p, s_r, s_p, d_l, j, w, da = 1.0, dy * c - dx * s, 0.0, 1.0, 0.0, lj, lw, lda
    else:
        d, d_r, d_p, s_r, s_p, d_l, asn, acs, da = arc_geometry(rho, c, s, radius, sgn, dx, dy, sx2, sy2, vc)
        j, w = _angle_row(math.atan2(asn, acs) / step_rad, P.shape[0] - 1)
    if d <= -half_px or d >= half_px:  # the plateaus (``_chain`` has them too): no reads
        return (0.0 if d < 0 else 1.0), 0.0, 0.0, 0.0, 0.0, 0.0
    i, t = _column(d, k0, inv_h, P.shape[1])
    v0, e0 = _hermite(P[j, i], P[j, i + 1], dP[j, i], dP[j, i + 1], t, inv_h)
    v1, e1 = _hermite(P[j + 1, i], P[j + 1, i + 1], dP[j + 1, i], dP[j + 1, i + 1], t, inv_h)
    m, pd, pa, lm, ld, la = _rows(w, da, t, v0, e0, v1, e1, L[j, i], L[j, i + 1], L[j + 1, i], L[j + 1, i + 1],
                                  step_rad, inv_h)
    return _chain(d, d_r, d_p, s_r, s_p, d_l, m, pd, pa, lm, ld, la, half_px, with_l)


@njit(cache=True, forceinline=True)
def atan_quadrant(y, x):
    """atan2(y, x) for y, x >= 0 without a libm call, so that a loop of it vectorises (~10x libm's time): the
    smaller over the larger (a division), then SLEEF's degree-19 polynomial (its atan2k) by Estrin's scheme (a
    short chain of dependent operations); within 2 ulp of libm's (4.4e-16 rad), which ``pixel_mean`` keeps."""
    swap = y > x
    den = y if swap else x
    s = (x if swap else y) / den if den > 0.0 else 0.0  # atan2(0, 0) = 0
    t = s * s
    t2 = t * t
    t4 = t2 * t2
    t8 = t4 * t4
    q0 = (-0.333333333333311110369124 + 0.199999999996591265594148 * t) + (
        -0.14285714266771329383765 + 0.111111105648261418443745 * t) * t2
    q1 = (-0.090908995008245008229153 + 0.0769219538311769618355029 * t) + (
        -0.0666573579361080525984562 + 0.0587666392926673580854313 * t) * t2
    q2 = (-0.0523674852303482457616113 + 0.0466667150077840625632675 * t) + (
        -0.0407629191276836500001934 + 0.0337852580001353069993897 * t) * t2
    q3 = (-0.0254517624932312641616861 + 0.016599329773529201970117 * t) + (
        -0.00889896195887655491740809 + 0.00370026744188713119232403 * t) * t2
    q4 = (-0.00110611831486672482563471 + 0.000209850076645816976906797 * t) - 1.88796008463073496563746e-05 * t2
    u = ((q0 + q1 * t4) + (q2 + q3 * t4) * t8) + q4 * (t8 * t8)
    a = u * t * s + s
    return 0.5 * math.pi - a if swap else a


@njit(cache=True, error_model="numpy")  # numpy's: no test per division (python's), so the first pass vectorises
def patch_means(kind, rho, c, s, radius, sgn, ox, oy, npix, P, dP, L, step_rad, half_px, k0, inv_h, sx2, sy2, vc,
                out, G, cell):
    """``pixel_mean`` (with_l) of one point at the offsets (ox, oy)[:npix]: out[0:6, k] <- its six values, the
    same operations but an arc's angle by ``atan_quadrant`` (within 2 ulp of libm's atan2: the values agree to
    ~1e-15).  In two passes over the pixels: the geometry and the table cell, which the compiler vectorises
    (square roots, divisions, the angle 8 pixels at once), then the table reads and the interpolation (scalar:
    split into vectorised loops of fewer arrays it was slower).  A function of its own, not inline="always": a
    kernel that evaluates the model at two places would have numba compile it twice.  Work: G (9, >= npix) and
    cell (2, >= npix) the cells' rows and columns."""
    nb = P.shape[0] - 1
    nd = P.shape[1]
    D, DR, DP, SR, SP, DL, W, DA, T = G[0], G[1], G[2], G[3], G[4], G[5], G[6], G[7], G[8]
    J = cell[0]
    I = cell[1]
    if kind == 0:
        lj, lw, lda = line_bin(c, s, step_rad, nb)
        for k in range(npix):
            d = ox[k] * c + oy[k] * s + rho
            D[k] = d
            DP[k] = oy[k] * c - ox[k] * s
            DR[k], SR[k], SP[k], DL[k], W[k], DA[k], J[k] = 1.0, 0.0, 1.0, 0.0, lw, lda, lj
            I[k], T[k] = _column(d, k0, inv_h, nd)
    else:
        for k in range(npix):
            d, DR[k], DP[k], SR[k], SP[k], DL[k], asn, acs, DA[k] = arc_geometry(rho, c, s, radius, sgn, ox[k], oy[k],
                                                                                 sx2, sy2, vc)
            D[k] = d
            J[k], W[k] = _angle_row(atan_quadrant(asn, acs) / step_rad, nb)
            I[k], T[k] = _column(d, k0, inv_h, nd)
    for k in range(npix):
        j = J[k]
        i = I[k]
        t = T[k]
        v0, e0 = _hermite(P[j, i], P[j, i + 1], dP[j, i], dP[j, i + 1], t, inv_h)
        v1, e1 = _hermite(P[j + 1, i], P[j + 1, i + 1], dP[j + 1, i], dP[j + 1, i + 1], t, inv_h)
        m, pd, pa, lm, ld, la = _rows(W[k], DA[k], t, v0, e0, v1, e1, L[j, i], L[j, i + 1], L[j + 1, i],
                                      L[j + 1, i + 1], step_rad, inv_h)
        out[0, k], out[1, k], out[2, k], out[3, k], out[4, k], out[5, k] = _chain(
            D[k], DR[k], DP[k], SR[k], SP[k], DL[k], m, pd, pa, lm, ld, la, half_px, True)


@njit(cache=True)
def _means_kernel(kind, rho, phi, radius, sgn, offx, offy, use, P, dP, L, step_rad, half_px, k0, inv_h,
                  sx2, sy2, vc, M, Jr, Jp, Jl, with_l, Lr, Lp):
    """M, dM/drho, dM/dphi, lambda dM/dlambda at every (point, offset) where ``use``; with ``with_l`` also
    the derivatives of L = lambda dP/dlambda in rho and phi (Lr, Lp: the slope of its linear interpolation
    in d and in psi; a circle's bend term in L is left constant) -- the exact Jacobian of a model first
    order in lambda, A + B (M + (lambda - 1) Jl)."""
    n = rho.shape[0]
    npx = offx.shape[0]
    nb = P.shape[0] - 1
    for i in range(n):
        c = math.cos(phi[i])
        s = math.sin(phi[i])
        lj, lw, lda = line_bin(c, s, step_rad, nb)
        for k in range(npx):
            if not use[i, k]:
                continue
            m, jr, jp, jl, lr, lp = pixel_mean(kind[i], rho[i], c, s, radius[i], sgn[i], offx[k], offy[k], lj, lw,
                                               lda, P, dP, L, step_rad, half_px, k0, inv_h, sx2, sy2, vc, with_l)
            M[i, k] = m
            Jr[i, k] = jr
            Jp[i, k] = jp
            Jl[i, k] = jl
            if with_l:
                Lr[i, k] = lr
                Lp[i, k] = lp


def means(tables: EsfTables, geometry: dict, offsets, use=None, l_derivatives: bool = False):
    """(M, dM/drho (1/px), dM/dphi (1/rad), lambda dM/dlambda), each (N, P), of the unit edge (0 dark .. 1
    bright) at pixel ``offsets`` (P, 2) = (dx, dy) px from each point of ``geometry`` (module docstring),
    where ``use`` (N, P) (default all; elsewhere 0).  ``l_derivatives``: also dL/drho and dL/dphi of
    L = lambda dM/dlambda (six arrays).  The tables must hold every angle row the points read (a line's two
    at phi; a circle's all)."""
    off = np.ascontiguousarray(np.asarray(offsets, float).reshape(-1, 2))
    n = np.asarray(geometry["rho"]).size
    npx = off.shape[0]
    use = np.ones((n, npx), bool) if use is None else np.ascontiguousarray(use, bool)
    # always a fresh writable array: a read-only one (a broadcast view) is another type to numba, and compiling
    # the kernel a second time for it cost 3.5 s of a cold start
    bc = lambda v, t=float: np.array(np.broadcast_to(np.asarray(v, t), (n,)))  # noqa: E731
    kind, rho, phi = bc(geometry["kind"], np.int64), bc(geometry["rho"]), bc(geometry["phi"])
    radius, sgn = bc(geometry["radius"]), bc(geometry["sgn"])
    M = np.zeros((n, npx))
    Jr, Jp, Jl = np.zeros_like(M), np.zeros_like(M), np.zeros_like(M)
    Lr, Lp = (np.zeros_like(M), np.zeros_like(M)) if l_derivatives else (np.zeros((0, 0)), np.zeros((0, 0)))
    if n and npx:
        t = tables
        _means_kernel(kind, rho, phi, radius, sgn, off[:, 0].copy(), off[:, 1].copy(), use, t.P, t.dP, t.L,
                      float(t.step_rad), float(t.half_px), float(t.k0), float(t.inv_h), float(t.sx2), float(t.sy2),
                      float(t.vc), M, Jr, Jp, Jl, bool(l_derivatives), Lr, Lp)
    return (M, Jr, Jp, Jl, Lr, Lp) if l_derivatives else (M, Jr, Jp, Jl)
