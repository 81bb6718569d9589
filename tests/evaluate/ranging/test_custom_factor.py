"""Every factor of a design is reported, whatever its name: a custom factor (f-number, two levels)
gets its own ranging and per-point tables, paired tests and figures, and a group outside the design
gets its own rows (issue 21)."""
from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from edgetruth.evaluate import design as dc
from edgetruth.render.testing import TINY_CAMERA

SPEC = """
[spec]
name = "fsweep"
camera = "{camera}"
spp = 4
edge_spp = 64
edge_mode = "path"
board_mode = "path"
sampler = "multijitter"

[design]
distance_range_cm = [60, 90]
count = 5
lateral_fraction = 0.3
tilt_max_deg = 3

[[design.factor]]
name = "fnum"
levels = [ {{ name = "F4", target = "T2", irradiance_w_m2 = 0.0044, camera = {{ f_number = 4.0 }} }},
           {{ name = "F8", target = "T2", irradiance_w_m2 = 0.0176, camera = {{ f_number = 8.0 }} }} ]

[[group]]
name = "near"
target = "T2"
distance_range_cm = [60, 90]
count = 2
irradiance_w_m2 = 0.0044
camera = {{ focus_distance_m = 0.85 }}
"""


def _true_calibration(dataset: Path, path: Path) -> Path:
    """A calibration.json with the true intrinsics (the spec has no boards)."""
    from edgetruth.render import open_dataset

    cam = open_dataset(dataset)[0].truth["camera"]
    path.write_text(json.dumps({"K": cam["K"], "dist_coeffs_opencv": cam["dist_coeffs_opencv"],
                                "image_size": [cam["width_px"], cam["height_px"]]}))
    return path


def _section(report: str, head: str) -> str:
    return report.split(head, 1)[1].split("\n## ", 1)[0]


def test_factor_tables_cover_every_factor_and_the_groups_outside():
    rows = []
    for k in range(4):
        for lv, off in (("F4", ""), ("F8", "fnum"), ("F2.8", "fnum")):
            rows.append({"image": f"{k}_{lv}", "group": lv, "slot": k, "levels": f"fnum={lv};snr=G1",
                         "off_base": off})
        rows.append({"image": f"{k}_G2", "group": "G2", "slot": k, "levels": "fnum=F4;snr=G2", "off_base": "snr"})
        rows.append({"image": f"{k}_near", "group": "near", "slot": "", "levels": "", "off_base": ""})
    assert dc.design_factors(rows) == {"fnum": ["F4", "F8", "F2.8"], "snr": ["G1", "G2"]}
    fts = {ft.key: ft for ft in dc.factor_tables(rows)}
    assert fts["G"].levels == ["G1", "G2"] and fts["G"].title.startswith("Table 16")
    f = fts["fnum"]
    assert f.levels == ["F4", "F8", "F2.8"] and f.paired and f.title == "Factor fnum: F4 vs F8 vs F2.8"
    assert len(f.rows) == 12 and f.cell_label("F8") == "fnum=F8"
    g = dc.plain_groups(rows)
    assert g.levels == ["near"] and not g.paired and len(g.rows) == 4


@pytest.mark.slow
def test_custom_factor_and_group_are_reported(tmp_path, fast_variant):
    from edgetruth.cli import main
    from edgetruth.render.dataset.driver import render_spec

    cam = tmp_path / "cam.toml"
    cam.write_text(TINY_CAMERA)
    spec = tmp_path / "fsweep.toml"
    spec.write_text(SPEC.format(camera=cam))
    data = tmp_path / "data"
    render_spec(spec, data, progress=False, announce=lambda s: None)
    cal = _true_calibration(data, tmp_path / "cal.json")
    out = tmp_path / "eval"
    rc = main(["evaluate", str(data), "--calibration", str(cal), "-o", str(out), "-j", "1", "--no-progress",
               "--methods", "canny_pixel,erf4p_fixed11,dynamic_erf_4p"])
    assert rc == 0
    report = (out / "report.md").read_text()

    # ranging: the factor's table across both levels, every method, CIs, and the paired test per method
    rng = _section(report, "## Factor fnum: F4 vs F8 (cm")
    for lv in ("F4", "F8"):
        assert f"| {lv} | ProposedDynamicERF_4P | 5 |" in rng
    assert "RMSE 95 % CI" in rng and "MAE 95 % CI" in rng
    line = next(ln for ln in rng.splitlines() if ln.startswith("- ProposedDynamicERF_4P:"))
    assert "paired on 5 pose slots" in line and "Wilcoxon signed-rank F4→F8, n = 5" in line and ", p = " in line

    # per point: the factor's E4-style table and its paired tests
    pts = _section(report, "## Factor fnum: F4 vs F8 — per-point RMSE (px)")
    assert "| method | F4 | F8 |" in pts
    line = next(ln for ln in pts.splitlines() if ln.startswith("- ProposedDynamicERF_4P:"))
    assert "n = 5 pose slots" in line and "Wilcoxon signed-rank F4→F8" in line and ", p = " in line

    # the group outside the design: its own rows, in ranging and per point
    grp = _section(report, "## Groups outside the design — per group (cm")
    assert "| near | ProposedDynamicERF_4P |" in grp
    assert "| method | near |" in _section(report, "## Groups outside the design — per-point RMSE (px)")

    # window shares per level and group, figures per factor
    win = _section(report, "## Window shares of the dynamic methods")
    assert "| fnum=F8 |" in win and "| group near |" in win
    assert (out / "figures" / "fig_factor_fnum.png").is_file()
    assert (out / "figures" / "fig_points_factor_fnum.png").is_file()
    assert "figures/fig_factor_fnum.png" in report and "figures/fig_points_factor_fnum.png" in report

    # the per-point summary CSV has the factor's levels and the group
    with open(out / "render_points_summary.csv", newline="") as f:
        cells = {(r["cell"], r["level"]) for r in csv.DictReader(f) if r["interval"] == "all"}
    assert {("base", ""), ("fnum", "F4"), ("fnum", "F8"), ("group", "near")} <= cells


def test_two_levels_are_tested_with_one_wilcoxon_and_an_empty_pairing_says_so():
    from edgetruth.evaluate.ranging import report as rr

    rows = [{"image": f"{k}_{lv}", "spec": "s", "group": lv, "slot": k, "status": "ok",
             "error_cm": 0.1 * (k + 1) + (0.05 if lv == "F8" else 0.0)} for k in range(6) for lv in ("F4", "F8")]
    text = rr.describe_levels(rr.level_analysis(rows, ["F4", "F8"]))
    assert "paired on 6 pose slots" in text and "F4→F8, n = 6" in text and "p = 0.0312" in text
    assert "Friedman χ²" not in text
    for r in rows:
        if r["group"] == "F8":
            r["status"] = "size failed"
    text = rr.describe_levels(rr.level_analysis(rows, ["F4", "F8"]))
    assert "paired design" in text and "not tested" in text
