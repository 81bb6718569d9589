"""The wheel is the product: built, installed non-editable into a clean virtual environment (a plain
`pip install`, nothing else) and run from a directory outside the checkout, it renders the `quick`
spec with the fast llvm_ad_rgb variant where the platform allows (its pip libLLVM comes as a
dependency) and locates points exactly as the checkout does, one image or a folder per call;
site-packages holds `edgetruth` only (no top-level render/locate/evaluate); and the numba kernels'
cache works from a read-only site-packages (a per-user folder instead). The wheel holds every package
and data file of the checkout, found with no hand-written list."""
from __future__ import annotations

import hashlib
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import venv
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


#: what this (checkout) process set or inherited must not help the installed wheel
CLEAN_ENV = {k: v for k, v in os.environ.items()
             if k not in ("DRJIT_LIBLLVM_PATH", "PYTHONPATH", "VIRTUAL_ENV") and not k.startswith("NUMBA_")}


def _run(cmd, cwd, timeout=900):
    r = subprocess.run([str(c) for c in cmd], cwd=cwd, capture_output=True, text=True, timeout=timeout,
                       env=CLEAN_ENV)
    assert r.returncode == 0, f"{cmd}\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}"
    return r


#: what the checkout holds that is no part of the product (the wheel is built from a copy without them)
NOT_SOURCE = (".venv", "build", "runs", ".git", "__pycache__", "*.egg-info", "results", ".pytest_cache", "*.nb[ic]",
              "*.py[cod]")
#: a sub-package and a data folder that only the copy the wheel is built from holds: found with no edit of
#: pyproject.toml or setup.py, they ship (package discovery, package data by glob)
PROBE_PACKAGE = Path("evaluate") / "board" / "wheel_probe_room"
PROBE_DATA = Path("assets") / "wheel_probe_set" / "nested"


def _setup_folders() -> dict[str, str]:
    """setup.py's FOLDERS (package -> source folder), read without running setup()."""
    import ast

    tree = ast.parse((ROOT / "setup.py").read_text())
    node = next(n for n in tree.body if isinstance(n, ast.Assign) and n.targets[0].id == "FOLDERS")
    return ast.literal_eval(node.value)


@pytest.fixture(scope="module")
def build_dir():
    """A folder of its own that other users may read (the read-only test runs as one)."""
    d = Path(tempfile.mkdtemp(prefix="edgetruth-wheel-"))
    d.chmod(0o755)
    try:
        yield d
    finally:
        subprocess.run(["chmod", "-R", "u+w", str(d)], capture_output=True)
        shutil.rmtree(d, ignore_errors=True)


@pytest.fixture(scope="module")
def wheel(build_dir) -> Path:
    # build from a copy: setuptools leaves build/ in the source tree, and stale files there would ship
    src = build_dir / "src"
    shutil.copytree(ROOT, src, ignore=shutil.ignore_patterns(*NOT_SOURCE))
    (src / PROBE_PACKAGE).mkdir()
    (src / PROBE_PACKAGE / "__init__.py").write_text('"""Only in the copy the wheel is built from."""\n')
    (src / PROBE_DATA).mkdir(parents=True)
    (src / PROBE_DATA / "probe.csv").write_text("a,b\n1,2\n")
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", build_dir / "wh", src], build_dir)
    wheels = list((build_dir / "wh").glob("edgetruth-*.whl"))
    assert len(wheels) == 1
    return wheels[0]


@pytest.fixture(scope="module")
def installed(build_dir, wheel):
    """(python of a clean venv with the wheel installed, a working directory outside the checkout)."""
    d = build_dir
    venv.create(d / "v", with_pip=True)
    py = d / "v" / "bin" / "python"
    _run([py, "-m", "pip", "install", "-q", "--disable-pip-version-check", wheel], d)  # that is all
    work = d / "elsewhere"
    work.mkdir()
    return py, work


def _checkout_files(folder: Path):
    """Every file under a source folder of the checkout, less what is no part of the product."""
    import fnmatch

    for f in sorted(folder.rglob("*")):
        rel = f.relative_to(ROOT).parts
        if f.is_file() and not any(fnmatch.fnmatch(p, pat) for p in rel for pat in NOT_SOURCE):
            yield f


