"""Fair per-point tables on renders: coverage, refined points, common subset, all candidates; the
optical edge in the truth and in the tables."""
from __future__ import annotations

import numpy as np
import pytest

from edgetruth.evaluate.points import report as rpr
from edgetruth.evaluate.points import scores as rp


def _table(n_img=10, per=50, seed=0):
    """'good' refines everything at 0.02 px; 'decliner' refines 70 % at 0.02 px and answers the rest
    with the pixel centre (errors ~ 0.4 px); 'other' declines a different 20 %."""
    rng = np.random.default_rng(seed)
    images = [{"image": f"{k:04d}", "spec": "s", "levels": "snr=G1;target=T1", "off_base": "",
               "interval": "50-100", "bound_px": 0.01} for k in range(n_img)]
    image = np.repeat(np.arange(n_img), per)
    n = image.size
    dec = rng.random(n) < 0.3
    oth = rng.random(n) < 0.2
    errs = {"good": rng.normal(0, 0.02, n), "decliner": np.where(dec, rng.uniform(-0.5, 0.5, n), rng.normal(0, 0.02, n)),
            "other": np.where(oth, 0.45, rng.normal(0.01, 0.02, n))}
    conv = {"good": np.ones(n, bool), "decliner": ~dec, "other": ~oth}
    opt = np.full(n, 0.01)
    return rp.PointTable(images, image, errs, conv, {}, opt, opt * 1.3), dec, oth


def test_refined_rmse_excludes_declines_and_common_subset_is_the_intersection():
    t, dec, oth = _table()
    common = rpr.common_mask(t, t.methods)
    assert np.array_equal(common, ~dec & ~oth)
    bound = np.array([r["bound_px"] for r in t.images])
    s = rpr.point_stats(t, "decliner", bound, common)
    assert s["coverage"] == pytest.approx(np.mean(~dec))
    assert s["rmse_refined"] == pytest.approx(np.sqrt(np.mean(t.errors["decliner"][~dec] ** 2)))
    assert s["rmse_refined"] < 0.025 < 0.1 < s["rmse"]  # the all-candidates figure keeps the declines
    assert s["rmse_common"] == pytest.approx(np.sqrt(np.mean(t.errors["decliner"][common] ** 2)))
    assert s["n_common"] == int(common.sum()) and s["n_refined"] == int((~dec).sum())
    o = rpr.point_stats(t, "other", bound, common)
    assert o["bias_refined"] == pytest.approx(0.01, abs=0.004)
    assert o["bias_optical"] == pytest.approx(0.0, abs=0.004)  # the optics' 0.01 px taken off
    # the RMSE against the optical edge: sqrt(0.02^2 + 0.01^2) -> 0.02 with the optics' 0.01 px taken off
    ref = ~oth
    assert o["rmse_optical"] == pytest.approx(np.sqrt(np.mean((t.errors["other"][ref] - 0.01) ** 2)), rel=1e-12)
    assert o["rmse_optical"] < o["rmse_refined"]
    t.bounds = {m: np.full(len(t.image), 0.02) for m in t.methods}
    o = rpr.point_stats(t, "other", bound, common)
    assert o["rmse_optical_over_bound"] == pytest.approx(o["rmse_optical"] / 0.02, rel=1e-12)
    assert o["rmse_optical_over_bound"] == pytest.approx(1.0, abs=0.08)  # N(0.01, 0.02) minus 0.01, over 0.02


def test_paired_tests_use_the_common_subset():
    t, dec, oth = _table()
    common = rpr.common_mask(t, t.methods)
    t.errors["dynamic_erf_4p"] = t.errors.pop("good")
    t.converged["dynamic_erf_4p"] = t.converged.pop("good")
    comp = {c["method"]: c for c in rpr.image_comparisons(t, t.methods, mask=common)}
    # on the common subset the decliner is as good as the reference: no significant difference
    assert not comp["decliner"]["significant"]
    assert abs(comp["decliner"]["rmse_difference"]) < 0.005
    comp_all = {c["method"]: c for c in rpr.image_comparisons(t, t.methods)}
    assert comp_all["decliner"]["significant"]  # all candidates: the declines dominate


