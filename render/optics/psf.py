"""The lens point-spread function as the renderer samples it: the pixel box convolved with the PSF.

A pixel's value is ∫ K(z) E(c + z) dz: the irradiance E convolved with the PSF and integrated
over the pixel, i.e. the kernel K = box ⊗ PSF around the pixel centre c.  The sensor plugin
draws z ~ K by warping the pixel's own stratified film sample through K's inverse CDF
(marginal in y, conditional in x; Mitsuba's ``MarginalContinuous2D1``), so that

- the film still files the sample under its own pixel (box filter) while the ray goes
  through c + z: the PSF convolves the irradiance *before* the pixel integrates it;
- no extra random dimension is needed (the aperture, time and wavelength samples stay free
  for defocus and motion), the sample keeps its stratification, and renders stay a pure
  function of the seed.

K is tabulated on a square grid of vertices (bilinear density, sampled exactly by the
warp), built in the frequency domain from the analytic OTF (``edgetruth.render.optics.mtf``):

    K̂(νx, νy) = sinc(νx) sinc(νy) · D(ν) · G_σ(ν) · OLPF(νx, νy)

pre-divided by the bilinear interpolation's own transfer sinc²(νx h) sinc²(νy h), so the
interpolated table reproduces K̂ in the base band.  The grid step h keeps K̂ band-limited
below the grid's Nyquist frequency 1/(2h) (diffraction cuts off at νc = p/(λN)); the table
reaches R (a round support) with R holding all but ``AIRY_TAIL_LOSS`` of the Airy pattern's
energy (its tail falls as 2λN/(π²r)) and 6σ of the Gaussian; the truncated kernel is
renormalised.

A field-dependent Gaussian σ(h) = σ0 (1 + g h²) (h: field height / half-diagonal) is
tabulated at ``FIELD_LEVELS`` values of h² (σ is linear in h², so the warp's linear mixing of
neighbouring levels follows σ closely).

The Gaussian may be anisotropic (``sigma_y_px``: σ along the image y axis, σ0 along x; both grow
with the field alike): G(νx, νy) = exp(−2π²(σx² νx² + σy² νy²)), an elliptical Gaussian with its
axes on the pixel axes (e.g. a video camera whose lines blur more than its columns).  The table is
built from the same 2-D OTF, so the warp samples it exactly as the isotropic one.  Without
``sigma_y_px`` (None) the isotropic code path runs unchanged (the same table to the last bit).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from edgetruth.render.optics import mtf
AIRY_TAIL_LOSS = 0.01  # fraction of the Airy energy left outside the table (renormalised)
GAUSS_SIGMAS = 6.0
FIELD_LEVELS = 9
MAX_VERTICES = 1025  # per side
NEGLIGIBLE = 1e-4  # a PSF whose OTF departs from 1 by less than this up to Nyquist is not sampled


@dataclass(frozen=True)
class PsfParams:
    """The PSF of a camera in pixels: diffraction cutoff, Gaussian σ(h), OLPF split."""

    cutoff_cy_px: float  # inf: no diffraction
    sigma_px: float  # at the image centre (along x when ``sigma_y_px`` is given)
    sigma_growth: float  # σ(h) = σ0 (1 + g h²)
    olpf_px: float
    sigma_y_px: float | None = None  # an anisotropic Gaussian: σ along y at the centre; None: isotropic

    def sigma_at(self, field_height: float) -> float:
        """σ along x (the isotropic σ) at ``field_height``."""
        return self.sigma_px * (1.0 + self.sigma_growth * float(field_height) ** 2)

    def sigma_y_at(self, field_height: float) -> float:
        """σ along y at ``field_height`` (σ along x when isotropic)."""
        s = self.sigma_px if self.sigma_y_px is None else self.sigma_y_px
        return s * (1.0 + self.sigma_growth * float(field_height) ** 2)

    @property
    def anisotropic(self) -> bool:
        return self.sigma_y_px is not None and self.sigma_y_px != self.sigma_px

    @property
    def sigma_max_px(self) -> float:
        return max(self.sigma_px, self.sigma_px if self.sigma_y_px is None else self.sigma_y_px)

    @property
    def sigma_min_px(self) -> float:
        return min(self.sigma_px, self.sigma_px if self.sigma_y_px is None else self.sigma_y_px)

    def sigma_along(self, angle_rad: float, field_height: float = 0.0) -> float:
        """σ of the Gaussian's profile along the direction ``angle_rad`` from the x axis (the 1-D
        section of an elliptical Gaussian's OTF: σ² = σx² cos² + σy² sin²)."""
        sx, sy = self.sigma_at(field_height), self.sigma_y_at(field_height)
        return math.sqrt((sx * math.cos(angle_rad)) ** 2 + (sy * math.sin(angle_rad)) ** 2)

    @property
    def field_dependent(self) -> bool:
        return self.sigma_max_px > 0 and self.sigma_growth != 0

    def gaussian_otf(self, nu_x, nu_y, field_height: float = 0.0):
        """The Gaussian factor alone: isotropic exp(−2π²σ²ν²), or the elliptical one."""
        if not self.anisotropic:
            return mtf.gaussian_mtf(np.hypot(nu_x, nu_y), self.sigma_at(field_height))
        sx, sy = self.sigma_at(field_height), self.sigma_y_at(field_height)
        return np.exp(-2.0 * np.pi ** 2 * ((sx * nu_x) ** 2 + (sy * nu_y) ** 2))

    def otf(self, nu_x, nu_y, field_height: float = 0.0, pixel: bool = True):
        """2-D OTF of box ⊗ PSF (``pixel``) or of the PSF alone."""
        nu_x, nu_y = np.asarray(nu_x, float), np.asarray(nu_y, float)
        nu = np.hypot(nu_x, nu_y)
        if self.anisotropic:
            out = mtf.diffraction_mtf(nu, self.cutoff_cy_px) * self.gaussian_otf(nu_x, nu_y, field_height)
        else:
            out = mtf.diffraction_mtf(nu, self.cutoff_cy_px) * mtf.gaussian_mtf(nu, self.sigma_at(field_height))
        if self.olpf_px:
            out = out * mtf.olpf_otf(nu_x, nu_y, self.olpf_px)
        if pixel:
            out = out * mtf.pixel_otf(nu_x, nu_y)
        return out

    def negligible(self) -> bool:
        """True when the PSF alone stays within ``NEGLIGIBLE`` of 1 up to Nyquist in every direction
        and at every field height (then the pixel box alone is the kernel)."""
        nu = np.linspace(0.0, 0.5 * math.sqrt(2.0), 65)
        for h in (0.0, 1.0):
            for a in np.linspace(0.0, np.pi / 2, 7):
                if np.max(np.abs(1.0 - self.otf(nu * np.cos(a), nu * np.sin(a), h, pixel=False))) > NEGLIGIBLE:
                    return False
        return True


