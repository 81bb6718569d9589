"""Analytic modulation transfer functions of the camera's optics (the prediction the JSON records).

Frequencies are in cycles per pixel along a direction (ν, or its components νx, νy on the
pixel axes); lengths in pixels unless a name says ``_um``.  The factors (BRIEF §7):

- pixel aperture, 100 % fill factor:    sinc(νx) · sinc(νy)          (sinc(x) = sin(πx)/(πx))
- diffraction of a circular aperture:   (2/π)(acos q − q√(1 − q²)), q = |ν|/νc, νc = p/(λN)
- Gaussian aberration σ:                exp(−2π²σ²|ν|²)
- defocus disk of radius r:             2 J1(2πr|ν|) / (2πr|ν|)
- 4-dot birefringent low-pass filter:   cos(πνx d) · cos(πνy d)      (dots at (±d/2, ±d/2))
- linear motion of length L along m:    sinc(L ν·m)

The system OTF is their product (the shift-invariant part at one field height).  Signed values
are OTFs (the defocus disk, the OLPF and the sinc change sign); the MTF is the modulus.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import brentq
from scipy.special import j1


def pixel_otf(nu_x, nu_y):
    return np.sinc(nu_x) * np.sinc(nu_y)


def diffraction_mtf(nu, cutoff_cy_px: float):
    """Incoherent MTF of an aberration-free circular pupil; ``cutoff_cy_px`` = p/(λN)."""
    if not np.isfinite(cutoff_cy_px):
        return np.ones_like(np.asarray(nu, float))
    q = np.clip(np.abs(np.asarray(nu, float)) / cutoff_cy_px, 0.0, 1.0)
    return (2.0 / np.pi) * (np.arccos(q) - q * np.sqrt(1.0 - q * q))


def diffraction_cutoff_cy_px(pitch_um: float, wavelength_nm: float, f_number: float) -> float:
    """νc = p / (λ N) in cycles per pixel (inf without diffraction)."""
    if wavelength_nm <= 0 or f_number <= 0:
        return float("inf")
    return pitch_um / (wavelength_nm * 1e-3 * f_number)


def gaussian_mtf(nu, sigma_px: float):
    nu = np.asarray(nu, float)
    return np.exp(-2.0 * np.pi ** 2 * sigma_px ** 2 * nu * nu)


def defocus_otf(nu, radius_px: float):
    """OTF of a uniform disk of radius ``radius_px`` (geometric defocus)."""
    x = 2.0 * np.pi * radius_px * np.abs(np.asarray(nu, float))
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(x < 1e-8, 1.0 - x * x / 8.0, 2.0 * j1(x) / np.where(x < 1e-8, 1.0, x))
    return out


def olpf_otf(nu_x, nu_y, split_px: float):
    return np.cos(np.pi * np.asarray(nu_x, float) * split_px) * np.cos(np.pi * np.asarray(nu_y, float) * split_px)


def motion_otf(nu_along, length_px: float):
    return np.sinc(length_px * np.asarray(nu_along, float))


def system_otf(nu, angle_rad: float = 0.0, *, cutoff_cy_px: float = float("inf"), sigma_px: float = 0.0,
               defocus_px: float = 0.0, olpf_px: float = 0.0, pixel: bool = True):
    """OTF along the direction ``angle_rad`` (from the image x axis) at frequencies ``nu`` (cy/px)."""
    nu = np.asarray(nu, float)
    nx, ny = nu * np.cos(angle_rad), nu * np.sin(angle_rad)
    out = diffraction_mtf(nu, cutoff_cy_px) * gaussian_mtf(nu, sigma_px) * defocus_otf(nu, defocus_px)
    if pixel:
        out = out * pixel_otf(nx, ny)
    if olpf_px:
        out = out * olpf_otf(nx, ny, olpf_px)
    return out


def mtf50(otf_of_nu, nu_max: float = 2.0) -> float:
    """The lowest frequency where |OTF| falls to 0.5 (cy/px); nan if it never does below ``nu_max``."""
    grid = np.linspace(0.0, nu_max, 4001)
    m = np.abs(otf_of_nu(grid))
    below = np.nonzero(m <= 0.5)[0]
    if not len(below):
        return float("nan")
    i = below[0]
    return float(brentq(lambda v: abs(float(otf_of_nu(np.array([v]))[0])) - 0.5, grid[i - 1], grid[i],
                        xtol=1e-10))
