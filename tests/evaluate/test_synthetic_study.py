"""The synthetic study: consistent tables, honest claims, resumable runs."""
import json

import numpy as np
import pytest

from edgetruth.evaluate import synthetic_study as ss

METHODS = ["canny_pixel", "canny_devernay", "glm1984", "erf4p_fixed5", "erf4p_fixed7", "erf4p_fixed9",
           "erf4p_fixed11", "dynamic_erf_4p"]


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out = tmp_path_factory.mktemp("syn")
    report = ss.run_synthetic_study(out, "quick", METHODS, progress=False, images_per_scenario=3)
    return out, report


def test_report_tables_and_figures_are_written(study):
    out, report = study
    text = report.read_text()
    for heading in ("Table 3", "Table 4", "Table 5", "Table 6", "Table 7", "Table 8", "Does the seed's synthetic study"):
        assert heading in text
    for f in ("table6_all_methods.csv", "table8_rmse_per_scenario.csv", "table7_wilcoxon.csv", "table3_window_shares.csv",
              "table4_threshold_sensitivity.csv"):
        assert (out / "tables" / f).stat().st_size > 0
    for f in ("fig4_window_shares.png", "fig5_threshold_sensitivity.png", "fig6_error_boxplots.png", "fig7_rmse_per_scenario.png"):
        assert (out / "figures" / f).read_bytes()[:4] == b"\x89PNG"
        assert f"figures/{f}" in text


def test_sensitivity_at_zero_offset_is_the_dynamic_method(study):
    """Table 4 re-selects fixed-window results by entropy; at delta = 0 it must equal dynamic_erf_4p exactly."""
    out, _ = study
    d = ss.collect(out, 3, ss.mo.ordered(METHODS), progress=False)  # from cache
    t = ss.build_tables(d)
    zero = [r for r in t["sensitivity"]["4p"] if r["delta"] == 0.0][0]
    dyn = [r for r in t["all"] if r["method"] == "dynamic_erf_4p"][0]
    assert zero["rmse"] == pytest.approx(dyn["rmse"], rel=1e-12)
    assert sum(zero["shares"].values()) == pytest.approx(1.0)


def test_every_method_is_scored_on_the_same_points(study):
    out, _ = study
    d = ss.collect(out, 3, ss.mo.ordered(METHODS), progress=False)
    sizes = {m: d.errors[m].size for m in d.methods}
    assert len(set(sizes.values())) == 1 and d.scenario.size == next(iter(sizes.values()))
    # CannyPixel's error is the candidate's distance: within the matching radius by construction
    assert np.abs(d.errors["canny_pixel"]).max() <= 1.5


def test_claims_are_computed_with_evidence(study):
    out, _ = study
    claims = json.loads((out / "claims.json").read_text())
    assert len(claims) >= 5
    assert all(c["verdict"] in ("holds", "does not hold", "partly") and c["evidence"] for c in claims)


def test_rerun_resumes_from_the_cache_and_refuses_other_settings(study):
    out, report = study
    before = (out / "tables" / "table6_all_methods.csv").read_text()
    cached = sorted(p.name for p in (out / "cache").glob("*.npz"))
    ss.run_synthetic_study(out, "quick", METHODS, progress=False, images_per_scenario=3)
    assert sorted(p.name for p in (out / "cache").glob("*.npz")) == cached
    after = (out / "tables" / "table6_all_methods.csv").read_text()
    # identical numbers except the timing column
    strip = lambda s: [",".join(r.split(",")[:-1]) for r in s.splitlines()]
    assert strip(before) == strip(after)
    with pytest.raises(ValueError, match="other methods"):
        ss.run_synthetic_study(out, "quick", ["canny_pixel", "dynamic_erf_4p"], progress=False, images_per_scenario=3)


def test_bad_arguments():
    with pytest.raises(ValueError, match="preset"):
        ss.run_synthetic_study("/tmp/x", "medium")
    with pytest.raises(ValueError, match="unknown method"):
        ss.run_synthetic_study("/tmp/x", "quick", ["nope"])


def test_process_pool_gives_the_same_numbers(study, tmp_path):
    """Blocks are pure tasks: two worker processes produce the same errors as the in-process run."""
    out, _ = study
    ss.run_synthetic_study(tmp_path, "quick", METHODS, progress=False, images_per_scenario=3, workers=2)
    a = ss.collect(out, 3, ss.mo.ordered(METHODS), progress=False)
    b = ss.collect(tmp_path, 3, ss.mo.ordered(METHODS), progress=False)
    for m in a.methods:
        assert np.array_equal(a.errors[m], b.errors[m])
