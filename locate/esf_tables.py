"""Tabulated edge-spread functions: the pixel means of a unit edge and their derivatives, from tables.

A camera's edge-spread function P_psi(d) -- the pixel box ⊗ PSF projected on the edge's normal, at
signed distance d (px, > 0 bright) and normal direction psi -- has no closed form.  It is tabulated
(``edgetruth.evaluate.bound_psf.EdgeSpread`` builds the tables from the camera's OTF) on a regular
grid of d per angle bin of psi in [0, 90°], with its slope P' and L = lambda dP/dlambda (the PSF's
scale lambda, relative).  This module holds the tables (``EsfTables``) and evaluates them for lines
and circles at pixel offsets from each point (``means``): cubic Hermite in d, linear in psi, the
derivatives by the chain rule through the tables.  The exact bound (``evaluate.bound_psf``) and the
locator ``patch_esf_fit`` share this one kernel, so the locator fits the model the bound is of.

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

@njit(cache=True, inline="always")
def _hermite_row(P, dP, j, d, k0, inv_h):
    x = d * inv_h + k0
    i = int(math.floor(x))
    if i < 0:
        i = 0
    if i > P.shape[1] - 2:
        i = P.shape[1] - 2
    t = x - i
    h = 1.0 / inv_h
    p0 = P[j, i]
    p1 = P[j, i + 1]
    m0 = dP[j, i] * h
    m1 = dP[j, i + 1] * h
    t2 = t * t
    t3 = t2 * t
    val = (2 * t3 - 3 * t2 + 1) * p0 + (t3 - 2 * t2 + t) * m0 + (-2 * t3 + 3 * t2) * p1 + (t3 - t2) * m1
    der = ((6 * t2 - 6 * t) * p0 + (3 * t2 - 4 * t + 1) * m0 + (-6 * t2 + 6 * t) * p1
           + (3 * t2 - 2 * t) * m1) * inv_h
    return val, der, i, t


@njit(cache=True, inline="always")
def line_bin(c, s, step_rad, nb):
    """(row, weight, sign of dpsi/dphi) of a line of normal (c, s): the same at every pixel, once per point."""
    la = math.atan2(abs(s), abs(c))
    lda = 1.0 if (s >= 0.0) == (c >= 0.0) else -1.0
    lx = la / step_rad
    lj = min(max(int(math.floor(lx)), 0), nb - 1)
    return lj, lx - lj, lda


@njit(cache=True, inline="always")
def pixel_mean(kind, rho, c, s, radius, sgn, dx, dy, lj, lw, lda, P, dP, L, step_rad, half_px, k0, inv_h,
               sx2, sy2, vc, with_l):
    """(M, dM/drho, dM/dphi, lambda dM/dlambda, dL/drho, dL/dphi) of one point at the pixel offset (dx, dy):
    (c, s) = n(phi), (lj, lw, lda) its ``line_bin``; dL/drho and dL/dphi are 0 unless ``with_l``.  The
    per-pixel body of ``_means_kernel``, shared with the fused fit of ``patch_esf_fit``."""
    nb = P.shape[0] - 1
    if kind == 0:
        d = dx * c + dy * s + rho
        d_r = 1.0
        d_p = dy * c - dx * s
        s_r = 0.0
        s_p = 1.0
        d_l = 0.0
        j0 = lj
        w = lw
        da = lda
    else:
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
        a = math.atan2(abs(sn), abs(cs))
        da = 1.0 if (sn >= 0.0) == (cs >= 0.0) else -1.0
        x = a / step_rad
        j0 = min(max(int(math.floor(x)), 0), nb - 1)
        w = x - j0
    if d <= -half_px or d >= half_px:
        return (0.0 if d < 0 else 1.0), 0.0, 0.0, 0.0, 0.0, 0.0
    v0, e0, ii, t = _hermite_row(P, dP, j0, d, k0, inv_h)
    v1, e1, _, _ = _hermite_row(P, dP, j0 + 1, d, k0, inv_h)
    l0 = L[j0, ii] * (1.0 - t) + L[j0, ii + 1] * t
    l1 = L[j0 + 1, ii] * (1.0 - t) + L[j0 + 1, ii + 1] * t
    pd = (1.0 - w) * e0 + w * e1
    pa = (v1 - v0) / step_rad * da
    lr = 0.0
    lp = 0.0
    if with_l:
        ld = ((1.0 - w) * (L[j0, ii + 1] - L[j0, ii]) + w * (L[j0 + 1, ii + 1] - L[j0 + 1, ii])) * inv_h
        la = (l1 - l0) / step_rad * da
        lr = ld * d_r + la * s_r
        lp = ld * d_p + la * s_p
    return ((1.0 - w) * v0 + w * v1, pd * d_r + pa * s_r, pd * d_p + pa * s_p, (1.0 - w) * l0 + w * l1 + pd * d_l,
            lr, lp)


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
    bc = lambda v, t=float: np.ascontiguousarray(np.broadcast_to(np.asarray(v, t), (n,)))  # noqa: E731
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
