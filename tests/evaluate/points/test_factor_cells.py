"""Per-point tables for every factor of a design, whatever its name, and for the groups outside it:
an E4-style table named after the factor, paired tests on the pose slots, window shares per level,
and the factor's levels in render_points_summary.csv."""
from __future__ import annotations

import csv

import numpy as np

from edgetruth.evaluate.points import report as rpr
from edgetruth.evaluate.points import scores as rp


def _table(n_slots=8, per=40, seed=0):
    """A design with factor fnum (F4 base, F8 blurs: larger errors on the same slots) and snr (G1, G2),
    one at a time, plus a group 'near' outside the design."""
    rng = np.random.default_rng(seed)
    cells = [("F4", "G1", "", 0.02), ("F8", "G1", "fnum", 0.04), ("F4", "G2", "snr", 0.03)]
    images, sd = [], []
    for f, g, off, s in cells:
        for k in range(n_slots):
            images.append({"image": f"{len(images):04d}_{f}_{g}", "spec": "s", "group": f"{f}_{g}", "slot": k,
                           "levels": f"fnum={f};snr={g}", "off_base": off, "interval": "50-100", "bound_px": 0.01})
            sd.append(s)
    for k in range(3):
        images.append({"image": f"{len(images):04d}_near", "spec": "s", "group": "near", "slot": "", "levels": "",
                       "off_base": "", "interval": "50-100", "bound_px": 0.01})
        sd.append(0.05)
    image = np.repeat(np.arange(len(images)), per)
    scale = np.repeat(sd, per)
    n = image.size
    errs = {"dynamic_erf_4p": rng.normal(0, 1, n) * scale, "erf4p_fixed11": rng.normal(0, 1, n) * scale * 1.1}
    conv = {m: np.ones(n, bool) for m in errs}
    win = {"dynamic_erf_4p": np.where(scale > 0.03, 7, 5)}
    return rp.PointTable(images, image, errs, conv, win)


def test_cells_hold_every_factor_and_the_groups_outside():
    c = rpr.cells(_table())
    keys = [(ft.key, ft.levels) for ft, _ in c["factors"]]
    assert keys == [("G", ["G1", "G2"]), ("fnum", ["F4", "F8"])]
    assert c["groups"][0].levels == ["near"] and int(c["groups"][1]["near"].sum()) == 3
    assert int(c["factors"][1][1]["F8"].sum()) == 8 and int(c["base"].sum()) == 8


def test_factor_gets_its_table_paired_tests_window_shares_and_summary_rows(tmp_path):
    t = _table()
    text = "\n".join(rpr.report_section(t, t.methods, tmp_path))
    sec = text.split("## Factor fnum: F4 vs F8 — per-point RMSE (px)")[1].split("\n## ")[0]
    assert "| method | F4 | F8 |" in sec
    line = next(ln for ln in sec.splitlines() if ln.startswith("- ProposedDynamicERF_4P:"))
    assert "n = 8 pose slots" in line and "Wilcoxon signed-rank F4→F8" in line and "p = 0.00781" in line
    assert "## Table E4G" in text  # the SNR factor keeps its seed table
    assert "| method | near |" in text.split("## Groups outside the design — per-point RMSE (px)")[1]
    win = text.split("## Window shares")[1]
    assert "| fnum=F8 | 0.0 % | 100.0 %" in win and "| G2 |" in win and "| group near |" in win
    assert (tmp_path / "figures" / "fig_points_factor_fnum.png").is_file()
    with open(tmp_path / "render_points_summary.csv", newline="") as f:
        cells = {(r["cell"], r["level"]) for r in csv.DictReader(f)}
    assert {("base", ""), ("snr", "G1"), ("snr", "G2"), ("fnum", "F4"), ("fnum", "F8"), ("group", "near")} <= cells


def test_level_tests_pair_on_the_slots():
    t = _table()
    c = rpr.cells(t)
    lt = rpr.level_tests(t, "dynamic_erf_4p", c["factors"][1][1])
    assert lt["n_blocks"] == 8 and lt["k"] == 2 and lt["steps"][0]["n_pairs"] == 8
    assert lt["steps"][0]["median_difference"] > 0 and lt["steps"][0]["rank_biserial"] == 1.0
