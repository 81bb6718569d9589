"""Threshold calibration: exact grid search on data disjoint from the test split."""
import json

import numpy as np
import pytest

from edgetruth import locate
from edgetruth.evaluate import threshold_calibration as tc
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
    from edgetruth.render.synthetic import SCENARIOS, synthetic_image

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