def psf_params(camera) -> PsfParams:
    """The PSF of ``camera`` (``edgetruth.render.optics.camera.Camera``) in its pixel units."""
    p = camera.pitch_um
    sy = getattr(camera, "aberration_sigma_y_um", None)
    return PsfParams(cutoff_cy_px=mtf.diffraction_cutoff_cy_px(p, camera.diffraction_wavelength_nm, camera.f_number),
                     sigma_px=camera.aberration_sigma_um / p, sigma_growth=camera.aberration_sigma_growth,
                     olpf_px=camera.olpf_split_um / p, sigma_y_px=None if sy is None else sy / p)


@dataclass(frozen=True)
class PsfTable:
    """K = box ⊗ PSF on (levels, n, n) vertices spanning [-R, R]² (rows: y), one level per h²."""

    density: np.ndarray
    half_width_px: float
    step_px: float
    field_heights_sq: tuple

    @property
    def n_vertices(self) -> int:
        return int(self.density.shape[-1])

    def describe(self) -> dict:
        return {"method": "film sample warped through the inverse CDF of box (x) PSF (tabulated, bilinear)",
                "vertices_per_side": self.n_vertices, "step_px": self.step_px, "half_width_px": self.half_width_px,
                "field_levels": len(self.field_heights_sq), "airy_tail_loss": AIRY_TAIL_LOSS}


def _band_limit_cy_px(p: PsfParams) -> float:
    """The frequency above which the PSF's OTF stays below 1e-6 in every direction (the table's
    grid must resolve it; inf when nothing limits the band)."""
    s_min = p.sigma_min_px
    if not math.isfinite(p.cutoff_cy_px) and s_min == 0:
        return math.inf
    top = p.cutoff_cy_px if math.isfinite(p.cutoff_cy_px) else 1.1 / s_min
    nu = np.linspace(0.0, top, 2049)
    g = 1.0 + p.sigma_growth  # σ(1) / σ(0)
    env = mtf.diffraction_mtf(nu, p.cutoff_cy_px) * mtf.gaussian_mtf(nu, min(s_min, s_min * g))
    above = np.nonzero(env >= 1e-6)[0]
    return float(nu[min(above[-1] + 1, len(nu) - 1)])


def kernel_radius_px(p: PsfParams) -> float:
    """How far from the pixel centre the tabulated kernel reaches (before rounding to the grid)."""
    sigma_max = max(p.sigma_at(0.0), p.sigma_at(1.0), p.sigma_y_at(0.0), p.sigma_y_at(1.0))
    airy_r = 0.0
    if math.isfinite(p.cutoff_cy_px):
        lam_n_px = 1.0 / p.cutoff_cy_px  # λN in pixels
        airy_r = 2.0 * lam_n_px / (math.pi ** 2 * AIRY_TAIL_LOSS)
    return 0.5 * math.sqrt(2.0) + airy_r + GAUSS_SIGMAS * sigma_max + p.olpf_px * math.sqrt(0.5)


def table_geometry(p: PsfParams) -> tuple[float, int]:
    """(step h, vertices per side n) of the table for ``p``."""
    band = _band_limit_cy_px(p)
    if not math.isfinite(band):
        raise ValueError("a 4-dot OLPF alone is not band-limited: add diffraction or aberration blur")
    h = min(max(1.0 / (2.2 * band), 1.0 / 64.0), 0.25)  # the grid's Nyquist 1/(2h) >= 1.1 x the band limit
    radius = kernel_radius_px(p)
    half = int(math.ceil(radius / h))
    if 2 * half + 1 > MAX_VERTICES:  # coarser grid rather than a truncated kernel
        h = radius / ((MAX_VERTICES - 1) // 2)
        half = (MAX_VERTICES - 1) // 2
    return h, 2 * half + 1


def _kernel_level(p: PsfParams, field_height: float, h: float, n: int) -> np.ndarray:
    """One level of the table: K sampled at the n x n vertices (row-major, y rows), pre-emphasised."""
    from scipy import fft

    m = fft.next_fast_len(4 * (n - 1))  # FFT period >= 4·(2R): the Airy tail beyond the table cannot wrap into it
    nx, ny = np.meshgrid(np.fft.rfftfreq(m, d=h), np.fft.fftfreq(m, d=h))
    spec = p.otf(nx, ny, field_height) / (np.sinc(nx * h) ** 2 * np.sinc(ny * h) ** 2)
    k = fft.irfft2(spec, s=(m, m))
    half = (n - 1) // 2
    idx = np.r_[m - half:m, 0:half + 1]  # vertices -R..R around the origin (index 0)
    k = k[np.ix_(idx, idx)]
    r = np.arange(-half, half + 1) * h
    k[np.hypot(r[None, :], r[:, None]) > half * h] = 0.0  # a round support: the kernel reaches R, not R√2
    return np.clip(k, 0.0, None)


def psf_table(p: PsfParams) -> PsfTable | None:
    """The sampling table for ``p``; None when the PSF is absent or negligible."""
    if not math.isfinite(p.cutoff_cy_px) and p.sigma_max_px == 0 and p.olpf_px == 0:
        return None
    if p.negligible():
        return None
    h, n = table_geometry(p)
    levels = np.linspace(0.0, 1.0, FIELD_LEVELS) if p.field_dependent else np.array([0.0])
    dens = np.stack([_kernel_level(p, math.sqrt(q), h, n) for q in levels]).astype(np.float32)
    return PsfTable(density=dens, half_width_px=h * (n - 1) / 2, step_px=h, field_heights_sq=tuple(levels))


def table_otf_x(table: PsfTable, level: int, nu) -> np.ndarray:
    """OTF along x of the *interpolated* table (what the renderer samples), normalised at 0."""
    return _table_otf(table, level, nu, axis=0)


def table_otf_y(table: PsfTable, level: int, nu) -> np.ndarray:
    """OTF along y of the *interpolated* table, normalised at 0."""
    return _table_otf(table, level, nu, axis=1)


def _table_otf(table: PsfTable, level: int, nu, axis: int) -> np.ndarray:
    d = table.density[level].astype(np.float64)
    marg = d.sum(axis=axis)  # axis 0: the x marginal (vertex weights); axis 1: the y marginal
    n = len(marg)
    x = (np.arange(n) - (n - 1) / 2) * table.step_px
    nu = np.asarray(nu, float)
    dtft = (marg[None, :] * np.cos(2 * np.pi * nu[:, None] * x[None, :])).sum(axis=1)
    return dtft / marg.sum() * np.sinc(nu * table.step_px) ** 2