def test_the_wheel_holds_every_package_module_and_data_file(wheel):
    """Every folder with an __init__.py under setup.py's source folders is a package of the wheel, every module
    and every data file (scenes/, assets/: TOML, JSON, images, text, licences) ships, the code folders ship no
    stray files, and a sub-package or data folder added with no edit of the packaging config ships too."""
    import zipfile

    names = set(zipfile.ZipFile(wheel).namelist())
    folders = _setup_folders()
    assert {"edgetruth", "edgetruth.render", "edgetruth.locate", "edgetruth.evaluate", "edgetruth.scenes",
            "edgetruth.assets"} <= set(folders)
    expected, packages = set(), set()
    for pkg, folder in folders.items():
        base = ROOT / folder
        for f in _checkout_files(base):
            if f.suffix == ".py" or folder in ("scenes", "assets"):
                expected.add("/".join([*pkg.split("."), *f.relative_to(base).parts]))
            if f.name == "__init__.py":
                packages.add(f.parent)
    missing = sorted(expected - names)
    assert not missing, f"{len(missing)} files of the checkout are not in the wheel: {missing[:20]}"
    assert len(packages) >= 23 and len([n for n in expected if not n.endswith(".py")]) >= 40
    shipped = {n for n in names if not n.startswith("edgetruth-") and n not in expected}
    probe = {"/".join(["edgetruth", *PROBE_PACKAGE.parts, "__init__.py"]),
             "/".join(["edgetruth", *PROBE_DATA.parts, "probe.csv"])}
    assert shipped == probe, f"the wheel holds files the checkout has not: {sorted(shipped - probe)}"


def _site(py, work) -> Path:
    r = _run([py, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], work)
    return Path(r.stdout.strip())


def test_site_packages_holds_one_namespace(installed):
    py, work = installed
    site = _site(py, work)
    assert (site / "edgetruth" / "render" / "dataset" / "spec.py").is_file()
    for stage in ("synthetic", "optics", "scene", "sensor", "dataset"):  # every sub-package is in the wheel
        assert (site / "edgetruth" / "render" / stage / "__init__.py").is_file(), stage
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
    from edgetruth.render.dataset.driver import render_spec

    py, work = installed
    edgetruth = py.parent / "edgetruth"
    # two of quick's 155 images: its first target image and the first board
    r = _run([edgetruth, "render", "quick", "--only", "0,15", "--no-progress"], work)
    out = work / "runs" / "render" / "quick"  # the default output: under the current directory
    assert (out / "manifest.json").is_file(), r.stdout
    wheel_ds = open_dataset(out)
    chosen = next(line for line in r.stdout.splitlines() if "Mitsuba variant" in line)
    print(chosen)  # e.g. "render: using Mitsuba variant llvm_ad_rgb"
    assert len(wheel_ds) == 2 and chosen.endswith("variant " + fast_variant)
    assert "warning" not in r.stderr, r.stderr  # no fallback note: nothing to install
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


@pytest.mark.skipif(not (sys.platform == "linux" and platform.machine() == "x86_64"),
                    reason="karellen-llvm-core has wheels for Linux x86_64 only")
def test_a_plain_install_brings_the_pip_libllvm(installed):
    py, work = installed
    r = _run([py, "-c", "from importlib.metadata import version as v; print(v('karellen-llvm-core'), "
                        "v('wheel-axle-runtime'))"], work)
    assert len(r.stdout.split()) == 2
    r = _run([py, "-c", "import os, edgetruth.render.variants as V; print(V.pip_libllvm_path()); "
                        "print(os.environ.get('DRJIT_LIBLLVM_PATH'))"], work)
    lib, env = r.stdout.split()
    assert Path(lib).is_file() and Path(lib).parent == py.parent.parent / "lib" and env == lib


def test_wheel_locates_a_folder_in_one_call(installed, tmp_path):
    import cv2
    import numpy as np

    py, work = installed
    edgetruth = py.parent / "edgetruth"
    shots = work / "shots"
    shots.mkdir(exist_ok=True)
    for i in range(3):
        img = np.full((48, 64), 200, np.uint8)
        img[:, 20 + 7 * i:] = 40
        cv2.imwrite(str(shots / f"s{i}.png"), cv2.GaussianBlur(img, (0, 0), 1.0))
    _run([edgetruth, "locate", shots, "-m", "glm1984", "-o", work / "each"], work)
    _run([edgetruth, "locate", str(shots / "s*.png"), "-m", "glm1984", "-o", work / "all.csv"], work)
    _run([edgetruth, "locate", shots / "s1.png", "-m", "glm1984", "-o", work / "one.csv"], work)
    assert (work / "each" / "s1.csv").read_bytes() == (work / "one.csv").read_bytes()
    rows = (work / "all.csv").read_text().splitlines()
    assert rows[0].startswith("image,x,y,") and len({r.split(",")[0] for r in rows[1:]}) == 3


