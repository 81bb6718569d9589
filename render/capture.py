"""One image from its rendered radiance: sensor exposure, saturation check, pipeline, and what the
JSON says about them.

The saturated fraction is counted over the *lit* pixels (board, targets, checkerboard plate:
radiance > 0; the black background behind a checkerboard plate does not count) and over the
whole frame.  Above ``SATURATION_WARN_FRACTION`` of the lit pixels a one-line warning goes to
stderr: a saturated edge has lost its profile.
"""
from __future__ import annotations

import numpy as np

from edgetruth import console
from edgetruth.render import pipeline

SATURATION_WARN_FRACTION = 1e-3


def predicted_saturated_fraction(radiance: np.ndarray, camera, sensor) -> float:
    """Expected saturated fraction of the lit pixels, from noise-free radiance (Gaussian
    approximation of the DN distribution, K²(σd² + μe) + 1/12, and the full-well clip)."""
    from scipy.special import ndtr

    mean_e = sensor.mean_electrons(radiance, camera.f_number, camera.pitch_um)
    lit = np.asarray(radiance) > 0
    dn = sensor.gain_dn_per_e * mean_e + sensor.dark_offset_dn
    p = ndtr((dn - (sensor.max_dn - 0.5)) / np.sqrt(sensor.predicted_variance_dn2(mean_e)))
    p = np.maximum(p, ndtr((mean_e - sensor.full_well_e) / np.sqrt(np.maximum(mean_e, 1.0))))
    return float(p[lit].mean()) if lit.any() else 0.0


def capture(radiance: np.ndarray, camera, sensor, rng: np.random.Generator, name: str = "image"):
    """(image file pixels, ground-truth dict) from the radiance of one render."""
    mean_e = sensor.mean_electrons(radiance, camera.f_number, camera.pitch_um)
    raw, saturated = sensor.expose_clipped(mean_e, rng)
    lit = np.asarray(radiance) > 0
    frac_lit = float(saturated[lit].mean()) if lit.any() else 0.0
    if frac_lit > SATURATION_WARN_FRACTION:
        console.warn(f"{name}: {100 * frac_lit:.2f} % of the lit pixels saturate (limit "
                     f"{100 * SATURATION_WARN_FRACTION:.1f} %); lower irradiance_w_m2, exposure_s or gain_db")
    image = pipeline.develop(raw, sensor)
    truth = {
        "image": pipeline.describe(sensor),
        "saturation": {"fraction_lit": frac_lit, "fraction_all": float(saturated.mean()),
                       "lit_fraction": float(lit.mean()),
                       "meaning": "pixels whose electrons reached the full well or whose DN reached full scale; "
                                  "lit = radiance > 0 (board, targets, checkerboard plate)",
                       "warn_above": SATURATION_WARN_FRACTION},
        "mean_electrons_lit": {"p1": float(np.percentile(mean_e[lit], 1)) if lit.any() else 0.0,
                               "p99": float(np.percentile(mean_e[lit], 99)) if lit.any() else 0.0},
    }
    return image, truth
