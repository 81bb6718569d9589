"""The shipped scene sweep (albedo x light direction x gloss, 2 x 2 x 2) renders and evaluates: a tiny
version of ``scenes/sweep_albedo_light_gloss.toml`` (the same factors and levels on the default camera binned
8 x 8 (160 x 128 px), 3 pose slots at 60-90 cm, low spp) end to end, and each factor gets its own tables
with paired tests in the report."""
from __future__ import annotations

import json
from pathlib import Path

import pytest



def _tiny_sweep(tmp_path: Path) -> Path:
    from edgetruth.resources import shipped_spec

    text = Path(shipped_spec("sweep_albedo_light_gloss")).read_text()
    for old, new in (("camera_scale = 2", "camera_scale = 8"),
                     ("spp = 16", "spp = 4"), ("edge_spp = 1024", "edge_spp = 64"), ("count = 6", "count = 3"),
                     ("distance_range_cm = [60, 200]", "distance_range_cm = [60, 90]"),
                     # 8 x 8 binned pixels collect 16x the light of the 2 x 2 binned: the same exposure
                     ("irradiance_w_m2 = 0.3", "irradiance_w_m2 = 0.01875")):
        assert old in text, old
        text = text.replace(old, new)
    spec = tmp_path / "sweep.toml"
    spec.write_text(text)
    return spec


def test_sweep_spec_cells_and_units():
    from edgetruth.render.dataset.spec import load_spec

    spec = load_spec("sweep_albedo_light_gloss")
    assert len(spec.groups) == 8 and spec.n_images == 48
    # every cell changes the radiance (material or light): 8 radiance units, none shared
    assert sorted(g.radiance_unit for g in spec.groups) == list(range(8))
    g = spec.group("gray_side_glossy")
    m = g.target.primary.material
    assert (m.type, m.albedo, m.alpha, m.eta) == ("roughplastic", 0.25, 0.15, 1.5)
    assert g.target.lights[0].position_m == (0.8, 0.0, -0.05)
    assert spec.group("black_above_matte").target.primary.material.to_bsdf() == {"type": "diffuse",
                                                                               "reflectance": 0.04}


@pytest.mark.slow
def test_tiny_sweep_renders_and_evaluates(tmp_path, fast_variant):
    from edgetruth.cli import main
    from edgetruth.render import open_dataset
    from edgetruth.render.dataset.driver import render_spec

    data = tmp_path / "data"
    render_spec(_tiny_sweep(tmp_path), data, progress=False, announce=lambda s: None)
    ds = open_dataset(data)
    assert len(ds) == 24
    gt = ds[23].truth
    assert gt["design"]["levels"] == {"albedo": "gray", "light": "side", "gloss": "glossy"}
    assert gt["target"]["material_params"] == {"type": "roughplastic", "albedo": 0.25, "alpha": 0.15, "eta": 1.5,
                                               "label": "rough_plastic"}
    light = gt["illumination"]["lights"][0]
    # the light gives the group's irradiance at the board centre (its aim point), whatever its direction
    assert light["irradiance_board_centre_w_m2"] == pytest.approx(0.01875, rel=1e-9)
    assert gt["illumination"]["board_centre_irradiance_w_m2"] == pytest.approx(0.01875, rel=1e-9)
    cam = gt["camera"]
    cal = tmp_path / "cal.json"
    cal.write_text(json.dumps({"K": cam["K"], "dist_coeffs_opencv": cam["dist_coeffs_opencv"],
                               "image_size": [cam["width_px"], cam["height_px"]]}))
    out = tmp_path / "eval"
    rc = main(["evaluate", str(data), "--calibration", str(cal), "-o", str(out), "-j", "1", "--no-progress",
               "--methods", "canny_devernay,erf4p_fixed11"])
    assert rc == 0
    report = (out / "report.md").read_text()
    for factor, a, b in (("albedo", "black", "gray"), ("light", "above", "side"), ("gloss", "matte", "glossy")):
        head = f"## Factor {factor}: {a} vs {b} (cm"
        assert head in report, factor
        sec = report.split(head, 1)[1].split("\n## ", 1)[0]
        assert f"| {a} |" in sec and f"| {b} |" in sec
        assert "Wilcoxon signed-rank" in sec and "pose slots" in sec
        assert f"## Factor {factor}: {a} vs {b} — per-point RMSE (px)" in report


@pytest.mark.slow
def test_sweep_does_not_saturate(fast_variant):
    """As tests/render/sensor/test_saturation.py for the shipped specs: every 3rd image (and every cell's first),
    noise-free at 1/4 resolution with the spec's photometry: <= 0.1 % of the lit pixels saturate (the gray
    glossy target's sheen under the light above the camera is the brightest cell)."""
    from edgetruth.render.sensor.capture import SATURATION_WARN_FRACTION, predicted_saturated_fraction
    from edgetruth.render.dataset.image import get_rig, job_pose
    from edgetruth.render.scene.ground_truth import view_outline_local
    from edgetruth.render.scene.mitsuba_scene import RenderSettings
    from edgetruth.render.dataset.spec import load_spec

    spec = load_spec("sweep_albedo_light_gloss")
    settings = RenderSettings(spp=16, sampler="multijitter", edge_spp=0)
    worst = (0.0, "")
    for job in spec.jobs:
        if job.index % 3 and job.slot != 0:
            continue
        pose = job_pose(job, job.camera, view_outline_local(job.target, spec.target_size_m, paired=True))
        rig = get_rig("target", job.camera.scaled(4), settings, spec.target_size_m)
        rig.set_state(job.target, pose, job.irradiance_w_m2)
        worst = max(worst, (predicted_saturated_fraction(rig.render(job.seed), job.camera, job.sensor), job.name))
    assert worst[0] <= SATURATION_WARN_FRACTION, worst
