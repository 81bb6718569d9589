"""Fixtures shared by every test package."""
from __future__ import annotations

import shutil
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _check_install() -> None:
    """An editable install made before cli/ moved out of edgetruth/ cannot find ``edgetruth.cli``: say so once,
    not in every CLI test."""
    import importlib.util

    spec = importlib.util.find_spec("edgetruth.cli")
    if spec is None or not spec.origin or Path(spec.origin).resolve().parent != ROOT / "cli":
        pytest.exit(f"edgetruth.cli is not {ROOT / 'cli'} (found: {spec and spec.origin}): the editable install "
                    "is older than the package layout; run `make setup` (or `.venv/bin/python -m pip install "
                    "--no-deps -e .`)", returncode=4)


_check_install()


@pytest.fixture(scope="session")
def fast_variant() -> str:
    """The Mitsuba variant for tests that render full frames; skips them on scalar_rgb, where the
    Python distortion sensor runs once per sample (hours for these tests).  `make` installs the pip
    libLLVM that enables llvm_ad_rgb; `edgetruth.render.variants` says how when it is missing."""
    from edgetruth.render.variants import choose_variant

    v = choose_variant(announce=lambda s: None)
    if v.startswith("scalar"):
        pytest.skip("needs llvm_ad_rgb or cuda_ad_rgb (only scalar_rgb works here): install karellen-llvm-core "
                    "or libllvm >= 18")
    return v


@pytest.fixture(scope="session")
def tiny_dataset(tmp_path_factory) -> tuple[Path, Path]:
    """(spec path, dataset dir) of the 3-image tiny spec, rendered in-process; copy before changing."""
    from edgetruth.render.dataset.driver import render_spec
    from edgetruth.render.testing import write_tiny_spec

    root = tmp_path_factory.mktemp("tiny")
    spec = write_tiny_spec(root, spp=4)
    out = root / "data"
    render_spec(spec, out, progress=False, announce=lambda s: None)
    return spec, out


@pytest.fixture
def dataset_copy(tiny_dataset, tmp_path) -> tuple[Path, Path]:
    spec, out = tiny_dataset
    dst = tmp_path / "data"
    shutil.copytree(out, dst)
    return spec, dst


@pytest.fixture(autouse=True)
def _console_state():
    """Each test starts with the console's defaults (progress on, not quiet) and leaves them so: an
    in-process ``main([..., "--no-progress"])`` sets them for the whole process, and under pytest-xdist
    a worker's order of files is not the serial one."""
    from edgetruth import console

    saved = dict(console._state)
    console._state.update(quiet=False, progress=True)
    yield
    console._state.clear()
    console._state.update(saved)
