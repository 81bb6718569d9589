"""Shared fixtures for the CLI tests: a tiny rendered dataset (rendered once per session)."""
from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

import pytest


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


@pytest.fixture(scope="session")
def tiny_dataset(tmp_path_factory) -> tuple[Path, Path]:
    """(spec path, dataset dir) of the 3-image tiny spec, rendered in-process; copy before changing."""
    from edgetruth.render.driver import render_spec
    from edgetruth.render.testing import write_tiny_spec

    root = tmp_path_factory.mktemp("tiny")
    spec = write_tiny_spec(root, spp=8)
    out = root / "data"
    render_spec(spec, out, progress=False, announce=lambda s: None)
    return spec, out


@pytest.fixture
def dataset_copy(tiny_dataset, tmp_path) -> tuple[Path, Path]:
    spec, out = tiny_dataset
    dst = tmp_path / "data"
    shutil.copytree(out, dst)
    return spec, dst
