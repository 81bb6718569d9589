"""``edgetruth locate IMAGE... --method M -o OUT``: subpixel edge points of images -> CSV.

One IMAGE file: ``-o`` is its CSV.  Several images, a folder or a glob: ``-o DIR`` writes one
``<stem>.csv`` per image into DIR, ``-o FILE.csv`` one CSV with an ``image`` column first.  The
start-up (imports, plug-ins, the kernels' first call) is paid once per call, not per image.
Nothing is renamed into place until every image has been read and refined: a bad image leaves
what was there before untouched.
"""
from __future__ import annotations

import argparse
import csv
import glob
import io
import os
from collections import deque
from pathlib import Path

import numpy as np

from edgetruth import console, locate
from edgetruth.cli import METHOD_SYNTAX, add_image_options, add_plugin_option, add_progress_option
from edgetruth.errors import InputError
from edgetruth.evaluate import method_order as mo
from edgetruth.fileio import (atomic_write_text, check_input_file, check_output_dir, check_output_file, make_output_dir,
                              tmp_path)
from edgetruth.image_io import SUFFIXES, read_gray
from edgetruth.locate import thresholds as thr
from edgetruth.locate.registry import OPTION_SEP, format_option_value


BATCH_HELP = ("One IMAGE file: -o is its CSV file.  Several IMAGEs, a folder (its image files, sorted, "
              "not recursive) or a glob pattern (quoted: 'shots/*.png'; ** matches folders too): -o DIR "
              "writes one STEM.csv per image into DIR (created if missing), -o FILE.csv writes one CSV "
              "whose first column 'image' names each row's image (as given, or FOLDER/NAME).  Every image "
              "is read and refined before any file is renamed into place, so a bad image leaves the "
              "outputs as they were.")


def register(sub) -> None:
    p = sub.add_parser("locate", help="subpixel edge points of images -> CSV (one or many images per call)",
                       description="Canny candidates refined by METHOD; one CSV row per point "
                                   "(x, y in OpenCV pixel coordinates: pixel centres at integers; columns in "
                                   "docs/formats.md).  " + BATCH_HELP)
    p.add_argument("image", nargs="+", metavar="IMAGE",
                   help="image file (PNG/TIFF/JPEG 8/16-bit, EXR, .npy), gray or colour (see --channel), its EXIF "
                        "orientation honoured; or a folder of them, or a glob pattern; several may be given")
    p.add_argument("--method", "-m", default="dynamic_erf_4p", metavar="METHOD[:key=value...]",
                   help="method id (see `edgetruth methods`; default dynamic_erf_4p), with its options if wanted; "
                        + METHOD_SYNTAX + ", so `-m pae2013` gives the points `edgetruth evaluate` and the "
                        "studies compute, and `-m pae2013:variant=floating` the method's own default.  The "
                        "options that ran are printed")
    p.add_argument("-o", "--output", required=True,
                   help="one IMAGE: the CSV file to write; several: a folder (one STEM.csv per image) or a "
                        "FILE.csv (all points, with an image column); written atomically")
    p.add_argument("--sigma", type=float, default=1.0, help="Gaussian smoothing for candidates/normals, px")
    p.add_argument("--low", type=float, default=None, help="Canny low threshold, gray levels/px")
    p.add_argument("--high", type=float, default=None, help="Canny high threshold, gray levels/px")
    p.add_argument("--thresholds", default=None,
                   help="entropy-thresholds JSON (from `edgetruth calibrate-thresholds`) for dynamic_erf_*")
    add_image_options(p)
    add_plugin_option(p)
    add_progress_option(p)
    p.set_defaults(handler=run)


def is_pattern(text: str) -> bool:
    return any(ch in text for ch in "*?[")


def expand_images(refs: list[str]) -> tuple[list[tuple[str, Path]], bool]:
    """([(name, path)], batch): the images ``refs`` name, in order, each once; ``batch`` is True unless
    ``refs`` is a single file (then ``-o`` is that file's CSV).  A ref is a file, a folder (its image
    files by name, not recursive) or a glob pattern (its image files, sorted)."""
    kinds = ", ".join(SUFFIXES)
    found: list[tuple[str, Path]] = []
    batch = len(refs) > 1
    for ref in refs:
        p = Path(ref)
        if p.is_dir():
            batch = True
            files = sorted(f for f in p.iterdir() if f.suffix.lower() in SUFFIXES and f.is_file())
            if not files:
                raise InputError(f"{ref}: is a directory with no image files in it ({kinds}); give image files, "
                                 "or a folder or pattern that holds some")
            found += [(os.path.join(ref, f.name), f) for f in files]
        elif not p.exists() and not p.is_symlink() and is_pattern(ref):
            batch = True
            files = [m for m in sorted(glob.glob(ref, recursive=True))
                     if Path(m).suffix.lower() in SUFFIXES and Path(m).is_file()]
            if not files:
                raise InputError(f"{ref}: no image file matches this pattern ({kinds}); check the pattern")
            found += [(m, Path(m)) for m in files]
        else:
            found.append((ref, check_input_file(p, "image")))
    seen, out = set(), []
    for name, path in found:
        key = os.path.realpath(path)
        if key not in seen:
            seen.add(key)
            out.append((name, path))
    return out, batch


def plan_outputs(images: list[tuple[str, Path]], output: str) -> tuple[Path, list[Path] | None]:
    """(the output, None: one combined CSV | one CSV path per image), every path checked, nothing written."""
    inputs = [p for _, p in images]
    out = Path(output)
    if output.lower().endswith(".csv") and not out.is_dir():
        return check_output_file(out, "-o", inputs=inputs), None
    out = check_output_dir(out, "-o")
    targets, owner = [], {}
    for name, path in images:
        t = out / f"{path.stem}.csv"
        if t.name in owner:
            raise InputError(f"-o {out}: {owner[t.name]} and {name} would both write {t}; write one CSV with an "
                             f"image column instead (-o {out / 'points.csv'}) or rename one of the images")
        owner[t.name] = name
        targets.append(check_output_file(t, "-o", inputs=inputs, make_parents=True))
    return out, targets


def csv_cells(pts) -> tuple[list[str], list[list[str]]]:
    """(column names, one list of formatted cells per column): the text ``EdgePoints.to_csv`` writes
    (ints as ints, floats by ``repr``), made column by column."""
    names, cells = [], []
    for name, col in pts.columns().items():
        a = np.asarray(col)
        names.append(name)
        if a.dtype.kind in "biu":
            cells.append(list(map(str, a.astype(np.int64).tolist())))
        else:
            cells.append(list(map(repr, a.astype(np.float64).tolist())))
    return names, cells


def csv_text(names: list[str], cells: list[list[str]], image: str | None = None) -> str:
    """Rows (no header) of ``cells``; with ``image``, that (CSV-quoted) first on every row."""
    if not cells or not cells[0]:
        return ""
    rows = [",".join(r) for r in zip(*cells)]
    if image is None:
        return "\n".join(rows) + "\n"
    lead = _quote(image) + ","
    return "".join(lead + r + "\n" for r in rows)


def _quote(text: str) -> str:
    buf = io.StringIO()
    csv.writer(buf, lineterminator="").writerow([text])
    return buf.getvalue()


def method_and_options(spec: str) -> tuple[str, dict]:
    """``-m METHOD[:key=value...]`` -> (method id, the options it runs with): the studies' options for it
    (``method_order.STUDY_OPTIONS``) overridden by the spec's own, every one checked first."""
    labels = mo.method_specs(spec)
    if not labels or len(labels) != 1:
        raise InputError(f"-m {spec!r}: give one method, METHOD[:key=value...] (for several, call locate once "
                         "per method)")
    return mo.resolve(labels[0], mo.STUDY_OPTIONS)


def options_note(method: str, options: dict, spec: str) -> str | None:
    """The line that says which options ran (None: the method's own defaults, none given)."""
    shown = {k: v for k, v in options.items() if k != "tau"}
    if not shown:
        return None
    study = mo.STUDY_OPTIONS.get(method, {})
    from_study = [k for k in shown if k in study and study[k] == shown[k] and f"{k}=" not in spec]
    text = ", ".join(f"{k}={format_option_value(v)}" for k, v in shown.items())
    note = (f" ({', '.join(from_study)}: the studies' choice, STUDY_OPTIONS; set it with -m "
            f"{method}{OPTION_SEP}{from_study[0]}=VALUE)") if from_study else ""
    return f"{method} ran with {text}{note}"


def run(args: argparse.Namespace) -> int:
    method, options = method_and_options(args.method)
    if locate.METHODS[method].needs_camera and "esf" not in options:
        raise InputError(f"-m {method}: it needs the camera's model (its edge-spread tables), which a photo alone does "
                         "not give; it runs in the render studies (edgetruth run, edgetruth evaluate on renders) -- "
                         "on photos use patch_psf_fit, which fits the PSF's scale itself")
    images, batch = expand_images(args.image)
    if args.thresholds is not None:
        if not method.startswith("dynamic_erf_"):
            raise InputError(f"--thresholds applies to dynamic_erf_2p/4p only, not {method}")
        options["tau"] = thr.load(method[-2:], args.thresholds)
    args.method, args.method_label = method, args.method
    if not batch:
        name, path = images[0]
        out = check_output_file(args.output, "-o", inputs=[path])
        pts = _points(name, path, args, options)
        names, cells = csv_cells(pts)
        try:
            atomic_write_text(out, ",".join(names) + "\n" + csv_text(names, cells))  # = pts.to_csv(out), faster
        except OSError as exc:
            raise InputError(f"-o {out}: cannot write ({exc.strerror}); choose a writable location") from exc
        console.say(f"{len(pts)} points ({int(pts.converged.sum())} converged) -> {out}")
        _say_options(args, options)
        return 0
    out, targets = plan_outputs(images, args.output)
    n_pts, n_conv = _write_batch(images, targets, out, args, options)
    where = f"{len(images)} CSV files in {out}" if targets is not None else str(out)
    console.say(f"{len(images)} images, {n_pts} points ({n_conv} converged) -> {where}")
    _say_options(args, options)
    return 0


