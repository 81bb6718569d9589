"""What a camera's optics predict: MTF (and MTF50) at a field height, relative illumination.

The renderer samples the same model (``edgetruth.render.optics.psf`` for the PSF, the sensor plugin
for the falloff); these are the closed forms recorded in every ground-truth JSON.
Field height h is the distance from the principal point divided by the half-diagonal
(0 at the centre, 1 at the image corner).
"""
from __future__ import annotations

import math

import numpy as np

from edgetruth.render.optics import mtf
from edgetruth.render.optics.psf import psf_params


def field_height(camera, x_px, y_px):
    """Normalised field height of OpenCV pixel positions."""
    cx, cy = camera.principal_point_px
    return np.hypot(np.asarray(x_px, float) - cx, np.asarray(y_px, float) - cy) / camera.half_diagonal_px


def system_otf(camera, nu, angle_rad: float = 0.0, field_h: float = 0.0, defocus_px: float = 0.0):
    """OTF of pixel ⊗ PSF ⊗ defocus along ``angle_rad`` (cy/px) at field height ``field_h``."""
    p = psf_params(camera)
    return mtf.system_otf(nu, angle_rad, cutoff_cy_px=p.cutoff_cy_px, sigma_px=p.sigma_at(field_h),
                          defocus_px=defocus_px, olpf_px=p.olpf_px)


def predicted_mtf50(camera, field_h: float = 0.0, defocus_px: float = 0.0, angle_rad: float = 0.0) -> float:
    """MTF50 (cy/px) of the analytic system MTF: in focus unless ``defocus_px`` is given."""
    return mtf.mtf50(lambda nu: system_otf(camera, nu, angle_rad, field_h, defocus_px))


def relative_illumination(camera, x_px, y_px):
    """Exact relative illumination of the thin lens at pixel positions (1 at the centre).

    A disk aperture of radius R at distance f seen from a sensor point at distance b off axis has
    the projected solid angle Ω = (π/2)(1 − (f² + b² − R²) / √((f² + b² + R²)² − 4R²b²)) (the
    configuration factor of a parallel disk); cos⁴θ is its small-aperture limit.  Times the
    lens-shading polynomial.
    """
    h = field_height(camera, x_px, y_px)
    out = np.ones_like(h)
    if camera.natural_vignetting:
        b = h * camera.half_diagonal_px / camera.fx_px  # in units of f
        r = camera.aperture_radius_m / camera.focal_length_m

        def omega(b):
            if r == 0:
                return 1.0 / (1.0 + b * b) ** 2
            return 0.5 * (1.0 - (1.0 + b * b - r * r) / np.sqrt((1.0 + b * b + r * r) ** 2 - 4.0 * r * r * b * b))

        out = omega(b) / omega(0.0)
    return out * np.maximum(0.0, 1.0 + camera.shading_a2 * h ** 2 + camera.shading_a4 * h ** 4)


def optics_ground_truth(camera) -> dict:
    """The optics block of the JSON: every parameter and the predicted in-focus MTF50s."""
    p = psf_params(camera)
    out = {
        "psf": {
            "diffraction_wavelength_nm": camera.diffraction_wavelength_nm,
            "diffraction_cutoff_cy_px": p.cutoff_cy_px if math.isfinite(p.cutoff_cy_px) else None,
            "aberration_sigma_um": camera.aberration_sigma_um,
            "aberration_sigma_growth": camera.aberration_sigma_growth,
            "aberration_sigma_px_centre": p.sigma_at(0.0),
            "aberration_sigma_px_corner": p.sigma_at(1.0),
            "olpf_split_um": camera.olpf_split_um,
            "model": "box (x) Airy(lambda, N) (x) Gaussian sigma(h) = sigma (1 + g h^2) (x) 4-dot OLPF, "
                     "h = field height / half-diagonal; convolved with the irradiance before the pixel integrates it",
        },
        "mtf50_centre_cy_px": predicted_mtf50(camera, 0.0),
        "mtf50_corner_cy_px": predicted_mtf50(camera, 1.0),
        "mtf50_meaning": "analytic in-focus system MTF (pixel x PSF) along the image x axis",
        "relative_illumination": {
            "natural_vignetting": camera.natural_vignetting,
            "shading_a2": camera.shading_a2, "shading_a4": camera.shading_a4,
            "corner": float(relative_illumination(camera, np.array([-0.5]), np.array([-0.5]))[0]),
            "model": "exact thin-lens falloff (projected solid angle of the aperture disk; cos^4 for a small "
                     "aperture) x (1 + a2 h^2 + a4 h^4)",
        },
        "motion": {"velocity_m_s": list(camera.velocity_m_s),
                   "angular_velocity_deg_s": list(camera.angular_velocity_deg_s)},
    }
    return out
