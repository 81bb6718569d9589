"""Threshold calibration: exact grid search on data disjoint from the test split."""
import json

import numpy as np
import pytest

from edgetruth import locate
from edgetruth.evaluate import threshold_calibration as tc
from edgetruth.errors import InputError
from edgetruth.locate import thresholds as thr


@pytest.fixture(scope="module")
def data():
    return tc.collect("calibration", images_per_scenario=4)


def test_grid_optimum_is_no_worse_than_any_fixed_window(data):
    # the grid contains 'all 11' (tau = 0, 0, 0) and 'all 5' (tau = 1, 1, 1 for H < 1)
    for model, errs in data.errors.items():
        tau, rmse, _ = tc.grid_search(data.entropy, errs, step=0.05)
        fixed = np.sqrt(np.mean(errs**2, axis=1))
        assert tau[0] <= tau[1] <= tau[2]
        assert rmse <= fixed.min() + 1e-12


def test_grid_rmse_equals_running_the_dynamic_method(data):
    """The prefix-sum shortcut must give exactly what dynamic_erf_4p gives with those thresholds."""
    tau, rmse, _ = tc.grid_search(data.entropy, data.errors["4p"], step=0.05)
    from edgetruth.evaluate.matching import on_edge
    from edgetruth.render.synthetic.scenarios import SCENARIOS, synthetic_image

    errs = []
    for scenario in SCENARIOS:
        for i in range(4):
            s = synthetic_image(scenario, i, split="calibration")
            cand = locate.candidates(s.image)
            cand = cand.subset(on_edge(s.truth, cand))
            pts = locate.refine(s.image, cand, "dynamic_erf_4p", tau=tau)
            errs.append(s.errors(pts.x, pts.y))
    e = np.concatenate(errs)
    assert np.sqrt(np.mean(e**2)) == pytest.approx(rmse, rel=1e-9)


def test_brute_force_agrees_on_a_small_grid():
    rng = np.random.default_rng(0)
    h = rng.uniform(0, 1, 300)
    errs = rng.normal(0, 1, (4, 300)) * np.array([[1.0], [0.8], [0.9], [1.2]])
    tau, rmse, (triples, table) = tc.grid_search(h, errs, step=0.1)
    for t, r in zip(triples[::37], table[::37]):
        w = np.select([h < t[0], h < t[1], h < t[2]], [0, 1, 2], 3)
        assert r == pytest.approx(np.sqrt(np.mean(errs[w, np.arange(300)] ** 2)))
    assert rmse == pytest.approx(table.min())


def test_shipped_thresholds_have_provenance_and_load():
    rec = json.loads(thr.source().read_text())
    prov = rec["provenance"]
    assert prov["data"]["split"] == "calibration"
    assert {"objective", "search", "code_version", "command"} <= set(prov)
    for model in ("2p", "4p"):
        assert thr.load(model) == tuple(rec["models"][model]["tau"])
        assert rec["models"][model]["rmse_px"] <= min(rec["models"][model]["fixed_window_rmse_px"].values())


def test_bad_threshold_files_are_clear_errors(tmp_path):
    with pytest.raises(ValueError, match="does not exist"):
        thr.load("4p", tmp_path / "missing.json")
    bad = tmp_path / "bad.json"
    bad.write_text('{"models": {"4p": {"tau": [0.9, 0.1, 0.5]}}}')
    with pytest.raises(ValueError, match="tau"):
        thr.load("4p", bad)


# --- thresholds for a camera, from renders ----------------------------------------------------------
THR_SPEC = """
[spec]
name = "{name}"
camera = "default"
camera_scale = 4
spp = 4
edge_spp = 16
edge_mode = "path"

[[group]]
name = "T1"
target = "T1"
distance_range_cm = [60, 90]
count = 2
lateral_fraction = 0.3
tilt_max_deg = 3
irradiance_w_m2 = 0.075
"""


@pytest.fixture(scope="module")
def two_render_sets(tmp_path_factory, fast_variant):
    """Two tiny target datasets from specs that differ only in their name (so in every seed)."""
    from edgetruth.render.dataset.driver import render_spec

    root = tmp_path_factory.mktemp("thr")
    out = {}
    for name in ("cal_renders", "test_renders"):
        spec = root / f"{name}.toml"
        spec.write_text(THR_SPEC.format(name=name))
        render_spec(spec, root / name, progress=False, announce=lambda s: None)
        out[name] = root / name
    return out


def test_render_calibration_records_its_seeds_and_refuses_them_at_test_time(two_render_sets, tmp_path):
    from edgetruth.render.dataset.reader import open_dataset

    rec = tc.calibrate_renders([two_render_sets["cal_renders"]], step=0.05)
    data = rec["provenance"]["data"]
    assert data["kind"] == "renders" and data["specs"] == ["cal_renders"] and data["on_edge_points"] > 50
    for model in ("2p", "4p"):  # the optimum is no worse than the best fixed window on the same points
        m = rec["models"][model]
        assert m["rmse_px"] <= min(m["fixed_window_rmse_px"].values()) + 1e-12
        assert thr.validate(m["tau"]) == tuple(m["tau"])
    path = tmp_path / "camera.json"
    tc.write(rec, path)
    assert thr.load("4p", path) == tuple(rec["models"]["4p"]["tau"])
    cal = [(s.name, s.truth) for s in open_dataset(two_render_sets["cal_renders"]).targets()]
    test = [(s.name, s.truth) for s in open_dataset(two_render_sets["test_renders"]).targets()]
    cal_keys = set().union(*(tc.image_seed_keys(gt) for _, gt in cal))
    test_keys = set().union(*(tc.image_seed_keys(gt) for _, gt in test))
    assert len(cal_keys) >= 3 * len(cal) - 1 and not cal_keys & test_keys  # own seeds: disjoint by the spec's name
    tc.check_disjoint(path, test)  # disjoint: accepted
    with pytest.raises(InputError, match="rendered from seeds its thresholds were calibrated on"):
        tc.check_disjoint(path, cal[:1])