def _say_options(args, options: dict) -> None:
    note = options_note(args.method, options, args.method_label)
    if note:
        console.say(note)


def _points(name: str, path: Path, args, options):
    img = read_gray(path, channel=args.channel)
    try:
        return locate.locate(img, args.method, sigma_px=args.sigma, low=args.low, high=args.high, **options)
    except InputError as exc:
        raise InputError(f"{name}: {exc}") from exc


#: from this many images on, a second process makes the CSV text (its start-up, ~0.3 s, then pays)
POOL_FROM_IMAGES = 12


def csv_block(columns: dict, image: str | None = None) -> tuple[list[str], str]:
    """(column names, the CSV rows of ``columns``, with ``image`` first on every row if given): what a
    batch writes for one image, a pure function of plain arrays (it runs in the formatting process)."""
    class _Cols:
        def columns(self):
            return columns

    names, cells = csv_cells(_Cols())
    return names, csv_text(names, cells, image=image)


class _InlineFuture:
    def __init__(self, value):
        self.value = value

    def result(self):
        return self.value


def _formatter(n_images: int):
    """A process pool of one for the CSV text of a long batch (None: format inline).  Python's ``repr``
    of every float takes as long as the refinement itself and holds the interpreter lock, so only a
    second process overlaps it with the next image's work."""
    if n_images < POOL_FROM_IMAGES:
        return None
    import multiprocessing as mp  # lazy: multiprocessing only for pools
    from concurrent.futures import ProcessPoolExecutor  # lazy: only for pools

    try:
        return ProcessPoolExecutor(1, mp_context=mp.get_context("spawn"))
    except (OSError, ValueError):  # no processes here (a sandbox): inline
        return None


def _write_batch(images, targets, out: Path, args, options) -> tuple[int, int]:
    """Refine every image into temporary files next to the outputs; rename them into place only when all
    are done (on any error or interrupt the temporary files go and nothing else is touched).  The CSV
    text of image k is made (by a second process on long batches: ``_formatter``) while image k + 1 is
    read and refined, and written in image order, so the files are those of the one-by-one loop."""
    temps: list[Path] = []
    n_pts = n_conv = 0
    combined = None
    made_dir = targets is not None and not out.exists()
    pending: deque = deque()
    header = None
    pool = None

    def write_next() -> None:
        nonlocal header
        k, name, n, future = pending.popleft()
        names, text = future.result()
        if combined is None:
            with open(temps[k], "w", encoding="utf-8", newline="") as fh:
                fh.write(",".join(names) + "\n" + text)
        elif n:
            if header is None:
                header = names
                combined.write(",".join(["image", *names]) + "\n")
            elif names != header:
                raise InputError(f"{name}: method {args.method} gave columns {', '.join(names)}, not "
                                 f"those of the images before it ({', '.join(header)}); write one CSV per "
                                 "image instead (-o DIR)")
            combined.write(text)

    try:
        if targets is not None:
            make_output_dir(out, "-o")
            temps += [tmp_path(t) for t in targets]
        else:
            temps.append(tmp_path(out))
            combined = open(temps[0], "w", encoding="utf-8", newline="")
        pool = _formatter(len(images))
        with console.bar(total=len(images), desc="locate", unit="img", enabled=not args.no_progress) as bar:
            for k, (name, path) in enumerate(images):
                pts = _points(name, path, args, options)
                n_pts += len(pts)
                n_conv += int(pts.converged.sum())
                cols = {c: np.asarray(v) for c, v in pts.columns().items()}
                image = None if combined is None else name
                future = pool.submit(csv_block, cols, image) if pool else _InlineFuture(csv_block(cols, image))
                pending.append((k, name, len(pts), future))
                while len(pending) > 1:  # one image in flight: memory stays flat
                    write_next()
                bar.update(1)
        while pending:
            write_next()
        if combined is not None:
            if header is None:  # no image had a point: the header of an empty result
                combined.write("image,x,y,nx,ny,converged\n")
            combined.close()
            os.replace(temps[0], out)
        else:
            for t, target in zip(temps, targets):
                os.replace(t, target)
        temps = made_dir = None
    except OSError as exc:
        raise InputError(f"-o {out}: cannot write ({exc.strerror}); choose a writable location") from exc
    finally:
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)
        if combined is not None and not combined.closed:
            combined.close()
        for t in temps or ():
            try:
                t.unlink()
            except OSError:
                pass
        if made_dir:  # a folder this call created for outputs it did not write
            try:
                out.rmdir()
            except OSError:
                pass
    return n_pts, n_conv
