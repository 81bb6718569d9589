"""The repository's tools/ scripts as modules (test support): they are not packaged, so a test loads one from its
file."""
from __future__ import annotations

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def load_tool(relative_path: str, name: str):
    """The module at ``ROOT / relative_path`` (e.g. ``tools/device/prepare.py``), loaded as ``name``."""
    spec = importlib.util.spec_from_file_location(name, ROOT / relative_path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod
