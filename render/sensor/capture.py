"""One image from its rendered radiance: sensor exposure, saturation check, pipeline, and what the
JSON says about them.

The saturated fraction is counted over the *lit* pixels (board, targets, checkerboard plate:
radiance > 0; the black background behind a checkerboard plate does not count) and over the
whole frame.  Above ``SATURATION_WARN_FRACTION`` of the lit pixels a one-line warning goes to
stderr: a saturated edge has lost its profile.  Hot and dead pixels (the sensor's fixed
pattern) are not counted: they are listed under ``fixed_pattern``.

The sensor's fixed-pattern noise is the camera's: its maps cover the camera's frame, and an
image that is a window of it (``crop`` = (x0, y0, width, height), or a smaller image at the
frame's top-left corner) gets that window, so every image of a camera shares one pattern.
"""
from __future__ import annotations

import numpy as np

from edgetruth import console
from edgetruth.render.sensor import pipeline
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


def camera_pattern(sensor, camera, shape: tuple[int, int], crop=None):
    """The sensor's fixed pattern for an image of ``shape``: the ``crop`` window of the camera's frame,
    else the frame's top-left ``shape`` (a pattern of its own when larger); None without FPN."""
    if not sensor.has_fixed_pattern:
        return None
    frame = (int(camera.height_px), int(camera.width_px))
    if crop is None:
        if shape[0] > frame[0] or shape[1] > frame[1]:
            return sensor.fixed_pattern(shape)
        crop = (0, 0, shape[1], shape[0])
    return sensor.fixed_pattern(frame, tuple(int(v) for v in crop))


def saturation_fix(sensor) -> str:
    """What lowers the saturation: with the full well in the ADC's range the well clips first, and the gain cannot
    help; above it the ADC clips first, and the gain can."""
    well_dn = sensor.gain_dn_per_e * sensor.full_well_e + sensor.dark_offset_dn
    if well_dn < sensor.max_dn:
        return (f"lower irradiance_w_m2 or exposure_s (the full well, {sensor.full_well_e:g} e-, clips at "
                f"{well_dn:.0f} of {sensor.max_dn} DN: gain_db does not help)")
    return "lower irradiance_w_m2, exposure_s or gain_db (the ADC clips before the full well)"


def capture(radiance: np.ndarray, camera, sensor, rng: np.random.Generator, name: str = "image", crop=None):
    """(image file pixels, ground-truth dict) from the radiance of one render (``crop``: the
    (x0, y0, width, height) window of the camera's frame it covers, None for the whole frame)."""
    from edgetruth.render.sensor.linear_model import no_fixed_pattern_truth

    mean_e = sensor.mean_electrons(radiance, camera.f_number, camera.pitch_um)
    pattern = camera_pattern(sensor, camera, mean_e.shape, crop)
    raw, saturated = sensor.expose_clipped(mean_e, rng, pattern)
    if pattern is not None and pattern.defects is not None:
        saturated &= ~pattern.defects
    lit = np.asarray(radiance) > 0
    frac_lit = float(saturated[lit].mean()) if lit.any() else 0.0
    if frac_lit > SATURATION_WARN_FRACTION:
        console.warn(f"{name}: {100 * frac_lit:.2f} % of the lit pixels saturate (limit "
                     f"{100 * SATURATION_WARN_FRACTION:.1f} %); {saturation_fix(sensor)}")
    image = pipeline.develop(raw, sensor, rng)  # rng: only output_noise_dn draws from it, after the exposure
    truth = {
        "image": pipeline.describe(sensor),
        "saturation": {"fraction_lit": frac_lit, "fraction_all": float(saturated.mean()),
                       "lit_fraction": float(lit.mean()),
                       "meaning": "pixels whose electrons reached the full well or whose DN reached full scale; "
                                  "lit = radiance > 0 (board, targets, checkerboard plate); hot and dead "
                                  "pixels (fixed_pattern) not counted",
                       "warn_above": SATURATION_WARN_FRACTION},
        "mean_electrons_lit": {"p1": float(np.percentile(mean_e[lit], 1)) if lit.any() else 0.0,
                               "p99": float(np.percentile(mean_e[lit], 99)) if lit.any() else 0.0},
        "fixed_pattern": no_fixed_pattern_truth(sensor) if pattern is None else pattern.truth(sensor),
    }
    return image, truth
