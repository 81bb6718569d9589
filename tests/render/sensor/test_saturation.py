"""Saturation: recorded per image, warned about above 0.1 % of the lit pixels, and absent from
every shipped spec."""
from __future__ import annotations

import numpy as np
import pytest

from edgetruth.render.optics.camera import load_camera
from edgetruth.render.sensor.capture import SATURATION_WARN_FRACTION, capture, predicted_saturated_fraction
from edgetruth.render.sensor.linear_model import SensorModel, make_rng


def test_saturated_fraction_is_recorded_and_warned_about(capsys):
    cam, s = load_camera(), SensorModel()
    full_scale = (s.max_dn - s.dark_offset_dn) / s.gain_dn_per_e / s.qe / s.photons_per_radiance(4.0, 4.8)
    radiance = np.full((100, 100), 0.5 * full_scale)
    radiance[:, :30] = 0.0  # unlit background does not count
    radiance[0, 30:37] = 3 * full_scale  # 7 of 7000 lit pixels: exactly 0.1 %, no warning
    _, truth = capture(radiance, cam, s, make_rng(1, 2), name="img")
    assert truth["saturation"]["fraction_lit"] == pytest.approx(7 / 7000)
    assert truth["saturation"]["fraction_all"] == pytest.approx(7 / 10000)
    assert capsys.readouterr().err == ""
    radiance[1, 30:40] = 3 * full_scale
    _, truth = capture(radiance, cam, s, make_rng(1, 2), name="img")
    err = capsys.readouterr().err
    assert truth["saturation"]["fraction_lit"] > SATURATION_WARN_FRACTION
    assert err.count("\n") == 1 and err.startswith("warning: img: 0.24 % of the lit pixels saturate")
    assert predicted_saturated_fraction(radiance, cam, s) == pytest.approx(17 / 7000, abs=1e-6)


def test_the_warning_names_what_lowers_the_saturation():
    """Where the full well maps inside the ADC's range the well clips first and only less light helps (a user at
    gain_db = -12 was told to lower the gain); where it maps beyond full scale the ADC clips first and the gain
    helps too.  Both against the sensor's own DN of a full well."""
    from dataclasses import replace

    from edgetruth.render.sensor.capture import saturation_fix

    s = SensorModel()
    low = replace(s, gain_db=-12.0)
    assert low.gain_dn_per_e * low.full_well_e + low.dark_offset_dn < low.max_dn
    assert "gain_db does not help" in saturation_fix(low) and "full well" in saturation_fix(low)
    high = replace(s, gain_db=12.0)
    assert high.gain_dn_per_e * high.full_well_e + high.dark_offset_dn > high.max_dn
    assert saturation_fix(high) == "lower irradiance_w_m2, exposure_s or gain_db (the ADC clips before the full well)"


@pytest.mark.slow
@pytest.mark.parametrize("spec_name", ["quick", "calibration", "study"])
def test_no_shipped_spec_saturates(spec_name, fast_variant):
    """Every 3rd image of each shipped spec (and the first and last of each group), rendered
    noise-free at 1/4 resolution (radiance does not depend on the pixel size) and exposed with the
    spec's full-resolution photometry: expected saturated fraction of the lit pixels <= 0.1 %."""
    from edgetruth.render.dataset.image import get_rig, job_pose
    from edgetruth.render.scene.ground_truth import target_outline_local
    from edgetruth.render.scene.mitsuba_scene import RenderSettings
    from edgetruth.render.dataset.spec import load_spec
    from edgetruth.render.scene.targets import TARGETS

    spec = load_spec(spec_name)
    settings = RenderSettings(spp=16, sampler="multijitter", edge_spp=0)
    picks = {g.first_index for g in spec.groups} | {g.first_index + g.count - 1 for g in spec.groups}
    worst = (0.0, "")
    for job in spec.jobs:
        if job.index % 3 and job.index not in picks:
            continue
        cam = job.camera.scaled(4)
        if job.kind == "target":
            pose = job_pose(job, job.camera, target_outline_local(TARGETS[job.target]["shape"], spec.target_size_m))
            rig = get_rig("target", cam, settings, spec.target_size_m)
            rig.set_state(job.target, pose, job.irradiance_w_m2)
        else:
            pose = job_pose(job, job.camera, spec.checkerboard.plate_corners_local())
            rig = get_rig("checkerboard", cam, settings, spec.checkerboard)
            rig.set_state(pose, job.irradiance_w_m2)
        frac = predicted_saturated_fraction(rig.render(job.seed), job.camera, job.sensor)
        worst = max(worst, (frac, job.name))
    print(f"{spec_name}: worst expected saturated fraction {100 * worst[0]:.4f} % ({worst[1]})")
    assert worst[0] <= SATURATION_WARN_FRACTION
