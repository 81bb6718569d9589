"""The per-point Cramér–Rao bound on renders: the expected image under the camera's actual PSF.

``evaluate.crb`` bounds a pixel-integrated *Gaussian*-blurred edge.  A render's edge is blurred by
the camera's PSF -- Airy (diffraction) ⊗ Gaussian aberration σ(h) ⊗ defocus disk ⊗ 4-dot OLPF --
and integrated over the pixel box.  This module builds that expected image and its Fisher
information over a method's footprint (docs/bound.md, "On renders: the exact bound").

**Straight edge.**  The pixel mean of a straight edge with unit normal n(ψ) at signed distance d
from the pixel centre is the edge-spread function of the 1-D kernel (pixel box ⊗ PSF) projected on
the normal, whose transfer function is the 2-D OTF on the normal's line:

    T_ψ(ν) = OTF_psf(ν cos ψ, ν sin ψ) · sinc(ν cos ψ) · sinc(ν sin ψ)          (render.mtf)
    P_ψ(d) = Φ(d/σ_r) + F⁻¹[(T_ψ(ν) − e^{−2π²σ_r²ν²}) / (2πiν)](d)

(σ_r: a reference Gaussian that carries the step; the Fourier term is the smooth, decaying
difference, computed by one FFT on a 1/64-px grid over ±512 px).  P_ψ and P'_ψ are tabulated for
ψ in 0.25° steps (``angle_step_deg``) over [0, 90°] (T depends on |cos ψ|, |sin ψ| only) and
interpolated: cubic Hermite in d, linear in ψ.  ``EdgeSpread.stack`` builds many bins at once with a
third table, λ ∂P/∂λ, and ``means_and_derivatives`` evaluates the means and their derivatives by the
chain rule through the tables in numba (the kernel is ``edgetruth.locate.esf_tables``, shared with the
locator ``patch_esf_fit``; ``EdgeSpread.tables`` hands it the arrays; ``footprint_bounds`` uses it;
``jacobian``, central differences of ``unit_means``, stays as the reference).  The PSF may be scaled by λ
(blur scale): OTF_psf(λν).

**Circle.**  Per pixel the tangent line (the true distance d and local normal ψ of the pixel
centre), the circle's bend inside the pixel (1/(24 r), as ``evaluate.crb``) and the bend seen by
the PSF's tangential spread v_t: the disk ⊗ kernel value is P(d) − sgn ∫ z_t² K(d, z_t) dz_t / 2r
≈ P(d − sgn (1/12 + v_t) / 2r) (first order in 1/r; exact for a Gaussian kernel), v_t = σ_t² +
r_def²/4 + (OLPF split)²/4 (the Airy pattern's tangential variance is unbounded: left out).

**Unknowns** θ = (ρ, φ, A, B[, λ]) with ρ = d(p), φ the normal's direction at p (a circle turns
about p), A the dark level, B the contrast (levels on both sides: shading is a level per point),
λ the PSF's scale when the method estimates the blur (``blur_unknown=True``).  **Noise**: a pixel's
variance from its mean (``variance_fn``, e.g. the EMVA model K²(σd² + μe) + 1/12 in DN²) plus
``extra_var`` (the renderer's Monte-Carlo noise).  F = Σ J Jᵀ / σ_i² over the footprint;
bound = sqrt((F⁻¹)_ρρ) (``crb.bound_from_fisher``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numba
import numpy as np
from scipy.special import ndtr

from edgetruth.evaluate.crb import bound_from_fisher
from edgetruth.locate.esf_tables import EsfTables
from edgetruth.locate.esf_tables import means as esf_means
from edgetruth.render.optics import mtf
GRID_STEP_PX = 1.0 / 64.0
FFT_LEN = 1 << 16  # x 1/64 px = ±512 px period: the Airy ESF tail beyond it is < 1e-3 of the contrast
TABLE_HALF_PX = 16.0
ANGLE_STEP_DEG = 0.25
_H_RHO = 1e-4
_H_PHI = 1e-4
_H_SCALE = 1e-3


@dataclass(frozen=True)
class Optics:
    """The PSF at one place of the image, in pixels (without the pixel box)."""

    cutoff_cy_px: float = math.inf  # diffraction: p / (λN); inf = none
    sigma_x_px: float = 0.0  # Gaussian aberration along the image axes
    sigma_y_px: float = 0.0
    defocus_px: float = 0.0  # radius of the defocus disk
    olpf_px: float = 0.0  # 4-dot OLPF split

    @classmethod
    def from_camera(cls, camera, field_h: float = 0.0, defocus_px: float = 0.0) -> "Optics":
        """The camera's PSF at field height ``field_h`` (render.camera.Camera, render.psf's model)."""
        p = camera.pitch_um
        g = 1.0 + camera.aberration_sigma_growth * field_h ** 2
        sy = getattr(camera, "aberration_sigma_y_um", None)
        sx = camera.aberration_sigma_um
        return cls(mtf.diffraction_cutoff_cy_px(p, camera.diffraction_wavelength_nm, camera.f_number),
                   sx / p * g, (sx if sy is None else sy) / p * g, float(defocus_px), camera.olpf_split_um / p)

    def otf(self, nu_x, nu_y, scale: float = 1.0):
        """The PSF's OTF (no pixel box), the PSF's lengths scaled by ``scale``."""
        nu_x = np.asarray(nu_x, float) * scale
        nu_y = np.asarray(nu_y, float) * scale
        nu = np.hypot(nu_x, nu_y)
        out = mtf.diffraction_mtf(nu, self.cutoff_cy_px) * np.exp(
            -2.0 * np.pi ** 2 * (self.sigma_x_px ** 2 * nu_x ** 2 + self.sigma_y_px ** 2 * nu_y ** 2))
        if self.defocus_px:
            out = out * mtf.defocus_otf(nu, self.defocus_px)
        if self.olpf_px:
            out = out * mtf.olpf_otf(nu_x, nu_y, self.olpf_px)
        return out

    def tangential_variance(self, psi, scale: float = 1.0):
        """Variance of the PSF along the edge (direction psi + 90°), Airy left out."""
        s, c = np.sin(psi), np.cos(psi)
        v = self.sigma_x_px ** 2 * s * s + self.sigma_y_px ** 2 * c * c + self.defocus_px ** 2 / 4.0 \
            + self.olpf_px ** 2 / 4.0
        return v * scale * scale

    def reference_sigma(self) -> float:
        v = 1.0 / 12.0 + max(self.sigma_x_px, self.sigma_y_px) ** 2 + self.defocus_px ** 2 / 4.0 + self.olpf_px ** 2 / 4
        if math.isfinite(self.cutoff_cy_px):
            v += (0.42 / self.cutoff_cy_px) ** 2
        return math.sqrt(v)


@dataclass
class EdgeSpread:
    """Tabulated P_ψ(d) and P'_ψ(d) of box ⊗ PSF (scale λ), built per angle bin when first needed.

    ``angle_step_deg``: the bins of ψ (linear interpolation between them); ``fft_len``: the FFT's
    length on the 1/64-px grid (its period: ``fft_len``/64 px).  ``stack`` builds many bins at once
    (batched FFTs over the PSF's band only) with a third table, dP/dλ (relative: λ ∂P/∂λ)."""

    optics: Optics
    scale: float = 1.0
    fft_len: int = FFT_LEN
    angle_step_deg: float = ANGLE_STEP_DEG
    _tables: dict = field(default_factory=dict, repr=False)

    def __post_init__(self):
        n = self.fft_len
        self._nu = np.fft.rfftfreq(n, d=GRID_STEP_PX)
        self._k = int(round(TABLE_HALF_PX / GRID_STEP_PX))
        self.d = np.arange(-self._k, self._k + 1) * GRID_STEP_PX
        self._sr = self.optics.reference_sigma() * self.scale
        self.n_bins = int(round(90.0 / self.angle_step_deg))
        if abs(self.n_bins * self.angle_step_deg - 90.0) > 1e-9:
            raise ValueError(f"angle_step_deg={self.angle_step_deg}: must divide 90")
        self._stack = None  # (P, dP, L) over all bins, rows filled by ``stack``
        self._built = np.zeros(self.n_bins + 1, bool)

    def _table(self, j: int):
        t = self._tables.get(j)
        if t is not None:
            return t
        psi = math.radians(j * self.angle_step_deg)
        c, s = math.cos(psi), math.sin(psi)
        nu = self._nu
        T = self.optics.otf(nu * c, nu * s, self.scale) * np.sinc(nu * c) * np.sinc(nu * s)
        G = np.exp(-2.0 * np.pi ** 2 * self._sr ** 2 * nu ** 2)
        with np.errstate(divide="ignore", invalid="ignore"):
            D = np.where(nu > 0, (T - G) / (2j * np.pi * np.where(nu > 0, nu, 1.0)), 0.0)
        h = GRID_STEP_PX
        n = self.fft_len
        diff = np.fft.irfft(D, n=n) / h
        lsf = np.fft.irfft(T, n=n) / h
        idx = np.r_[n - self._k:n, 0:self._k + 1]
        P = ndtr(self.d / self._sr) + diff[idx]
        dP = lsf[idx]
        t = (P, dP)
        self._tables[j] = t
        return t

    def band_limit_cy_px(self) -> float:
        """Frequency beyond which the PSF's OTF is 0 (diffraction) or below 1e-13 (Gaussian)."""
        o = self.optics
        lim = o.cutoff_cy_px
        smin = min(o.sigma_x_px, o.sigma_y_px)
        if smin > 0:
            lim = min(lim, math.sqrt(30.0 / (2.0 * math.pi ** 2)) / smin)
        return lim / self.scale

    def stack(self, bins=None):
        """(P, dP, L) arrays (n_bins + 1, len(d)) of every angle bin, the rows of ``bins`` (default:
        all) built: P and P' as ``_table``, L = λ ∂P/∂λ (the PSF's scale, relative; the pixel box
        fixed) from the central difference of the OTF in λ (step 1e-4)."""
        nd = self.d.size
        if self._stack is None:
            self._stack = (np.zeros((self.n_bins + 1, nd)), np.zeros((self.n_bins + 1, nd)),
                           np.zeros((self.n_bins + 1, nd)))
        want = np.arange(self.n_bins + 1) if bins is None else np.unique(np.asarray(bins, np.int64))
        want = want[(want >= 0) & (want <= self.n_bins)]
        want = want[~self._built[want]]
        if want.size:
            self._build(want)
        return self._stack

    def tables(self, bins=None) -> EsfTables:
        """The ``locate.esf_tables.EsfTables`` of this spread (the rows of ``bins`` built, default all): what
        the shared kernel and the locator patch_esf_fit read."""
        P, dP, L = self.stack(bins)
        o = self.optics
        lam2 = self.scale ** 2
        return EsfTables(P, dP, L, math.radians(self.angle_step_deg), TABLE_HALF_PX, float(self._k),
                         1.0 / GRID_STEP_PX, o.sigma_x_px ** 2 * lam2, o.sigma_y_px ** 2 * lam2,
                         (o.defocus_px ** 2 / 4.0 + o.olpf_px ** 2 / 4.0) * lam2)

    def _build(self, bins, chunk: int = 48):
        n = self.fft_len
        h = GRID_STEP_PX
        nu_all = self._nu
        lim = self.band_limit_cy_px()
        m = nu_all.size if not math.isfinite(lim) else min(nu_all.size, int(np.searchsorted(nu_all, lim * 1.01)) + 2)
        nu = nu_all[:m]
        inv = np.zeros(m, complex)
        inv[1:] = 1.0 / (2j * np.pi * nu[1:])
        G_all = np.exp(-2.0 * np.pi ** 2 * self._sr ** 2 * nu_all ** 2)
        idx = np.r_[n - self._k:n, 0:self._k + 1]
        # beyond the band the OTF is 0: that part of (T - G)/(2 pi i nu) is -G/(2 pi i nu), the same for every bin
        tail = np.zeros(nu_all.size, complex)
        tail[m:] = -G_all[m:] / (2j * np.pi * nu_all[m:])
        base = ndtr(self.d / self._sr) + (np.fft.irfft(tail, n=n) / h)[idx]
        eps = 1e-4
        P, dP, L = self._stack
        for c0 in range(0, bins.size, chunk):
            b = bins[c0:c0 + chunk]
            psi = np.radians(b * self.angle_step_deg)[:, None]
            nx, ny = nu[None, :] * np.cos(psi), nu[None, :] * np.sin(psi)
            box = np.sinc(nx) * np.sinc(ny)
            T = self.optics.otf(nx, ny, self.scale) * box
            dT = (self.optics.otf(nx, ny, self.scale * (1 + eps))
                  - self.optics.otf(nx, ny, self.scale * (1 - eps))) * box / (2 * eps)
            D = (T - G_all[None, :m]) * inv[None, :]
            P[b] = base[None, :] + (np.fft.irfft(D, n=n, axis=1) / h)[:, idx]
            dP[b] = (np.fft.irfft(T, n=n, axis=1) / h)[:, idx]
            L[b] = (np.fft.irfft(dT * inv[None, :], n=n, axis=1) / h)[:, idx]
            self._built[b] = True

    def value(self, d, psi):
        """(P, dP/dd) at signed distances d and local normal directions psi (arrays, same shape)."""
        d = np.asarray(d, float)
        a = np.abs(np.arctan2(np.abs(np.sin(psi)), np.abs(np.cos(psi))))  # fold to [0, pi/2]
        x = np.degrees(a) / self.angle_step_deg
        j0 = np.clip(np.floor(x).astype(np.int64), 0, self.n_bins - 1)
        w = x - j0
        P = np.zeros(d.shape)
        dP = np.zeros(d.shape)
        for j in np.unique(np.concatenate([j0.ravel(), j0.ravel() + 1])):
            wj = np.where(j0 == j, 1.0 - w, 0.0) + np.where(j0 + 1 == j, w, 0.0)
            use = wj > 0
            if not use.any():
                continue
            p, dp = self._hermite(self._table(int(j)), d[use])
            P[use] += wj[use] * p
            dP[use] += wj[use] * dp
        return P, dP

    def _hermite(self, table, d):
        P, dP = table
        h = GRID_STEP_PX
        x = np.clip(d, -TABLE_HALF_PX, TABLE_HALF_PX - 1e-9) / h + self._k
        i = np.clip(np.floor(x).astype(np.int64), 0, P.size - 2)
        t = x - i
        p0, p1 = P[i], P[i + 1]
        m0, m1 = dP[i] * h, dP[i + 1] * h
        t2, t3 = t * t, t * t * t
        val = (2 * t3 - 3 * t2 + 1) * p0 + (t3 - 2 * t2 + t) * m0 + (-2 * t3 + 3 * t2) * p1 + (t3 - t2) * m1
        der = ((6 * t2 - 6 * t) * p0 + (3 * t2 - 4 * t + 1) * m0 + (-6 * t2 + 6 * t) * p1 + (3 * t2 - 2 * t) * m1) / h
        # outside the table: the plateaus
        val = np.where(d < -TABLE_HALF_PX, 0.0, np.where(d >= TABLE_HALF_PX, 1.0, val))
        der = np.where(np.abs(d) >= TABLE_HALF_PX, 0.0, der)
        return val, der


# ---------------------------------------------------------------- the batched kernels
#
# The means and their derivatives: ``edgetruth.locate.esf_tables`` (shared with the locator patch_esf_fit).

@numba.njit(cache=True)
def _fisher_kernel(Jr, Jp, Jl, M, B, wgt, masks, npar, F):
    """F[u, i] = sum_k masks[u, i, k] w J J^T over (rho, phi, A, B[, lambda]), J = (B Jr, B Jp, 1, M, B Jl)."""
    nu_ = masks.shape[0]
    n = M.shape[0]
    npx = M.shape[1]
    nq = npar * (npar + 1) // 2
    for i in range(n):
        jac = np.empty(5)
        q = np.empty(15)
        acc = np.zeros((nu_, 15))
        for k in range(npx):
            wk = wgt[i, k]
            if wk == 0.0:
                continue
            jac[0] = B[i] * Jr[i, k]
            jac[1] = B[i] * Jp[i, k]
            jac[2] = 1.0
            jac[3] = M[i, k]
            jac[4] = B[i] * Jl[i, k]
            t = 0
            for a in range(npar):
                wa = wk * jac[a]
                for b in range(a + 1):
                    q[t] = wa * jac[b]
                    t += 1
            for u in range(nu_):
                if masks[u, i, k]:
                    for t in range(nq):
                        acc[u, t] += q[t]
        for u in range(nu_):
            t = 0
            for a in range(npar):
                for b in range(a + 1):
                    F[u, i, a, b] = acc[u, t]
                    F[u, i, b, a] = acc[u, t]
                    t += 1


@numba.njit(cache=True)
def _rho_variance_kernel(F, drop_rel, out):
    """(F^-1)_00 per stacked Fisher matrix (crb.bound_from_fisher's rule: a nuisance with information
    below drop_rel F_00 is dropped), by Cholesky of the diagonally normalised matrix; NaN where it
    is not positive definite (the caller falls back to the pseudo-inverse)."""
    n = F.shape[0]
    k = F.shape[1]
    for i in range(n):
        keep = np.empty(k, np.int64)
        m = 0
        f00 = F[i, 0, 0]
        for a in range(k):
            if a == 0 or F[i, a, a] >= drop_rel * f00:
                keep[m] = a
                m += 1
        L = np.zeros((m, m))
        d = np.empty(m)
        for a in range(m):
            d[a] = math.sqrt(max(F[i, keep[a], keep[a]], 1e-300))
        ok = True
        for a in range(m):
            for b in range(a + 1):
                v = F[i, keep[a], keep[b]] / (d[a] * d[b])
                for c in range(b):
                    v -= L[a, c] * L[b, c]
                if a == b:
                    if not v > 1e-12:
                        ok = False
                        break
                    L[a, a] = math.sqrt(v)
                else:
                    L[a, b] = v / L[b, b]
            if not ok:
                break
        if not ok:
            out[i] = np.nan
            continue
        # (Fn^-1)_00 = |L^-1 e_0|^2: forward substitution of e_0
        z = np.zeros(m)
        z[0] = 1.0 / L[0, 0]
        for a in range(1, m):
            v = 0.0
            for c in range(a):
                v -= L[a, c] * z[c]
            z[a] = v / L[a, a]
        v = 0.0
        for a in range(m):
            v += z[a] * z[a]
        out[i] = v / (d[0] * d[0])


def rho_bound(F: np.ndarray, drop_rel: float = 1e-9) -> np.ndarray:
    """``crb.bound_from_fisher`` for stacked (..., K, K) Fisher matrices, fast: Cholesky in numba, the
    pseudo-inverse only where a matrix is not positive definite."""
    F = np.asarray(F, float)
    shape = F.shape[:-2]
    Ff = np.ascontiguousarray(F.reshape(-1, F.shape[-2], F.shape[-1]))
    v = np.empty(Ff.shape[0])
    if Ff.shape[0]:
        _rho_variance_kernel(Ff, drop_rel, v)
    bad = ~np.isfinite(v)
    out = np.sqrt(np.where(v > 0, v, np.inf))
    if bad.any():
        out[bad] = bound_from_fisher(Ff[bad], drop_rel)
    return out.reshape(shape)


def means_and_derivatives(spread: EdgeSpread, geometry: dict, offsets, use=None):
    """(M, dM/drho, dM/dphi, lambda dM/dlambda), each (N, P), of the unit edge at pixel ``offsets``
    (P, 2) = (dx, dy) from each point (``crb.edge_geometry``), where ``use`` (N, P) (default all):
    one pass of the batched kernel (``locate.esf_tables.means``) over the tables of the angle bins
    the points need."""
    n = np.asarray(geometry["rho"]).size
    kind = np.broadcast_to(np.asarray(geometry["kind"], np.int64), (n,))
    # the angle bins the points reach: lines at phi, circles all around
    if n and np.any(kind == 1):
        bins = None
    else:
        phi = np.broadcast_to(np.asarray(geometry["phi"], float), (n,))
        step = math.radians(spread.angle_step_deg)
        a = np.arctan2(np.abs(np.sin(phi)), np.abs(np.cos(phi)))
        j = np.clip(np.floor(a / step).astype(np.int64), 0, spread.n_bins - 1)
        bins = np.concatenate([j, j + 1])
    return esf_means(spread.tables(bins), geometry, offsets, use)


def unit_means(spread: EdgeSpread, geometry: dict, offsets, rho=None, phi=None) -> np.ndarray:
    """(N, P) unit means (0 dark .. 1 bright) at pixel offsets (P, 2) = (dx, dy) from each point,
    for the geometry of ``crb.edge_geometry`` (rho, phi overridable for differences)."""
    rho = geometry["rho"] if rho is None else rho
    phi = geometry["phi"] if phi is None else phi
    dx = np.asarray(offsets, float)[None, :, 0]
    dy = np.asarray(offsets, float)[None, :, 1]
    cp = np.cos(phi)[:, None]
    sp = np.sin(phi)[:, None]
    circle = (geometry["kind"] == 1)[:, None]
    radius = np.where(geometry["kind"] == 1, geometry["radius"], 1.0)[:, None]
    sgn = geometry["sgn"][:, None]
    d_line = dx * cp + dy * sp + rho[:, None]
    k = sgn * radius - rho[:, None]
    vx = dx - k * cp
    vy = dy - k * sp
    r = np.maximum(np.hypot(vx, vy), 1e-12)
    psi_circle = np.arctan2(vy, vx)
    vt = spread.optics.tangential_variance(psi_circle, spread.scale)
    d_circle = sgn * (radius - r - (1.0 / 12.0 + vt) / (2.0 * r))
    d = np.where(circle, d_circle, d_line)
    psi = np.where(circle, psi_circle, np.broadcast_to(phi[:, None], d.shape))
    return spread.value(d, psi)[0]


def offsets_of(union: np.ndarray) -> np.ndarray:
    """(P, 2) pixel offsets (dx, dy) of the True cells of a (SIZE, SIZE) mask."""
    r = union.shape[0] // 2
    iy, ix = np.nonzero(union)
    return np.stack([ix - r, iy - r], axis=1).astype(float)


def jacobian(optics: Optics, geometry: dict, A, B, offsets, blur_unknown: bool = True,
             spread: EdgeSpread | None = None):
    """(J (N, P, 4 or 5), M (N, P)): d m / d (rho, phi, A, B[, lambda]) and the unit means."""
    spread = spread or EdgeSpread(optics)
    n = geometry["rho"].size
    A = np.broadcast_to(np.asarray(A, float), (n,))[:, None]
    B = np.broadcast_to(np.asarray(B, float), (n,))[:, None]
    rho, phi = geometry["rho"], geometry["phi"]
    M = unit_means(spread, geometry, offsets)
    cols = [B * (unit_means(spread, geometry, offsets, rho=rho + _H_RHO)
                 - unit_means(spread, geometry, offsets, rho=rho - _H_RHO)) / (2 * _H_RHO),
            B * (unit_means(spread, geometry, offsets, phi=phi + _H_PHI)
                 - unit_means(spread, geometry, offsets, phi=phi - _H_PHI)) / (2 * _H_PHI),
            np.ones_like(M), M]
    if blur_unknown:
        up = EdgeSpread(optics, spread.scale * (1 + _H_SCALE), spread.fft_len, spread.angle_step_deg)
        dn = EdgeSpread(optics, spread.scale * (1 - _H_SCALE), spread.fft_len, spread.angle_step_deg)
        cols.append(B * (unit_means(up, geometry, offsets) - unit_means(dn, geometry, offsets)) / (2 * _H_SCALE))
    return np.stack(cols, axis=-1), M


def footprint_bounds(optics: Optics, geometry: dict, A, B, masks: dict, noise_var=None, variance_fn=None,
                     extra_var=0.0, background=0.0, blur_unknown: bool = True,
                     spread: EdgeSpread | None = None) -> dict:
    """The per-point bound (px) of each footprint in ``masks`` (name -> (N, SIZE, SIZE) bool) under
    ``optics``: Gaussian noise ``noise_var`` (gray levels², scalar or per point) or ``variance_fn``
    (the pixel means (N, P) -> variances, e.g. the EMVA sensor model), plus ``extra_var``
    (Monte-Carlo noise, scalar or (N, 1)).  ``blur_unknown``: the PSF's scale is a nuisance.
    Masks that are equal share one Fisher computation."""
    if not masks:
        return {}
    names = list(masks)
    unique, key_of = [], {}
    seen = {}
    for name in names:
        m = np.ascontiguousarray(masks[name], bool)
        key = (m.shape, m.tobytes())
        if key not in seen:
            seen[key] = len(unique)
            unique.append(m)
        key_of[name] = seen[key]
    stack = np.stack(unique)
    union = stack.any(axis=(0, 1))
    off = offsets_of(union)
    ui = np.nonzero(union.ravel())[0]
    n = stack.shape[1]
    mu = np.ascontiguousarray(stack.reshape(len(unique), n, -1)[:, :, ui])
    use = mu.any(axis=0)
    spread = spread or EdgeSpread(optics)
    derivs = means_and_derivatives(spread, geometry, off, use)
    bounds = bounds_from_derivatives(derivs, A, B, mu, noise_var, variance_fn, extra_var, background, blur_unknown)
    return {name: bounds[key_of[name]] for name in names}


def bounds_from_derivatives(derivs, A, B, masks_on_offsets: np.ndarray, noise_var=None, variance_fn=None,
                            extra_var=0.0, background=0.0, blur_unknown: bool = True) -> list:
    """The bounds (one (N,) array per mask) from ``means_and_derivatives``' output and masks
    (U, N, P) over the same offsets."""
    M, Jr, Jp, Jl = derivs
    mu = np.ascontiguousarray(masks_on_offsets, bool)
    n = M.shape[0]
    use = mu.any(axis=0)
    Av = np.broadcast_to(np.asarray(A, float).reshape(-1), (n,))[:, None]
    Bv = np.ascontiguousarray(np.broadcast_to(np.asarray(B, float).reshape(-1), (n,)))
    mean = Av + Bv[:, None] * M + background
    if variance_fn is not None:
        var = np.asarray(variance_fn(mean), float)
    else:
        var = np.broadcast_to(np.asarray(noise_var, float).reshape(-1, 1), M.shape)
    w = np.ascontiguousarray(np.where(use, 1.0 / (var + extra_var), 0.0))
    npar = 5 if blur_unknown else 4
    F = np.zeros((mu.shape[0], n, npar, npar))
    if n:
        _fisher_kernel(Jr, Jp, Jl, M, Bv, w, mu, npar, F)
    return list(rho_bound(F)) if n else [np.zeros(0) for _ in range(mu.shape[0])]


def emva_variance(gain_dn_per_e: float, dark_noise_e: float, offset_dn: float = 0.0):
    """variance_fn of the EMVA 1288 model: K² σd² + K (μ_DN − offset) + 1/12 (DN²)."""
    K = float(gain_dn_per_e)

    def fn(mean_dn):
        return K * K * dark_noise_e ** 2 + K * np.maximum(np.asarray(mean_dn, float) - offset_dn, 0.0) + 1.0 / 12.0
    return fn
