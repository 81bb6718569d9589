"""The quick run's report sets its window shares beside the full study's (issue 19, item 3)."""
from __future__ import annotations

import csv
from pathlib import Path

import pytest

from edgetruth.evaluate.ranging.window_shares import FULL_STUDY_SHARES, beside_section, summary_shares

COMMITTED = Path(__file__).resolve().parents[3] / "docs" / "results" / "ranging_full" / "render_points_summary.csv"
FIELDS = ["cell", "level", "interval", "method", "n_points", "window5_share", "window7_share", "window9_share",
          "window11_share"]


def test_full_study_shares_are_the_committed_results():
    if not COMMITTED.is_file():
        pytest.skip("no docs/results in this install")
    committed = summary_shares(COMMITTED)
    for key, v in FULL_STUDY_SHARES.items():
        assert committed[key][4] == v[4], key
        assert committed[key][:4] == pytest.approx(v[:4], abs=5e-5), key
    # every cell and dynamic method of the committed table is stated (G1 and T1 are the base cell)
    assert {k for k in committed if k[0] not in ("G1", "T1")} == set(FULL_STUDY_SHARES)
    assert all(committed[("G1", m)] == committed[("base", m)] for _, m in committed if _ == "base")


def _summary(path: Path, rows) -> Path:
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=FIELDS)
        w.writeheader()
        for r in rows:
            w.writerow(dict(zip(FIELDS, r)))
    return path


def test_beside_section_pairs_each_cell_with_the_full_study(tmp_path):
    p = _summary(tmp_path / "s.csv", [
        ("base", "", "all", "dynamic_erf_4p", 1200, 0.9, 0.1, 0.0, 0.0),
        ("snr", "G4", "all", "dynamic_erf_4p", 1100, 0.7, 0.25, 0.05, 0.0),
        ("snr", "G4", "50-100", "dynamic_erf_4p", 300, 0.2, 0.8, 0.0, 0.0),   # per interval: not read
        ("base", "", "all", "canny_pixel", 1200, "", "", "", ""),              # no windows: not read
    ])
    text = "\n".join(beside_section(p))
    assert "## Window shares: this run beside the full study" in text
    rows = [ln for ln in text.splitlines() if ln.startswith("| ProposedDynamicERF_4P")]
    assert len(rows) == 2
    full = FULL_STUDY_SHARES[("base", "dynamic_erf_4p")]  # the full study's side: the committed shares
    assert rows[0].split(" | ")[1:] == ["base (G1_T1)", "90.0 %", "10.0 %", "0.0 %", "0.0 %",
                                        *[f"{100 * s:.1f} %" for s in full[:4]], f"1,200 / {full[4]:,} |"]
    assert "G4" in rows[1] and "70.0 %" in rows[1] and f"{100 * FULL_STUDY_SHARES[('G4', 'dynamic_erf_4p')][0]:.1f} %" in rows[1]
    assert beside_section(_summary(tmp_path / "none.csv", [("base", "", "all", "canny_pixel", 5, "", "", "", "")])) == []
