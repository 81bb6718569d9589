"""The headline tables README.md and docs/*.md quote (between <!-- table:NAME --> markers) are what
tools/results_tables.py makes from the committed results in docs/results/: none is typed by hand."""
from __future__ import annotations

from tests.support.tools import ROOT, load_tool

tables = load_tool("tools/results_tables.py", "results_tables")


def test_quoted_tables_match_docs_results():
    stale = []
    quoted = 0
    for path in tables.quoting_files():
        text = path.read_text()
        quoted += len(tables.MARK.findall(text))
        _, changed = tables.render(text, str(path))
        stale += [f"{path.relative_to(ROOT)}: {name}" for name in changed]
    assert quoted >= 4, "README.md and docs/results.md quote the headline tables"
    assert not stale, f"quoted tables differ from docs/results/ (run python tools/results_tables.py): {stale}"


def test_a_changed_figure_is_caught():
    text = (ROOT / "docs" / "results.md").read_text()
    start = text.index("<!-- table:synthetic_rmse -->")
    row = text.index("| ", text.index("|---|", start))  # the first data row
    digit = next(i for i in range(row, len(text)) if text[i].isdigit())
    tampered = text[:digit] + str((int(text[digit]) + 1) % 10) + text[digit + 1:]
    _, changed = tables.render(tampered)
    assert changed == ["synthetic_rmse"]


def test_tables_read_the_committed_csv():
    first = tables.synthetic_rmse().splitlines()[2]
    rows = tables._csv(ROOT / "docs" / "results" / "synthetic_full" / "tables" / "table6_all_methods.csv")
    best = min(rows, key=lambda r: float(r["rmse_common"]))
    assert f"{float(best['rmse_common']):.3f}" in first
