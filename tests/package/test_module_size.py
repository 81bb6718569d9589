"""Small modules with one job: no source module of the package is over ``MAX_LINES`` lines (issue 49); the check
can fail (a longer text fails it)."""
from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
#: the package's source folders (tests, tools and the docs are not the package)
SOURCE = ("edgetruth", "cli", "render", "locate", "evaluate", "scenes", "assets")
MAX_LINES = 800


def long_modules(files) -> list[str]:
    return [f"{f}: {n} lines" for f in files
            if (n := len(f.read_text().splitlines())) > MAX_LINES]


def test_no_module_is_over_800_lines(tmp_path):
    files = [f for folder in SOURCE for f in sorted((ROOT / folder).rglob("*.py"))]
    assert len(files) > 100
    assert long_modules(files) == [], "split these by job"
    big = tmp_path / "big.py"
    big.write_text("x = 1\n" * (MAX_LINES + 1))
    assert long_modules([big]) == [f"{big}: {MAX_LINES + 1} lines"]  # the rule can fail
