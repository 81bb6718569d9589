"""The twin's error budget (``evaluate/board/twin/budget.py``): one scene per rendered term with only that term off,
and shares that add in quadrature."""
from __future__ import annotations

import math

import numpy as np
import pytest

from edgetruth.evaluate.board.twin import budget as B
from edgetruth.render.dataset.spec import load_spec


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    out = tmp_path_factory.mktemp("budget")
    return B.term_scenes("opencv_left_twin_bent", out), load_spec("opencv_left_twin_bent")


def test_each_term_the_twin_renders_gets_a_scene_and_the_floor_has_them_all_off(scenes):
    """OpenCV's bent twin renders noise, JPEG, a clipped white, the boards' curl and lens shading (no FPN and no
    sharpening: its photos overshoot < 3 %): one scene each, and the all-off scene."""
    paths, _ = scenes
    assert list(paths) == ["noise", "jpeg", "clip", "bend", "lens_shading", B.ALL_OFF]


def test_a_term_off_changes_that_term_only(scenes):
    """Each scene loads as a spec with the same name, so the same seeds and poses; only its term differs."""
    paths, base = scenes
    for name, path in paths.items():
        spec = load_spec(path)
        assert spec.name == base.name and spec.n_images == base.n_images
        for a, b in zip(spec.jobs, base.jobs):
            assert (a.seed, a.render_seed, a.pose, a.irradiance_w_m2) == (b.seed, b.render_seed, b.pose,
                                                                           b.irradiance_w_m2)
            off = {name} if name != B.ALL_OFF else set(paths) - {B.ALL_OFF}
            assert (a.sensor.shot_noise, a.sensor.dark_noise_e, a.sensor.output_noise_dn) == (
                (False, 0.0, 0.0) if "noise" in off else (True, b.sensor.dark_noise_e, b.sensor.output_noise_dn))
            assert a.sensor.output == ("srgb8" if "jpeg" in off else b.sensor.output)
            assert a.sensor.output_clip_dn == (255.0 if "clip" in off else b.sensor.output_clip_dn)
            assert (a.board_bend_mm is None) == ("bend" in off or b.board_bend_mm is None)
        cam = spec.camera
        assert (cam.shading_a2, cam.shading_a4) == ((0.0, 0.0) if name in ("lens_shading", B.ALL_OFF)
                                                    else (base.camera.shading_a2, base.camera.shading_a4))
        same = {"shading_a2", "shading_a4", "name"}  # the copy's camera file is named camera.toml
        assert {k: v for k, v in vars(cam).items() if k not in same} == \
            {k: v for k, v in vars(base.camera).items() if k not in same}


def test_a_term_absent_from_the_scene_gets_none():
    """Zhang's twin has no JPEG and no bend: asking for them gives no scene."""
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as d:
        assert B.term_scenes("zhang1998_twin", Path(d), names=["jpeg", "bend"]) == {}


def test_seed_copies_are_the_twin_under_other_names_so_other_seeds_and_the_same_poses(tmp_path):
    paths = B.term_scenes("opencv_left_twin", tmp_path, names=[], seeds=3)
    assert list(paths) == ["seed2", "seed3"]
    base = load_spec("opencv_left_twin")
    for k, path in enumerate(paths.values(), start=2):
        spec = load_spec(path)
        assert spec.name == f"opencv_left_twin_seed{k}"
        for a, b in zip(spec.jobs, base.jobs):
            assert a.pose == b.pose and a.sensor == b.sensor and a.render_seed != b.render_seed


def test_the_seed_row_gives_the_range_and_whether_the_photos_lie_inside_it():
    real = _summ(a=(0.06, 0.2))
    twin = _summ(a=(0.05, 0.1))
    off = {"seed2": _summ(a=(0.07, 0.11)), "seed3": _summ(a=(0.055, 0.12))}
    row = next(r for r in B.budget_rows(real, twin, off, ["a"]) if r["term"] == "seeds")
    assert row["range_straightness_px"] == [0.05, 0.07] and row["real_inside_straightness_px"] is True
    assert row["range_calib_rms_px"] == [0.1, 0.12] and row["real_inside_calib_rms_px"] is False


def _summ(**per_method):
    return {m: {"straightness_px": s, "calib_rms_px": c} for m, (s, c) in per_method.items()}


