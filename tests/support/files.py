"""File-tree helpers for tests."""
from __future__ import annotations

import hashlib
from pathlib import Path


def tree_hash(root: Path) -> dict:
    """{relative path: sha256 or 'dir'} of everything under ``root`` (missing root -> {})."""
    root = Path(root)
    if not root.exists():
        return {}
    if root.is_file():
        return {".": hashlib.sha256(root.read_bytes()).hexdigest()}
    out = {}
    for p in sorted(root.rglob("*")):
        out[str(p.relative_to(root))] = "dir" if p.is_dir() else hashlib.sha256(p.read_bytes()).hexdigest()
    return out
