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
ψ in 0.25° steps over [0, 90°] (T depends on |cos ψ|, |sin ψ| only) and interpolated: cubic
Hermite in d, linear in ψ.  The PSF may be scaled by λ (blur scale): OTF_psf(λν).

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

import numpy as np
from scipy.special import ndtr

from edgetruth.evaluate.crb import bound_from_fisher
from edgetruth.render import mtf

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
    """Tabulated P_ψ(d) and P'_ψ(d) of box ⊗ PSF (scale λ), built per angle bin when first needed."""

    optics: Optics
    scale: float = 1.0
    fft_len: int = FFT_LEN
    _tables: dict = field(default_factory=dict, repr=False)

    def __post_init__(self):
        n = self.fft_len
        self._nu = np.fft.rfftfreq(n, d=GRID_STEP_PX)
        self._k = int(round(TABLE_HALF_PX / GRID_STEP_PX))
        self.d = np.arange(-self._k, self._k + 1) * GRID_STEP_PX
        self._sr = self.optics.reference_sigma() * self.scale

    def _table(self, j: int):
        t = self._tables.get(j)
        if t is not None:
            return t
        psi = math.radians(j * ANGLE_STEP_DEG)
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

    def value(self, d, psi):
        """(P, dP/dd) at signed distances d and local normal directions psi (arrays, same shape)."""
        d = np.asarray(d, float)
        a = np.abs(np.arctan2(np.abs(np.sin(psi)), np.abs(np.cos(psi))))  # fold to [0, pi/2]
        x = np.degrees(a) / ANGLE_STEP_DEG
        j0 = np.clip(np.floor(x).astype(np.int64), 0, int(round(90 / ANGLE_STEP_DEG)) - 1)
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
        up = EdgeSpread(optics, spread.scale * (1 + _H_SCALE), spread.fft_len)
        dn = EdgeSpread(optics, spread.scale * (1 - _H_SCALE), spread.fft_len)
        cols.append(B * (unit_means(up, geometry, offsets) - unit_means(dn, geometry, offsets)) / (2 * _H_SCALE))
    return np.stack(cols, axis=-1), M


def footprint_bounds(optics: Optics, geometry: dict, A, B, masks: dict, noise_var=None, variance_fn=None,
                     extra_var=0.0, background=0.0, blur_unknown: bool = True,
                     spread: EdgeSpread | None = None) -> dict:
    """The per-point bound (px) of each footprint in ``masks`` (name -> (N, SIZE, SIZE) bool) under
    ``optics``: Gaussian noise ``noise_var`` (gray levels², scalar or per point) or ``variance_fn``
    (the pixel means (N, P) -> variances, e.g. the EMVA sensor model), plus ``extra_var``
    (Monte-Carlo noise, scalar or (N, 1)).  ``blur_unknown``: the PSF's scale is a nuisance."""
    if not masks:
        return {}
    stack = np.stack([np.asarray(m, bool) for m in masks.values()])
    union = stack.any(axis=(0, 1))
    off = offsets_of(union)
    ui = np.nonzero(union.ravel())[0]
    J, M = jacobian(optics, geometry, A, B, off, blur_unknown, spread)
    n = M.shape[0]
    mean = np.asarray(A, float).reshape(-1, 1) + np.asarray(B, float).reshape(-1, 1) * M + background
    if variance_fn is not None:
        var = np.asarray(variance_fn(mean), float)
    else:
        var = np.broadcast_to(np.asarray(noise_var, float).reshape(-1, 1), M.shape)
    w = 1.0 / (var + extra_var)
    out = {}
    for name, m in zip(masks, stack):
        wm = w * m.reshape(n, -1)[:, ui]
        F = np.einsum("np,npk,npl->nkl", wm, J, J)
        out[name] = bound_from_fisher(F)
    return out


def emva_variance(gain_dn_per_e: float, dark_noise_e: float, offset_dn: float = 0.0):
    """variance_fn of the EMVA 1288 model: K² σd² + K (μ_DN − offset) + 1/12 (DN²)."""
    K = float(gain_dn_per_e)

    def fn(mean_dn):
        return K * K * dark_noise_e ** 2 + K * np.maximum(np.asarray(mean_dn, float) - offset_dn, 0.0) + 1.0 / 12.0
    return fn
