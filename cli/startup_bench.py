"""Start-up costs of the command line, measured as a user meets them: fresh interpreters (subprocesses).

Figures (medians of ``repeats`` runs, all measured in this one run, targets from issue 21):

- ``edgetruth --version``: wall time of the whole command (target <= 0.3 s);
- ``import edgetruth.locate``: the import alone, timed inside a fresh interpreter (target <= 0.5 s),
  and the interpreter's own start for reference;
- ``edgetruth locate`` on 100 images (640 x 512 PNG) in one call, against the sum of the per-image
  method times (read + Canny + refinement, timed in this process after a warm-up) plus one
  start-up (a one-image call's wall time less that image's own work): target ratio <= 1.2.  On
  frames like the renders' (one target); edge-dense frames are shown too, with the time the CSV
  text takes (Python's ``repr`` of every float: as long as the method itself there).

The kernels' on-disk cache is warmed first (one untimed call), as it is for any user after the
first run.
"""
from __future__ import annotations

import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from edgetruth import locate
from edgetruth.cli.commands.locate import csv_cells, csv_text
from edgetruth.image_io import read_gray


N_IMAGES = 100
SHAPE = (512, 640)
METHOD = "dynamic_erf_4p"
TARGETS = {"version": 0.3, "import": 0.5, "batch_ratio": 1.2}


def _wall(cmd: list[str], cwd: Path) -> float:
    t0 = time.perf_counter()
    r = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    dt = time.perf_counter() - t0
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({r.returncode}): {r.stderr.strip()[-400:]}")
    return dt


def _median(f, repeats: int) -> float:
    return statistics.median(f() for _ in range(repeats))


def _import_time(module: str, cwd: Path) -> float:
    code = f"import time; t = time.perf_counter(); import {module}; print(time.perf_counter() - t)"
    r = subprocess.run([sys.executable, "-c", code], cwd=cwd, capture_output=True, text=True, check=True)
    return float(r.stdout.strip())


