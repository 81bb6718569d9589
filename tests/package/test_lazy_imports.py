"""Imports sit at the top of their module unless there is a reason: every import inside a function of the
hoisted floors carries the trailing comment ``# lazy: <reason>`` (a heavy or optional dependency, a module that
loads one, a name the tests patch on its module; docs/architecture.md), and the check can fail."""
from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
#: the source folders whose function-level imports are all marked
CHECKED = ("edgetruth", "cli", "evaluate")
MARK = re.compile(r"#.*\blazy: \S")


def unmarked(path: Path, text: str | None = None) -> list[str]:
    """``path:line: statement`` of every function-level import without its ``# lazy:`` reason."""
    text = path.read_text() if text is None else text
    lines = text.splitlines()
    out = []

    def walk(node, in_func):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.Import, ast.ImportFrom)):
                span = lines[child.lineno - 1:child.end_lineno]  # a wrapped import: its mark on any line
                if in_func and not any(MARK.search(line) for line in span):
                    out.append(f"{path}:{child.lineno}: {ast.unparse(child)}")
                continue
            walk(child, in_func or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)))

    walk(ast.parse(text), False)
    return out


def test_every_function_level_import_says_why():
    files = [f for folder in CHECKED for f in sorted((ROOT / folder).rglob("*.py"))]
    assert len(files) > 100
    bad = [line for f in files for line in unmarked(f)]
    assert not bad, f"{len(bad)} function-level imports without a '# lazy: <reason>' comment (hoist them to the " \
                    "module's top, or say why not):\n" + "\n".join(bad)


def test_the_check_finds_an_unmarked_import(tmp_path):
    src = ("import os\n\n\ndef f():\n    import json  # lazy: only here\n    from edgetruth import errors\n"
           "    return json, errors, os\n")
    p = tmp_path / "m.py"
    found = unmarked(p, src)
    assert found == [f"{p}:6: from edgetruth import errors"]
    assert unmarked(p, "import json\n\n\ndef f():\n    return json\n") == []
