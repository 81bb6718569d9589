"""The headline tables that README.md and docs/*.md quote, generated from the committed results.

    python tools/results_tables.py           # rewrite every quoted table in place (make tables)
    python tools/results_tables.py --check   # exit 1 naming each quoted table that differs from its source

A quoted table sits between ``<!-- table:NAME -->`` and ``<!-- /table -->``; NAME is one of TABLES below,
each read from a file under docs/results/ (a CSV or JSON a study command wrote). Numbers are printed as the
reports print them; nothing is typed by hand. tests/package/test_results_tables.py runs the check.
"""
from __future__ import annotations

import argparse
import csv
import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results"
#: the files that may quote tables
QUOTING = ["README.md", "docs/*.md"]
MARK = re.compile(r"(<!-- table:(?P<name>[a-z0-9_]+) -->\n)(?P<body>.*?)(<!-- /table -->)", re.S)


def _labels() -> dict:
    """Method id -> the label the reports print (the registry's)."""
    from edgetruth.locate import METHODS

    labels = {m: v.label for m, v in METHODS.items()}
    labels.update({"dynamic_erf_4p_camera": f"{labels['dynamic_erf_4p']} (camera τ)",
                   "dynamic_erf_2p_camera": f"{labels['dynamic_erf_2p']} (camera τ)"})
    return labels


def _csv(path: Path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _table(header: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def synthetic_rmse() -> str:
    """The synthetic study (docs/results/synthetic_full): coverage and RMSE per method, on the points every
    method refines (the common subset) and on all candidates with failures as pixel centres."""
    labels = _labels()
    rows = _csv(RESULTS / "synthetic_full" / "tables" / "table6_all_methods.csv")
    rows.sort(key=lambda r: float(r["rmse_common"]))
    return _table(["method", "coverage (%)", "RMSE, common subset (px)", "RMSE, all candidates (px)"],
                  [[labels.get(r["method"], r["method"]), f"{float(r['coverage_pct']):.1f}",
                    f"{float(r['rmse_common']):.3f}", f"{float(r['rmse_all']):.3f}"] for r in rows])


def _points_rows() -> list[dict]:
    rows = _csv(RESULTS / "ranging_full" / "render_points_summary.csv")
    rows = [r for r in rows if r["cell"] == "base" and r["interval"] == "all"]
    rows.sort(key=lambda r: float(r["rmse_px"]))
    return rows


def _points_table(rows: list[dict]) -> str:
    labels = _labels()
    return _table(["method", "RMSE (px)", "bias vs optical edge (px)", "RMSE ÷ exact bound"],
                  [[labels.get(r["method"], r["method"]), f"{float(r['rmse_px']):.4f}",
                    f"{float(r['bias_optical_px']):+.4f}", f"{float(r['rmse_optical_over_bound']):.2f}"]
                   for r in rows])


def points_top() -> str:
    """The full ranging study's per-point table E1 (base cell, every distance): the five lowest RMSEs."""
    return _points_table(_points_rows()[:5])


def points_all() -> str:
    """Table E1 of the full ranging study for every method (base cell, every distance)."""
    return _points_table(_points_rows())


def ranging() -> str:
    """The full ranging study's base cell per method: RMSE of Z = fx·S/l and of the pose (cm), with CIs."""
    labels = _labels()
    pm = json.loads((RESULTS / "ranging_full" / "ranging_summary.json").read_text())["per_method"]
    items = sorted(pm.items(), key=lambda kv: kv[1]["pose"]["rmse"])
    return _table(["method", "size model RMSE (cm)", "95 % CI", "pose RMSE (cm)", "95 % CI"],
                  [[labels.get(m, m), f"{v['rmse']:.3f}", f"{v['rmse_ci'][0]:.3f}–{v['rmse_ci'][1]:.3f}",
                    f"{v['pose']['rmse']:.3f}",
                    f"{v['pose']['rmse_ci'][0]:.3f}–{v['pose']['rmse_ci'][1]:.3f}"] for m, v in items])


TABLES = {"synthetic_rmse": synthetic_rmse, "points_top": points_top, "points_all": points_all,
          "ranging": ranging}


def quoting_files(root: Path = ROOT) -> list[Path]:
    return sorted({p for pat in QUOTING for p in root.glob(pat)})


def render(text: str, where: str = "") -> tuple[str, list[str]]:
    """``text`` with every quoted table regenerated, and the names of those that changed."""
    changed = []

    def sub(m: re.Match) -> str:
        name = m["name"]
        if name not in TABLES:
            raise SystemExit(f"{where}: <!-- table:{name} -->: no such table; choose one of {', '.join(TABLES)}")
        body = TABLES[name]()
        if body != m["body"]:
            changed.append(name)
        return m.group(1) + body + m.group(4)

    return MARK.sub(sub, text), changed


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--check", action="store_true", help="change nothing; exit 1 if a quoted table differs")
    args = ap.parse_args(argv)
    stale = []
    for path in quoting_files():
        text = path.read_text()
        new, changed = render(text, str(path.relative_to(ROOT)))
        for name in changed:
            stale.append(f"{path.relative_to(ROOT)}: table {name!r} differs from docs/results/")
        if changed and not args.check:
            path.write_text(new)
    if args.check and stale:
        print("\n".join(stale) + "\nregenerate them: python tools/results_tables.py", file=sys.stderr)
        return 1
    for s in stale:
        print(s.replace("differs from", "regenerated from"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
