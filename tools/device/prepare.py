"""Wheels for the GPU check (``tools/device/gpu_check.sh``), into ``.whl/`` at the repository root.

The device machine (docs/gpu.md) is bare of Mitsuba, Dr.Jit and OpenEXR and reaches no package index, and
the working tree plus what it carries must stay under 64 MiB.  Mitsuba's wheel alone is 62.5 MB, so this
writes a copy without what the check cannot use: the mono and spectral variants' modules, the C++
headers and a few large plug-ins no edgetruth scene names (volumes, sky models, curves, SDFs).  The RGB
variants (cuda_ad_rgb, llvm_ad_rgb, scalar_rgb) are kept whole.  edgetruth itself travels as its own
wheel, so the device runs what ``pip install`` gives, not the checkout.

    python3 tools/device/prepare.py [--python-version 3.12]   # the device's python (KINDS.md)
"""
from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / ".whl"
LIMIT_B = 64 * 2 ** 20  # what may travel to the device, working tree included
# The versions this checkout's venv runs (pyproject pins only lower bounds); the device has numpy, scipy,
# numba, OpenCV, matplotlib, tqdm, tabulate and cloudpickle of its own.
CARRIED = ("mitsuba", "drjit", "OpenEXR")
PLATFORMS = ("manylinux_2_28_x86_64", "manylinux_2_27_x86_64", "manylinux_2_17_x86_64", "manylinux2014_x86_64")
# Mitsuba files the check never loads: other colour modes' variant modules, headers, and plug-ins for
# participating media, sky models, curves, ellipsoids and SDF grids (edgetruth's scenes name none of them).
DROP = re.compile(r"^mitsuba/(include/"
                  r"|(scalar|llvm_ad|cuda_ad)_(mono|spectral)\w*\.cpython-[^/]*\.so$"
                  r"|plugins/(volpath\w*|prbvolpath\w*|\w*sunsky|ellipsoids\w*|bsplinecurve|linearcurve"
                  r"|sdfgrid|catmullrom|bezier)\.so$"
                  r"|data/sunsky/)")


def installed_version(name: str) -> str:
    from importlib import metadata

    return metadata.version(name)


def download(names: list[str], python_version: str, dest: Path) -> None:
    cmd = [sys.executable, "-m", "pip", "download", "-q", "--no-deps", "--only-binary=:all:", "--python-version",
           python_version, "--implementation", "cp", "-d", str(dest)]
    for p in PLATFORMS:
        cmd += ["--platform", p]
    subprocess.run(cmd + names, check=True)


def prune_wheel(src: Path, dst: Path) -> tuple[int, int]:
    """Copy the wheel ``src`` to ``dst`` without the files ``DROP`` matches (RECORD rewritten to match):
    (files dropped, bytes saved)."""
    dropped = []
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zout:
        for info in zin.infolist():
            if DROP.match(info.filename):
                dropped.append(info.filename)
                continue
            data = zin.read(info)
            if info.filename.endswith(".dist-info/RECORD"):
                gone = set(dropped) | {i.filename for i in zin.infolist() if DROP.match(i.filename)}
                data = "".join(l + "\n" for l in data.decode().splitlines() if l.split(",")[0] not in gone).encode()
            zout.writestr(info, data)
    return len(dropped), src.stat().st_size - dst.stat().st_size


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--python-version", default="3.12", help="the device's python (default 3.12)")
    args = ap.parse_args(argv)
    shutil.rmtree(OUT, ignore_errors=True)
    OUT.mkdir()
    with tempfile.TemporaryDirectory() as tmp:
        raw = Path(tmp)
        download([f"{n}=={installed_version(n)}" for n in CARRIED], args.python_version, raw)
        for whl in sorted(raw.glob("*.whl")):
            if whl.name.lower().startswith("mitsuba-"):
                n, saved = prune_wheel(whl, OUT / whl.name)
                print(f"{whl.name}: {n} files left out, {saved / 1e6:.1f} MB smaller")
            else:
                shutil.copy2(whl, OUT / whl.name)
    build = Path(tempfile.mkdtemp())
    try:  # edgetruth's own wheel, built from this tree as a user's pip would
        subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(OUT), str(ROOT)],
                       check=True, cwd=build)
    finally:
        shutil.rmtree(build, ignore_errors=True)
        shutil.rmtree(ROOT / "build", ignore_errors=True)  # setuptools leaves one in the tree
    tracked = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"], cwd=ROOT,
                             capture_output=True, check=True).stdout.split(b"\0")
    tree_b = sum((ROOT / f.decode()).stat().st_size for f in tracked if f and (ROOT / f.decode()).is_file())
    whl_b = sum(p.stat().st_size for p in OUT.glob("*.whl"))
    for p in sorted(OUT.glob("*.whl")):
        print(f"  {p.stat().st_size / 2 ** 20:6.1f} MiB  {p.name}")
    total = tree_b + whl_b
    print(f"travels: {tree_b / 2 ** 20:.1f} MiB tree + {whl_b / 2 ** 20:.1f} MiB wheels = {total / 2 ** 20:.1f} MiB "
          f"of {LIMIT_B / 2 ** 20:.0f}")
    if total > LIMIT_B:
        print("too large for the device: leave more out (DROP)", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
