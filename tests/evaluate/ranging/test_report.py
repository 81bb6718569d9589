"""The ranging report on a paired design: tables select the cells of one factor, levels are compared
on shared pose slots (Friedman, Holm-adjusted Wilcoxon steps), verdicts state n, p and effect size."""
from __future__ import annotations

import numpy as np

from edgetruth.evaluate.ranging import report as rr


def _rows(paired: bool = True, n_slots: int = 30, seed: int = 0):
    rng = np.random.default_rng(seed)
    nuisance = rng.uniform(0.2, 1.0, n_slots)  # per-slot pose error, shared by every level
    rows = []
    cells = [("G1", "T1"), ("G2", "T1"), ("G3", "T1"), ("G4", "T1"), ("G1", "T2")]
    for snr, target in cells:
        for k in range(n_slots):
            g = int(snr[1]) - 1
            e = nuisance[k] * (1 if paired else rng.uniform(0.5, 1.5)) + 0.05 * g + rng.normal(0, 0.01)
            off = ",".join(f for f, v, b in (("snr", snr, "G1"), ("target", target, "T1")) if v != b)
            rows.append({"image": f"{k:04d}_{snr}_{target}", "spec": "study", "group": f"{snr}_{target}",
                         "slot": k if paired else "", "levels": f"snr={snr};target={target}" if paired else "",
                         "off_base": off, "method": "dynamic_erf_4p", "status": "ok", "error_cm": float(e),
                         "true_distance_m": 1.0})
    return rows


def test_design_rows_feed_the_tables():
    rows = _rows()
    assert {r["group"] for r in rr.main_rows(rows)} == {"G1_T1"}
    g = rr.group_rows(rows, "G")
    assert sorted({r["group"] for r in g}) == ["G1", "G2", "G3", "G4"] and len(g) == 4 * 30
    t = rr.group_rows(rows, "T")
    assert sorted({r["group"] for r in t}) == ["T1", "T2"] and len(t) == 2 * 30


def test_levels_are_compared_on_shared_slots():
    a = rr.level_analysis(rr.group_rows(_rows(), "G"), ["G1", "G2", "G3", "G4"])
    assert a["paired"] and a["n"] == 30
    assert a["friedman"]["p_value"] < 1e-6 and a["friedman"]["kendall_w"] > 0.8
    assert all(s["significant"] and s["median_difference"] > 0 for s in a["steps"])
    text = rr.describe_levels(a)
    assert "paired on 30 pose slots" in text and "Friedman" in text and "p(Holm)" in text


def test_unpaired_groups_are_said_to_be_unpaired():
    rows = _rows(paired=False)
    for r in rows:
        r["group"] = r["group"].split("_")[0] if r["group"].endswith("T1") else "T2"
    a = rr.level_analysis([r for r in rows if r["group"].startswith("G")], ["G1", "G2", "G3", "G4"])
    assert not a["paired"] and "unpaired" in rr.describe_levels(a)


def test_pairing_keys_on_spec_and_image():
    """Two datasets may both hold an image named 0000_T1: they must not pair with each other."""
    a = [{"spec": "s1", "image": "0000_T1", "status": "ok", "error_cm": 1.0},
         {"spec": "s2", "image": "0000_T1", "status": "ok", "error_cm": 5.0}]
    b = [{"spec": "s1", "image": "0000_T1", "status": "ok", "error_cm": 2.0}]
    ea, eb = rr.paired_errors(a, b)
    assert ea.tolist() == [1.0] and eb.tolist() == [2.0]


def test_pose_bias_is_split_into_its_shares_exactly():
    """A method's pose errors = calibration + optics (per image, from the truth) + resampling (ranging pose
    minus raw-image pose) + its points (the rest): each share's mean comes back exactly, and the four add up
    to the bias; rows without the shares (photos) give none and no Table 13c."""
    rng = np.random.default_rng(3)
    cal, opt, res, pts = (rng.normal(mu, 0.01, 40) for mu in (0.1, 0.02, 0.015, -0.03))
    rows = [{"image": f"{i:04d}", "method": "erf4p_fixed11", "status": "ok", "error_cm": 0.5, "rel_error_pct": 0.1,
             "size_error_px": 0.0, "error_pose_cm": float(c + o + r + p), "error_pose_raw_cm": float(c + o + p),
             "pose_cal_floor_cm": float(c), "pose_optics_floor_cm": float(o)}
            for i, (c, o, r, p) in enumerate(zip(cal, opt, res, pts))]
    s = rr.method_stats(rows)["pose"]
    assert s["n_shares"] == 40
    for key, want in (("calibration", cal), ("optics", opt), ("resampling", res), ("points", pts)):
        assert abs(s[key] - np.mean(want)) < 1e-12, key
    assert abs(s["calibration"] + s["optics"] + s["resampling"] + s["points"] - s["bias"]) < 1e-12
    assert abs(s["rmse_points"] - np.sqrt(np.mean(pts ** 2))) < 1e-12
    assert abs(s["rmse_raw"] - np.sqrt(np.mean((cal + opt + pts) ** 2))) < 1e-12
    table = "\n".join(rr.pose_shares_table({"erf4p_fixed11": rr.method_stats(rows)}, ["erf4p_fixed11"]))
    assert "Table 13c" in table and f"{np.mean(res):+.3f}" in table and f"{np.mean(pts):+.3f}" in table
    for r in rows:
        r["error_pose_raw_cm"] = float("nan")
    s = rr.method_stats(rows)["pose"]
    assert s["n_shares"] == 0 and np.isnan(s["points"]) and abs(s["bias"] - np.mean(cal + opt + res + pts)) < 1e-12
    assert rr.pose_shares_table({"erf4p_fixed11": rr.method_stats(rows)}, ["erf4p_fixed11"]) == []
