"""The wheel is the product: built, installed non-editable into a clean virtual environment and run
from a directory outside the checkout, it renders the `quick` spec and locates points exactly as the
checkout does; site-packages holds `edgetruth` only (no top-level render/locate/evaluate)."""
from __future__ import annotations

import hashlib
import shutil
import subprocess
import sys
import venv
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.slow


def _run(cmd, cwd, timeout=900):
    r = subprocess.run([str(c) for c in cmd], cwd=cwd, capture_output=True, text=True, timeout=timeout)
    assert r.returncode == 0, f"{cmd}\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}"
    return r


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """(python of a clean venv with the wheel installed, a working directory outside the checkout)."""
    d = tmp_path_factory.mktemp("wheel")
    # build from a copy: setuptools leaves build/ in the source tree, and stale files there would ship
    src = d / "src"
    shutil.copytree(ROOT, src, ignore=shutil.ignore_patterns(".venv", "build", "runs", ".git", "__pycache__",
                                                             "*.egg-info", "results", ".pytest_cache", "*.nb[ic]"))
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", d / "wh", src], d)
    wheels = list((d / "wh").glob("edgetruth-*.whl"))
    assert len(wheels) == 1
    venv.create(d / "v", with_pip=True)
    py = d / "v" / "bin" / "python"
    _run([py, "-m", "pip", "install", "-q", "--disable-pip-version-check", wheels[0]], d)
    # the optional speed-up `make` installs, so both sides render with the same Mitsuba variant
    subprocess.run([py, "-m", "pip", "install", "-q", "--disable-pip-version-check", "karellen-llvm-core"],
                   cwd=d, capture_output=True, timeout=900)
    work = d / "elsewhere"
    work.mkdir()
    return py, work


def test_site_packages_holds_one_namespace(installed):
    py, work = installed
    r = _run([py, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], work)
    site = Path(r.stdout.strip())
    assert (site / "edgetruth" / "render" / "spec.py").is_file()
    assert (site / "edgetruth" / "scenes" / "quick.toml").is_file()
    assert (site / "edgetruth" / "assets" / "entropy_thresholds.json").is_file()
    assert (site / "edgetruth" / "assets" / "cameras" / "default.toml").is_file()
    for name in ("render", "locate", "evaluate", "scenes", "assets"):
        assert not (site / name).exists(), f"top-level {name} in site-packages"
    r = _run([py, "-c", "import importlib.util as u; print([m for m in ('render', 'locate', 'evaluate') "
                        "if u.find_spec(m)])"], work)
    assert r.stdout.strip() == "[]"
    r = _run([py, "-m", "edgetruth", "--version"], work)
    from edgetruth import __version__

    assert r.stdout.strip() == f"edgetruth {__version__}"


def test_wheel_renders_and_locates_exactly_like_the_checkout(installed, tmp_path, fast_variant):
    from edgetruth import locate
    from edgetruth.image_io import read_gray
    from edgetruth.render import open_dataset
    from edgetruth.render.driver import render_spec

    py, work = installed
    edgetruth = py.parent / "edgetruth"
    # two of quick's 155 images: its first target image and the first board
    r = _run([edgetruth, "render", "quick", "--only", "0,15", "--no-progress"], work)
    out = work / "runs" / "render" / "quick"  # the default output: under the current directory
    assert (out / "manifest.json").is_file(), r.stdout
    wheel_ds = open_dataset(out)
    assert len(wheel_ds) == 2 and "variant " + fast_variant in r.stdout
    first = wheel_ds.targets()[0]
    _run([edgetruth, "locate", out / f"{first.name}.png", "-m", "dynamic_erf_4p", "-o", work / "pts.csv"], work)

    mine = tmp_path / "checkout"
    render_spec("quick", mine, only=[first.index], progress=False, announce=lambda s: None)
    here = open_dataset(mine)[first.name]
    for ext in ("png", "exr", "json"):
        a = hashlib.sha256((out / f"{first.name}.{ext}").read_bytes()).hexdigest()
        b = hashlib.sha256((mine / f"{first.name}.{ext}").read_bytes()).hexdigest()
        assert a == b, f"{first.name}.{ext} differs between the wheel and the checkout"
    pts = locate.locate(read_gray(mine / f"{first.name}.png"), "dynamic_erf_4p")
    pts.to_csv(tmp_path / "pts.csv")
    assert (work / "pts.csv").read_bytes() == (tmp_path / "pts.csv").read_bytes()
    assert len(pts) > 100 and here.kind == "target"