def test_independent_terms_add_up_in_quadrature():
    """A twin of 0.05 px whose two terms are 0.03 and 0.04 px on a floor of 0: the shares are 0.03 and 0.04, the
    floor's share 0.05, the interaction 0; photos of 0.13 px leave 0.12 unexplained (5-12-13)."""
    real = _summ(a=(0.13, 0.13))
    twin = _summ(a=(0.05, 0.05))
    off = {"noise": _summ(a=(0.04, 0.04)), "jpeg": _summ(a=(0.03, 0.03)), B.ALL_OFF: _summ(a=(0.0, 0.0))}
    rows = {r["term"]: r for r in B.budget_rows(real, twin, off, ["a"])}
    for k in B.FIGURES:
        assert rows["noise"][f"share_{k}"] == pytest.approx(0.03, abs=1e-12)
        assert rows["jpeg"][f"share_{k}"] == pytest.approx(0.04, abs=1e-12)
        assert rows[B.ALL_OFF][f"share_{k}"] == pytest.approx(0.05, abs=1e-12)
        assert rows["interaction"][f"share_{k}"] == pytest.approx(0.0, abs=1e-9)
        assert rows["unexplained"][f"share_{k}"] == pytest.approx(0.12, abs=1e-12)
        assert rows["all"][f"ratio_{k}"] == pytest.approx(0.05 / 0.13)


def test_a_term_whose_removal_raises_the_figure_has_a_negative_share_and_the_median_is_over_methods():
    real = _summ(a=(0.1, 0.2), b=(0.3, 0.4), c=(0.5, 0.6))
    twin = _summ(a=(0.1, 0.1), b=(0.2, 0.2), c=(0.3, 0.3))
    off = {"clip": _summ(a=(0.3, 0.3), b=(0.25, 0.25), c=(0.4, 0.4))}
    rows = {r["term"]: r for r in B.budget_rows(real, twin, off, ["a", "b", "c"])}
    assert rows[""]["straightness_px"] == 0.3 and rows["all"]["calib_rms_px"] == 0.2
    assert rows["clip"]["share_straightness_px"] == pytest.approx(-math.sqrt(0.3 ** 2 - 0.2 ** 2))
    per = B.per_method_rows(real, twin, off, ["a", "b", "c"])
    assert [r["method"] for r in per] == ["a", "b", "c"]
    assert per[0]["share_calib_rms_px"] == pytest.approx(-math.sqrt(0.08))


def test_study_twin_budget_runs_and_writes_its_table(tmp_path):
    """``study twin opencv_left --images 1,2,3 --budget jpeg`` on two methods: the budget's table is in the report,
    its files beside it, and the twin without JPEG is a different image set with the same poses (its points move)."""
    from edgetruth.evaluate.board.twin.study import run_twin_study

    report = run_twin_study("opencv_left", tmp_path, methods=["canny_devernay", "erf4p_fixed11"], images=[1, 2, 3],
                            progress=False, budget=["jpeg"])
    text = report.read_text()
    assert "## Error budget" in text and "twin without JPEG coding" in text
    data = __import__("json").loads((tmp_path / "budget.json").read_text())
    terms = [r["term"] for r in data["rows"]]
    assert terms == ["", "all", "seeds", "jpeg", "unexplained"]
    seeds, jpeg = data["rows"][2], data["rows"][3]
    lo, hi = seeds["range_straightness_px"]
    assert lo <= data["rows"][1]["straightness_px"] <= hi and lo < hi  # other seeds, other noise
    assert np.isfinite(jpeg["straightness_px"]) and jpeg["straightness_px"] != data["rows"][1]["straightness_px"]
    assert (tmp_path / "budget" / "jpeg" / "twin.toml").is_file() and (tmp_path / "budget.csv").is_file()
    # where the photos' calibration residual lives, measured on them (erf4p_fixed11's row), beside the table
    m = data["measured_on_photos"]
    assert m["method"] == "erf4p_fixed11" and m["calib_rms_px"] > 0 and -1.0 < m["print_share"] < 1.0
    assert m["print_px"] == pytest.approx(np.sqrt(max(m["print_share"], 0.0)) * m["calib_rms_px"])
    assert "Measured on the photos, not rendered" in text and "**the print**" in text