def frame(seed: int, shape=SHAPE, dense: bool = False):
    """A 640 x 512 8-bit test frame: a dark rotated square on a light board (as a rendered target frame),
    or with ``dense`` a 5 x 4 grid of dark and light discs (every edge orientation, ~4x the edge
    pixels); blurred (sigma 0.8-1.5 px) with noise sigma 2 gray levels.  Drawn with OpenCV (1/16 px
    vertices): timing needs realistic edges, not exact truth."""
    rng = np.random.default_rng(seed)
    h, w = shape
    img = np.full(shape, 190.0)
    shift = 4
    if dense:
        tile = min(h // 4, w // 5)
        for r in range(4):
            for c in range(5):
                centre = (int(16 * ((c + 0.5) * w / 5 + rng.uniform(-2, 2))), int(16 * ((r + 0.5) * h / 4
                                                                                        + rng.uniform(-2, 2))))
                cv2.circle(img, centre, int(16 * rng.uniform(0.25, 0.4) * tile), float(rng.choice([40.0, 250.0])),
                           -1, cv2.LINE_AA, shift)
    else:
        side = rng.uniform(0.25, 0.45) * h
        a = rng.uniform(0, np.pi / 2)
        cx, cy = w / 2 + rng.uniform(-0.15, 0.15) * w, h / 2 + rng.uniform(-0.1, 0.1) * h
        corners = [(cx + side / 2 * (np.cos(a + k * np.pi / 2) - np.sin(a + k * np.pi / 2)),
                    cy + side / 2 * (np.sin(a + k * np.pi / 2) + np.cos(a + k * np.pi / 2))) for k in range(4)]
        cv2.fillPoly(img, [np.round(16 * np.array(corners)).astype(np.int32)], 35.0, cv2.LINE_AA, shift)
    img = cv2.GaussianBlur(img, (0, 0), rng.uniform(0.8, 1.5))
    img += rng.normal(0.0, 2.0, size=img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def write_images(folder: Path, n: int = N_IMAGES, dense: bool = False, distinct: int = 10) -> list[Path]:
    """``n`` PNG frames (``distinct`` different ones, repeated under new names)."""
    folder.mkdir(parents=True, exist_ok=True)
    frames = [frame(1000 + i, dense=dense) for i in range(min(n, distinct))]
    paths = []
    for i in range(n):
        p = folder / f"img{i:03d}.png"
        cv2.imwrite(str(p), frames[i % len(frames)])
        paths.append(p)
    return paths


def method_times(paths: list[Path], method: str = METHOD) -> tuple[list[float], list[float]]:
    """Per image, in this process (warmed up: kernels compiled): (read + Canny + refinement, formatting
    and writing its CSV as ``edgetruth locate`` does)."""
    locate.locate(read_gray(paths[0]), method)
    work, csv = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for p in paths:
            t0 = time.perf_counter()
            pts = locate.locate(read_gray(p), method)
            t1 = time.perf_counter()
            names, cells = csv_cells(pts)
            (Path(tmp) / "p.csv").write_text(",".join(names) + "\n" + csv_text(names, cells))
            work.append(t1 - t0)
            csv.append(time.perf_counter() - t1)
    return work, csv


def _batch_lines(cli, work: Path, label: str, dense: bool, n_images: int, repeats: int) -> list[str]:
    """Rounds of: the per-image work in this process, a one-image call, the batch call with -o DIR and with
    -o FILE.csv, back to back; ratios per round, then their median (the machine's load may change between
    rounds, hardly within one)."""
    folder = work / label
    paths = write_images(folder, n_images, dense=dense)
    _wall([*cli, "locate", str(paths[0]), "-m", METHOD, "-o", str(work / "warm.csv")], work)  # the numba cache
    rounds = []
    for _ in range(max(1, min(repeats, 3))):
        per_image, per_csv = method_times(paths)
        one = _wall([*cli, "locate", str(paths[0]), "-m", METHOD, "-o", str(work / "one.csv")], work)
        walls = [_wall([*cli, "locate", str(folder), "-m", METHOD, "-o", str(out)], work)
                 for out in (work / f"{label}-out", work / f"{label}-all.csv")]
        methods_s, csv_s = sum(per_image), sum(per_csv)
        startup = max(one - per_image[0] - per_csv[0], 0.0)
        rounds.append((methods_s, csv_s, one, startup, walls))
    med = statistics.median
    methods_s, csv_s = med(r[0] for r in rounds), med(r[1] for r in rounds)
    one, startup = med(r[2] for r in rounds), med(r[3] for r in rounds)
    lines = [f"edgetruth locate, {n_images} {label} {SHAPE[1]}x{SHAPE[0]} PNGs ({METHOD}): per image "
             f"{1e3 * methods_s / n_images:.1f} ms read + Canny + refinement, {1e3 * csv_s / n_images:.1f} ms its CSV; "
             f"start-up {startup:.2f} s (a one-image call: {one:.2f} s); {n_images} one-image calls would take "
             f"~{n_images * one:.0f} s (medians of {len(rounds)} rounds)"]
    for k, how in enumerate(("-o DIR", "-o FILE.csv")):
        ratio = med(r[4][k] / (r[0] + r[3]) for r in rounds)
        with_csv = med(r[4][k] / (r[0] + r[1] + r[3]) for r in rounds)
        ok = "ok" if ratio <= TARGETS["batch_ratio"] else "ABOVE TARGET"
        lines.append(f"  one call, {how}: {med(r[4][k] for r in rounds):.2f} s = {ratio:.2f} x (sum of method times "
                     f"+ one start-up), target <= {TARGETS['batch_ratio']}: {ok}; {with_csv:.2f} x with the CSV "
                     "writing counted (median per-round ratios)")
    return lines


def run_bench(repeats: int = 5, n_images: int = N_IMAGES) -> list[str]:
    cli = [sys.executable, "-m", "edgetruth"]
    lines = []
    with tempfile.TemporaryDirectory(prefix="edgetruth-startup-") as tmp:
        work = Path(tmp)
        # --version and the import: fresh interpreters, from a folder outside any checkout
        bare = _median(lambda: _wall([sys.executable, "-c", "pass"], work), repeats)
        version = _median(lambda: _wall([*cli, "--version"], work), repeats)
        imp = _median(lambda: _import_time("edgetruth.locate", work), repeats)
        ok = version <= TARGETS["version"]
        lines.append(f"edgetruth --version: {version:.3f} s (python itself {bare:.3f} s), median of {repeats}; "
                     f"target <= {TARGETS['version']} s: {'ok' if ok else 'ABOVE TARGET'}")
        ok = imp <= TARGETS["import"]
        lines.append(f"import edgetruth.locate: {imp:.3f} s in a fresh interpreter, median of {repeats}; "
                     f"target <= {TARGETS['import']} s: {'ok' if ok else 'ABOVE TARGET'}")
        # locate: n images in one call vs the method times + one start-up; frames like the renders' (the
        # target), and edge-dense ones, where writing the CSV (repr of every float) costs as much as the method
        lines += _batch_lines(cli, work, "frames", False, n_images, repeats)
        lines += _batch_lines(cli, work, "dense", True, n_images, repeats)
    return lines