def test_report_section_writes_the_four_figures(tmp_path):
    t, _, _ = _table()
    t.errors["dynamic_erf_4p"] = t.errors.pop("good")
    t.converged["dynamic_erf_4p"] = t.converged.pop("good")
    lines = rpr.report_section(t, t.methods, tmp_path)
    text = "\n".join(lines)
    for word in ("coverage", "RMSE (refined)", "RMSE (common subset)", "declines at pixel", "bias vs optical edge",
                 "common subset", "optics: predicted displacement", "RMSE vs optical ÷ bound"):
        assert word in text
    rows = (tmp_path / "render_points_summary.csv").read_text().splitlines()
    head = rows[0].split(",")
    for col in ("rmse_refined_px", "rmse_common_px", "bias_optical_px", "optical_offset_px", "rmse_optical_px",
                "rmse_optical_over_bound"):
        assert col in head


def test_points_file_round_trips_the_optical_offsets(tmp_path):
    t, _, _ = _table()
    rp.write_points(tmp_path / rp.POINTS_FILE, t)
    back = rp.read_points(tmp_path / rp.POINTS_FILE)
    assert np.allclose(back.optical("centroid"), 0.01) and np.allclose(back.optical("median"), 0.013)
    sub = back.select(np.arange(len(back.images)) < 3)
    assert len(sub.optical("centroid")) == len(sub.image)


def test_rendered_dataset_carries_the_optical_edge_and_scores_against_it(tiny_dataset):
    from edgetruth.render.dataset.reader import open_dataset

    _, out = tiny_dataset
    ds = open_dataset(out)
    s = ds.targets()[0]
    oe = s.truth["outline"]["optical_edge"]
    assert len(oe["offset_px"]) == len(s.truth["outline"]["polyline_distorted_px"])
    opt = s.optical_outline
    poly = np.asarray(s.truth["outline"]["polyline_distorted_px"])
    q = poly[::7] + 0.3
    geo = s.outline.signed_distance(q[:, 0], q[:, 1])
    assert np.allclose(opt.geometric_signed_distance(q[:, 0], q[:, 1]), geo)
    assert np.allclose(opt.signed_distance(q[:, 0], q[:, 1]), geo - opt.offset_at(q[:, 0], q[:, 1]))
    moved = opt.polyline()
    assert np.allclose(opt.signed_distance(moved[::5, 0], moved[::5, 1]), 0.0, atol=2e-3)
    sc = rp.score_image(s.image.astype(float), s.truth, ["canny_pixel", "canny_devernay", "erf4p_fixed11"])
    assert sc.optical_offset is not None and np.isfinite(sc.optical_offset).all()
    t = rp.table_from_scores([{"image": s.name, "interval": "50-100"}], [sc], ["canny_pixel", "canny_devernay",
                                                                              "erf4p_fixed11"])
    common = rpr.common_mask(t, t.methods)
    assert np.array_equal(common, t.converged["canny_devernay"] & t.converged["erf4p_fixed11"]
                          & t.converged["canny_pixel"])
    st = rpr.point_stats(t, "canny_devernay", np.array([np.nan]), common)
    e, c = t.errors["canny_devernay"], t.converged["canny_devernay"]
    if (~c).any():  # a declining method: its refined-point RMSE leaves the declines out
        assert st["rmse_refined"] == pytest.approx(np.sqrt(np.mean(e[c] ** 2)))


def test_the_lowest_rmse_method_gets_its_own_paired_table(tmp_path):
    """E2b: the method with the lowest common-subset RMSE against each other method, paired per image."""
    t, _, _ = _table()
    t.errors["dynamic_erf_4p"] = t.errors["other"].copy()
    t.converged["dynamic_erf_4p"] = t.converged["other"].copy()
    t.errors["decliner"] = t.errors["decliner"] * 2.0  # its refined points at 0.04 px: 'good' is the lowest
    text = "\n".join(rpr.report_section(t, t.methods, tmp_path))
    assert "Table E2b" in text and "lowest-RMSE method (good)" in text
    block = text.split("Table E2b")[1].split("##")[0]
    rows = {ln.split("|")[1].strip(): ln.split("|") for ln in block.splitlines() if ln.startswith("| ") and "---" not in ln}
    # 'good' (unbiased) against 'decliner' (twice the noise on the common subset): lower RMSE on every image
    assert float(rows["decliner"][3]) < 0 and rows["decliner"][-2].strip() == "yes"