def _as_other_user() -> list[str] | None:
    """A command prefix that drops root (a read-only folder stops no root process), [] when not root."""
    if os.geteuid() != 0:
        return []
    if not shutil.which("setpriv"):
        return None
    return ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups", "--"]


def test_numba_cache_from_a_read_only_site_packages(installed):
    """chmod -R a-w site-packages/edgetruth, a home that cannot be written either: locate runs twice, the
    first call compiles into the per-user folder under TMPDIR, the second loads from it."""
    import cv2
    import numpy as np

    prefix = _as_other_user()
    if prefix is None:
        pytest.skip("running as root without setpriv: cannot make a folder read-only to this process")
    py, work = installed
    site = _site(py, work) / "edgetruth"
    ro = work.parent / "ro"
    ro.mkdir()
    tmp = ro / "tmp"
    tmp.mkdir()
    tmp.chmod(0o1777)
    img = np.full((48, 64), 200, np.uint8)
    img[:, 30:] = 40
    cv2.imwrite(str(ro / "img.png"), cv2.GaussianBlur(img, (0, 0), 1.0))
    (ro / "img.png").chmod(0o644)
    _run(["chmod", "-R", "a-w", site], work)
    try:
        in_package = sorted(site.rglob("*.nb[ic]"))  # the root runs above may have cached there
        env = dict(CLEAN_ENV)
        env.update(HOME="/nonexistent", TMPDIR=str(tmp), NUMBA_DEBUG_CACHE="1", XDG_CACHE_HOME="/nonexistent/c")
        runs = []
        for k in range(2):
            r = subprocess.run([*prefix, str(py.parent / "edgetruth"), "locate", str(ro / "img.png"), "-o",
                                str(tmp / f"p{k}.csv")], cwd=tmp, env=env, capture_output=True, text=True, timeout=900)
            assert r.returncode == 0, r.stdout + r.stderr
            runs.append(r.stdout)
            assert not r.stderr.strip(), r.stderr  # a cache folder was found: no warning
        folder = [p for p in tmp.iterdir() if p.name.startswith("edgetruth-numba-")]
        assert len(folder) == 1 and list(folder[0].rglob("*.nbc")), runs[0]
        assert "data saved" in runs[0] and str(folder[0]) in runs[0]
        assert "data loaded" in runs[1] and "data saved" not in runs[1], runs[1]
        assert sorted(site.rglob("*.nb[ic]")) == in_package  # nothing was written into the package
        assert (tmp / "p0.csv").read_bytes() == (tmp / "p1.csv").read_bytes()
    finally:
        _run(["chmod", "-R", "u+w", site], work)


@pytest.mark.slow
def test_wheel_runs_the_board_study_on_the_shipped_real_photos(installed):
    """Zhang's photos, model and corners are package data: the board study runs from the wheel, from
    any folder, and its reference row (Zhang's own corners) gives his calibration."""
    import csv

    py, work = installed
    (work / "board").mkdir(exist_ok=True)
    _run([py.parent / "edgetruth", "study", "board", "zhang1998", "--methods", "canny_devernay,erf4p_fixed11",
          "-o", work / "board" / "zhang", "--no-progress"], work / "board")
    out = work / "board" / "zhang"
    report = (out / "report.md").read_text()
    assert "Zhang's corners" in report and "Canny" in report
    rows = {r["row"]: r for r in csv.DictReader(open(out / "summary.csv"))}
    ref = rows["zhang_corners"]
    assert abs(float(ref["calib_rms_px"]) - 0.337) <= 0.01 and abs(float(ref["fx"]) - 832.2) <= 1.0
    assert float(rows["canny_devernay"]["straightness_px"]) > 0
    # OpenCV's chessboard photos and their board.toml are package data too
    _run([py.parent / "edgetruth", "study", "board", "opencv_left", "--methods", "canny_devernay",
          "-o", work / "board" / "ocv", "--no-progress"], work / "board")
    rows = {r["row"]: r for r in csv.DictReader(open(work / "board" / "ocv" / "summary.csv"))}
    assert list(rows) == ["canny_devernay", "opencv_corners"]
    assert abs(float(rows["opencv_corners"]["fx"]) - 532.8) <= 5.0
