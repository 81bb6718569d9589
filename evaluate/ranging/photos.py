"""Ranging on real photos: a distances CSV, a calibration, and every method against a reference distance.

``edgetruth evaluate --photos DIR --distances FILE.csv --calibration FILE|DIR``.  A photo has no
ground-truth JSON: what the experimenter knows is written in the CSV (docs/formats.md, "Distances
CSV for real photos"), one row per photo:

``image``        the photo, relative to ``--photos DIR`` (looked up first) or to the CSV's folder, or absolute
``distance_cm``  the reference distance: Z of the target's centre in the camera frame, i.e. along the
                 optical axis from the camera's centre of projection (for a target square-on to the
                 camera: the distance to the target plane) -- the quantity a render's
                 ``true_distance_m`` holds and Z = fx·S/l estimates
``size_m``       square side, circle diameter, rectangle width (its horizontal side in the photo)
``height_m``     rectangles only, optional: the vertical side (for the pose and a 90-degree check)
``shape``        square | circle | rectangle
``group``        free text: the per-group table's grouping
``polarity``     optional: dark (target darker than its surroundings) | light | auto (default)
``note``         optional free text, ignored

Every row is checked (and every photo decoded, its size compared with the calibration's) before
anything is written; a bad row is one line naming the CSV's line.  Each photo is then read as the
other commands read photos (``edgetruth.image_io.read_gray``, ``--channel``), undistorted with the
calibration, its target found (``target_finding``, the row's polarity), its boundary refined by
every method on the same candidates, sized and ranged (``ranging.range_undistorted``, the code the
renders go through), and the errors e = Z_hat - distance go into the same tables, paired tests and
verdicts as a render study's (``ranging_report.write_report``).  There is no per-point truth.
"""
from __future__ import annotations

import csv
import dataclasses
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from edgetruth import console, locate
from edgetruth.errors import InputError
from edgetruth.evaluate import method_order as mo
from edgetruth.evaluate.calibration import Calibration
from edgetruth.evaluate.design import REFERENCE_METHOD, interval_label
from edgetruth.evaluate.ranging.focal_length import apply_fx, reference_fx
from edgetruth.evaluate.ranging.images import (SHAPES, UNDISTORT_LINES, ImageResult, check_undistort, range_undistorted,
                                               write_rows)
from edgetruth.evaluate.ranging.overlays import overlay_name, write_photo_overlay
from edgetruth.evaluate.ranging.report import write_report
from edgetruth.evaluate.ranging.undistort import from_calibration
from edgetruth.evaluate.report_format import num, table
from edgetruth.fileio import check_input_file, write_json
from edgetruth.image_io import SUFFIXES, read_gray
from edgetruth.locate import plugins


REQUIRED_COLUMNS = ("image", "distance_cm", "size_m", "shape", "group")
OPTIONAL_COLUMNS = ("height_m", "polarity", "roi_px", "point_px", "reference", "note")
PHOTO_POLARITIES = ("dark", "light", "auto")
#: a physical size above this is almost surely centimetres typed into a metres column
MAX_SIZE_M = 10.0
#: what the errors of a photo set are measured against (the report says it)
REFERENCE = ("the CSV's reference distances (distance_cm: Z of the target centre along the optical axis, "
             "measured by the experimenter)")


@dataclass(frozen=True)
class PhotoRecord:
    """One row of the distances CSV, checked."""

    line: int  # line of the CSV (the header is line 1)
    image: str  # as written in the CSV (the row's name in every table)
    path: str  # the file it resolved to
    distance_cm: float
    size_m: float
    shape: str
    group: str
    polarity: str = "auto"
    height_m: float | None = None
    roi_px: tuple[int, int, int, int] | None = None  # x, y, w, h: the target lies inside this box
    point_px: tuple[float, float] | None = None  # x, y: a point inside the target
    reference: bool = False  # a reference photo: sets fx (fx = Z l / S), not ranged

    def finder_priors(self) -> dict:
        """What the row tells the declared-target finder (``target_finder.find_region``)."""
        return {"shape": self.shape, "aspect": self.size_m / self.height_m if self.height_m else 1.0,
                "polarity": self.polarity, "roi": self.roi_px, "point": self.point_px}


def _number(text: str, where: str, column: str, unit_hint: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise InputError(f"{where}: {column} {text!r} is not a number; give {unit_hint}") from None
    if not math.isfinite(v) or v <= 0:
        raise InputError(f"{where}: {column} {text!r} must be a positive finite number ({unit_hint})")
    return v


def _numbers(text: str, n: int, where: str, column: str, hint: str) -> tuple[float, ...]:
    """``n`` numbers separated by commas, semicolons or spaces (a comma-separated field is quoted in the CSV)."""
    parts = [t for t in text.replace(";", " ").replace(",", " ").split() if t]
    try:
        vals = tuple(float(t) for t in parts)
    except ValueError:
        vals = ()
    if len(vals) != n or not all(math.isfinite(v) for v in vals):
        raise InputError(f"{where}: {column} {text!r} is not {n} numbers; give {hint}")
    return vals


REFERENCE_WORDS = {"": False, "no": False, "0": False, "false": False, "yes": True, "1": True, "true": True}


def _resolve(image: str, where: str, photos_dir: Path | None, csv_dir: Path) -> Path:
    p = Path(image)
    if p.is_absolute():
        tried = [p]
    else:
        tried = ([photos_dir / p] if photos_dir is not None else []) + [csv_dir / p]
    for q in tried:
        if q.exists():
            try:
                return check_input_file(q, "photo")
            except InputError as exc:
                raise InputError(f"{where}: {exc}") from None
    raise InputError(f"{where}: image {image!r} not found (looked in {', '.join(str(q.parent) for q in tried)}); "
                     "give a path relative to --photos DIR or to the CSV's folder")


def read_distances(csv_path: str | Path, photos_dir: str | Path | None = None) -> list[PhotoRecord]:
    """The checked rows of a distances CSV (see the module docstring); one-line ``InputError`` for the
    first bad row (missing file, bad number, unknown shape or polarity, duplicate photo, ...)."""
    csv_path = check_input_file(csv_path, "distances CSV")
    photos_dir = Path(photos_dir) if photos_dir is not None else None
    if photos_dir is not None and not photos_dir.is_dir():
        raise InputError(f"--photos {photos_dir}: not a directory; pass the folder that holds the photos")
    try:
        text = csv_path.read_text(encoding="utf-8-sig")
    except (UnicodeDecodeError, OSError) as exc:
        raise InputError(f"{csv_path}: not a readable UTF-8 text file ({type(exc).__name__}); save it as CSV") from None
    reader = csv.DictReader(text.splitlines())
    header = [h.strip().lower() for h in (reader.fieldnames or [])]
    if not header:
        raise InputError(f"{csv_path}: empty; the first line must name the columns "
                         f"{', '.join(REQUIRED_COLUMNS)} (optional {', '.join(OPTIONAL_COLUMNS)})")
    missing = [c for c in REQUIRED_COLUMNS if c not in header]
    unknown = [c for c in header if c not in REQUIRED_COLUMNS + OPTIONAL_COLUMNS]
    dup = sorted({c for c in header if header.count(c) > 1})
    if missing or unknown or dup:
        what = "; ".join(x for x in (f"missing column(s) {', '.join(missing)}" if missing else "",
                                     f"unknown column(s) {', '.join(unknown)}" if unknown else "",
                                     f"repeated column(s) {', '.join(dup)}" if dup else "") if x)
        raise InputError(f"{csv_path} line 1: {what}; the columns are {', '.join(REQUIRED_COLUMNS)} "
                         f"(optional {', '.join(OPTIONAL_COLUMNS)})")
    reader.fieldnames = header
    out: list[PhotoRecord] = []
    seen: dict[str, int] = {}
    for raw in reader:
        line = reader.line_num
        if None in raw:
            raise InputError(f"{csv_path} line {line}: more fields than the header's {len(header)}; "
                             "quote a field that holds a comma")
        row = {k: (v or "").strip() for k, v in raw.items()}
        if not any(row.values()):
            continue  # a blank line
        if any(v is None for v in raw.values()):
            raise InputError(f"{csv_path} line {line}: fewer fields than the header's {len(header)}; "
                             "give every column (empty optional ones as ,,)")
        image = row["image"]
        where = f"{csv_path} line {line} ({image or 'no image'})"
        if not image:
            raise InputError(f"{where}: the image column is empty; name the photo")
        shape = row["shape"].lower()
        if shape not in SHAPES:
            raise InputError(f"{where}: shape {row['shape']!r} is unknown; choose one of {', '.join(SHAPES)}")
        distance_cm = _number(row["distance_cm"], where, "distance_cm", "the reference distance in cm, e.g. 150")
        size_m = _number(row["size_m"], where, "size_m", "the target's size in metres, e.g. 0.13")
        if size_m > MAX_SIZE_M:
            raise InputError(f"{where}: size_m {row['size_m']} is over {MAX_SIZE_M:g} m; give metres "
                             "(13 cm = 0.13)")
        height_m = None
        if row.get("height_m"):
            if shape != "rectangle":
                raise InputError(f"{where}: height_m is for rectangles only; leave it empty for a {shape}")
            height_m = _number(row["height_m"], where, "height_m", "the rectangle's vertical side in metres")
            if height_m > MAX_SIZE_M:
                raise InputError(f"{where}: height_m {row['height_m']} is over {MAX_SIZE_M:g} m; give metres")
        polarity = (row.get("polarity") or "auto").lower()
        if polarity not in PHOTO_POLARITIES:
            raise InputError(f"{where}: polarity {row['polarity']!r} is unknown; choose one of "
                             f"{', '.join(PHOTO_POLARITIES)} (or leave it empty: auto)")
        roi = point = None
        if row.get("roi_px"):
            roi = _numbers(row["roi_px"], 4, where, "roi_px", '"x,y,w,h" in pixels of the photo, e.g. "120,80,300,240"')
            if roi[2] <= 0 or roi[3] <= 0:
                raise InputError(f"{where}: roi_px {row['roi_px']!r} has a width or height <= 0; give \"x,y,w,h\" "
                                 "with w, h > 0")
            roi = tuple(int(round(v)) for v in roi)
        if row.get("point_px"):
            point = _numbers(row["point_px"], 2, where, "point_px", '"x,y" in pixels of the photo, inside the target')
        ref = (row.get("reference") or "").lower()
        if ref not in REFERENCE_WORDS:
            raise InputError(f"{where}: reference {row['reference']!r}; write yes for a reference photo (its distance "
                             "sets the focal length) or leave it empty")
        group = row["group"]
        if not group:
            raise InputError(f"{where}: the group column is empty; name the photo's group (any text)")
        path = _resolve(image, where, photos_dir, csv_path.parent)
        key = os.path.realpath(path)
        if key in seen:
            raise InputError(f"{where}: the same photo as line {seen[key]}; one row per photo")
        seen[key] = line
        out.append(PhotoRecord(line, image, str(path), distance_cm, size_m, shape, group, polarity, height_m,
                               roi, point, REFERENCE_WORDS[ref]))
    if not out:
        raise InputError(f"{csv_path}: no rows; add one row per photo under the header")
    return out


def check_photos(records: list[PhotoRecord], image_size: tuple[int, int] | None, csv_path="distances CSV",
                 channel: str = "luma", progress: bool = True) -> tuple[int, int]:
    """Decode every photo and check it against the calibration's image size (before anything is written);
    ``image_size`` None (no calibration): every photo must have the first one's size.  Returns the size."""
    w = h = None if image_size is None else 0
    if image_size is not None:
        w, h = (int(v) for v in image_size)
    for r in console.track(records, "check photos", "photo", enabled=progress):
        where = f"{csv_path} line {r.line} ({r.image})"
        try:
            img = read_gray(r.path, channel=channel)
        except InputError as exc:
            raise InputError(f"{where}: {exc}") from None
        if img.ndim != 2:
            raise InputError(f"{where}: not a 2-D gray image (shape {img.shape}); save it as a gray or colour photo")
        if w is None:
            w, h, first = img.shape[1], img.shape[0], r
        if (img.shape[1], img.shape[0]) != (w, h):
            if image_size is None:
                raise InputError(f"{where}: {img.shape[1]} x {img.shape[0]} px, {first.image} is {w} x {h} px; "
                                 "without a calibration every photo must come from one camera at one resolution "
                                 "and orientation")
            raise InputError(f"{where}: {img.shape[1]} x {img.shape[0]} px, the calibration is for {w} x {h} px; "
                             "calibrate with photos of the same camera at the same resolution and orientation")
        if not np.all(np.isfinite(img)):
            raise InputError(f"{where}: holds NaN or infinite pixels; re-export the photo")
        check_pointers(r, img.shape, where)
    return int(w), int(h)


def resolve_references(records: list[PhotoRecord], specs: list[str], photos_dir, csv_path) -> list[PhotoRecord]:
    """``--reference-photo IMAGE[=DISTANCE_CM]``: mark the CSV's row of IMAGE as a reference photo (with a
    distance, it must agree with the row's), or add IMAGE as one (then the distance is needed and the CSV's
    rows must share one shape and size).  At least one test row must remain."""
    out = list(records)
    by_path = {os.path.realpath(r.path): k for k, r in enumerate(out)}
    for spec in specs:
        image, _, dist = spec.partition("=")
        where = f"--reference-photo {spec}"
        d = _number(dist, where, "distance", "IMAGE=DISTANCE_CM, e.g. ref.jpg=100") if dist else None
        path = _resolve(image, where, Path(photos_dir) if photos_dir else None, Path(csv_path).parent)
        k = by_path.get(os.path.realpath(path))
        if k is not None:
            r = out[k]
            if d is not None and abs(d - r.distance_cm) > 1e-9 * max(d, 1.0):
                raise InputError(f"{where}: {csv_path} line {r.line} lists {r.image} as a test photo at "
                                 f"{r.distance_cm:g} cm, not {d:g} cm; give one distance (drop =DISTANCE_CM to use "
                                 "the CSV's)")
            out[k] = dataclasses.replace(r, reference=True)
            continue
        if d is None:
            raise InputError(f"{where}: {image} is not in {csv_path}; give its distance as IMAGE=DISTANCE_CM")
        kinds = {(r.shape, r.size_m, r.height_m) for r in records}
        if len(kinds) != 1:
            raise InputError(f"{where}: {image} is not in {csv_path}, whose rows hold several targets; add it to "
                             "the CSV as a row with reference = yes")
        r0 = records[0]
        out.append(PhotoRecord(0, image, str(path), d, r0.size_m, r0.shape, "reference", r0.polarity, r0.height_m,
                               reference=True))
        by_path[os.path.realpath(path)] = len(out) - 1
    if all(r.reference for r in out):
        raise InputError(f"{csv_path}: every photo is a reference photo; keep at least one to range")
    return out


def camera_without_board(fx_px: float, image_size: tuple[int, int], method: str):
    """A calibration with no board: fx = fy = ``fx_px``, the principal point at the image centre, no distortion."""
    w, h = image_size
    K = np.array([[fx_px, 0.0, (w - 1) / 2.0], [0.0, fx_px, (h - 1) / 2.0], [0.0, 0.0, 1.0]])
    return Calibration(K=K, dist=np.zeros(5), image_size=(int(w), int(h)), rms_px=float("nan"), n_views=0,
                       method=method)


def check_pointers(r: PhotoRecord, shape, where: str) -> None:
    """The row's roi_px and point_px lie inside the photo (``shape`` (H, W)) and agree with each other."""
    h, w = shape
    if r.roi_px is not None:
        x, y, bw, bh = r.roi_px
        if x < 0 or y < 0 or x + bw > w or y + bh > h:
            raise InputError(f"{where}: roi_px {x},{y},{bw},{bh} leaves the {w} x {h} px photo; give a box inside it "
                             "(x, y from the top-left corner, 0-based)")
    if r.point_px is not None:
        px, py = r.point_px
        if not (0 <= px <= w - 1 and 0 <= py <= h - 1):
            raise InputError(f"{where}: point_px {px:g},{py:g} is outside the {w} x {h} px photo; give a point on the "
                             "target")
        if r.roi_px is not None:
            x, y, bw, bh = r.roi_px
            if not (x <= px <= x + bw and y <= py <= y + bh):
                raise InputError(f"{where}: point_px {px:g},{py:g} is outside its roi_px; give a point inside the box")


def unlisted_photos(records: list[PhotoRecord], photos_dir: str | Path) -> list[str]:
    """Image files directly in ``photos_dir`` that no row names (reported, not evaluated)."""
    listed = {os.path.realpath(r.path) for r in records}
    return sorted(p.name for p in Path(photos_dir).iterdir()
                  if p.is_file() and p.suffix.lower() in SUFFIXES and os.path.realpath(p) not in listed)


def photo_base(r: PhotoRecord) -> dict:
    """The fields every ``ranging_rows.csv`` row of a photo starts from (no render truth: floors NaN)."""
    size = f"{r.size_m:g} m" if r.height_m is None else f"{r.size_m:g} x {r.height_m:g} m"
    return {"image": r.image, "spec": "", "group": r.group, "target": f"{r.shape} {size}", "shape": r.shape,
            "true_distance_m": r.distance_cm / 100.0, "interval": interval_label(r.distance_cm),
            "slot": "", "levels": "", "off_base": "", "model_floor_cm": float("nan"), "pose_floor_cm": float("nan"),
            "pose_cal_floor_cm": float("nan")}


def range_photo(image: np.ndarray, record: PhotoRecord, cal, methods: list[str], keep_points: bool = False,
                options: dict | None = None, undistorter=None, undistort: str = "image") -> ImageResult:
    """Undistort one photo (a 2-D array) with ``cal``, find its target and range it with every method;
    ``undistort="points"``: refine the raw photo and undistort the points instead (``process_image``)."""
    und = undistorter or from_calibration(cal)
    raw = np.asarray(image, np.float64)
    kw = dict(keep_points=keep_points, name=record.image, options=options, polarity=record.polarity,
              height_m=record.height_m, finder=record.finder_priors())
    args = (record.shape, record.size_m, record.distance_cm / 100.0, cal, methods, photo_base(record))
    if check_undistort(undistort) == "points":
        return range_undistorted(raw, None, *args, points_undistorter=und, **kw)
    return range_undistorted(und(raw), und.valid_mask(), *args, **kw)


_undistorters: dict = {}


def _photo_task(k: int, record: PhotoRecord, cal, methods, keep_points, options, channel, undistort="image",
                figures_dir=None):
    """One photo (a pure function of its arguments; runs in worker processes); with ``figures_dir`` it also
    writes the photo's overlay there (``overlays.write_photo_overlay``)."""
    key = (cal.K.tobytes(), cal.dist.tobytes(), tuple(cal.image_size))
    if key not in _undistorters:
        _undistorters[key] = from_calibration(cal)
    image = read_gray(record.path, channel=channel)
    res = range_photo(image, record, cal, methods, keep_points or figures_dir is not None, options,
                      _undistorters[key], undistort)
    if figures_dir is not None and not res.error and res.fits:
        write_overlay(figures_dir, record, res, _undistorters[key](np.asarray(image, np.float64)))
    if not keep_points:
        res.points, res.fits = {}, {}
    return k, res


def overlay_method(res: ImageResult) -> str:
    """The method an overlay shows: the reference method where it ranged, else the first that did."""
    return REFERENCE_METHOD if REFERENCE_METHOD in res.fits else next(iter(res.fits))


def write_overlay(figures_dir, record: PhotoRecord, res: ImageResult, und: np.ndarray) -> None:
    m = overlay_method(res)
    row = next(r for r in res.rows if r["method"] == m)
    write_photo_overlay(Path(figures_dir) / overlay_name(record.image), und, res.region, res.fits[m],
                        res.points.get(m), m, float(row.get("z_hat_m", float("nan"))), record.distance_cm / 100.0)
    res.region["overlay"] = f"figures/{overlay_name(record.image)}"
    res.region["overlay_method"] = m


def run_photo_ranging(records: list[PhotoRecord], cal, out_dir: Path, photos_dir: str | Path | None = None,
                      methods: list[str] | None = None, options: dict | None = None, channel: str = "luma",
                      progress: bool = True, backend: str = "local", workers: int | None = 1,
                      address: str | None = None, figure_examples: int = 3, undistort: str = "image",
                      cals: list | None = None) -> dict:
    """Range every photo with every method; write ``ranging_rows.csv`` and ``ranging_images.json``.
    ``cals``: one calibration per record (fx from each photo's EXIF) instead of ``cal`` for all.
    Reference rows (``PhotoRecord.reference``) set each method's fx (``focal_length.reference_fx``) and
    leave the error tables; the others are re-ranged with it.
    Returns {"rows", "examples", "per_image", "methods", "reference_fx"} (as ``ranging.run_ranging``)."""
    from edgetruth.backends import make_backend  # lazy: the tests patch it on its module

    methods = list(methods or locate.registry.camera_free())  # photos: no camera model to give a method
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    keep, shown = set(), set()
    for k, r in enumerate(records):  # figure examples: the first photo of each shape
        if len(keep) < figure_examples and r.shape not in shown:
            keep.add(k)
            shown.add(r.shape)
    figures = out_dir / "figures"
    figures.mkdir(exist_ok=True)
    tasks = [(k, r, cals[k] if cals else cal, methods, k in keep, options or {}, channel, undistort, str(figures))
             for k, r in enumerate(records)]
    n_workers = min(1 if workers is None else int(workers), max(1, len(tasks)))
    init, initargs = plugins.backend_initializer(backend, n_workers, methods)
    results: dict = {}
    with make_backend(backend, n_workers, address, gpu=False, initializer=init, initargs=initargs) as be, \
            console.bar(total=len(tasks), desc="photos", unit="photo", enabled=progress) as bar:
        for k, res in be.map_unordered(_photo_task, tasks):
            results[k] = res
            bar.update(1)
    dataset = os.path.relpath(Path(photos_dir) if photos_dir is not None else Path(records[0].path).parent, out_dir)
    rows, per_image, examples = [], [], []
    for k, rec in enumerate(records):
        res = results[k]
        if k in keep and not res.error:
            examples.append(res)
        rows += [dict(row, dataset=dataset) for row in res.rows]
        per_image.append({"image": rec.image, "path": rec.path, "csv_line": rec.line, "group": rec.group,
                          "shape": rec.shape, "size_m": rec.size_m, "height_m": rec.height_m,
                          "distance_cm": rec.distance_cm, "polarity_requested": rec.polarity,
                          "n_candidates": res.n_candidates, "n_boundary": res.n_boundary, **res.region,
                          "methods_ok": sum(row.get("status") == "ok" for row in res.rows), "error": res.error,
                          "reference": rec.reference,
                          **({"fx_px": (cals[k] if cals else cal).fx} if cals else {})})
    ref_fx = None
    if any(r.reference for r in records):
        refs = {r.image for r in records if r.reference}
        size_of_image = {r.image: r.size_m for r in records}
        ref_fx = reference_fx([row for row in rows if row["image"] in refs], size_of_image)
        rows = apply_fx([row for row in rows if row["image"] not in refs], ref_fx, size_of_image)
        write_json(out_dir / "reference_fx.json", ref_fx)
    write_rows(out_dir / "ranging_rows.csv", rows)
    write_json(out_dir / "ranging_images.json", per_image)
    return {"rows": rows, "examples": examples, "per_image": per_image, "methods": methods, "reference_fx": ref_fx}


def photo_section(per_image: list[dict]) -> list[str]:
    """The report's table of photos: what each row declared and what target finding saw."""
    body = []
    for p in per_image:
        pol = p.get("polarity", "—")
        if p["polarity_requested"] == "auto" and p.get("polarity"):
            pol = f"auto → {pol}"
        found = p.get("shape_guess", "")
        flag = "" if not found or found == p["shape"] else f" (looks like a {found})"
        size = f"{p['size_m']:g}" + (f" × {p['height_m']:g}" if p.get("height_m") else "")
        fin = p.get("finder") or {}
        if not fin:
            choice = "—"
        elif fin.get("close"):
            choice = f"**close**: {fin['chosen']['score']:.2f} vs {fin['runners_up'][0]['score']:.2f}"
        else:
            nxt = fin["runners_up"][0]["score"] if fin.get("runners_up") else 0.0
            choice = f"{fin['chosen']['score']:.2f} (next {nxt:.2f})"
        pic = f"[overlay]({p['overlay']})" if p.get("overlay") else "—"
        status = p["error"] or ("ok; reference: sets fx" if p.get("reference") else "ok")
        body.append([p["image"], p["group"], p["shape"] + flag, size, f"{p['distance_cm']:g}", pol,
                     num(p.get("contrast", float("nan")), 2), choice, p["n_boundary"], p["methods_ok"],
                     status, pic])
    n_close = sum(bool((p.get("finder") or {}).get("close")) for p in per_image)
    n_light = sum(p.get("polarity") == "light" for p in per_image)
    n_dark = sum(p.get("polarity") == "dark" for p in per_image)
    n_none = len(per_image) - n_dark - n_light
    return ["", "## Photos", "",
            f"{len(per_image)} photos: {n_dark} dark targets, {n_light} light targets"
            + (f", {n_none} without a target found" if n_none else "")
            + ".  Polarity: what the CSV asked → what target finding used (auto: the regions of both polarities "
            "compete, and the best-scoring one is kept: the choice column).  Contrast: (o − i)/(o + i) of the "
            "median levels outside and inside the region kept, sign flipped for a light target.  l is the side of "
            "a square, the "
            "diameter of a circle and the *width* (left/right side lines) of a rectangle, with size_m its "
            "horizontal side.  No per-point tables: a photo has no exact outline to score points against.", "",
            table(["image", "group", "shape", "size (m)", "distance (cm)", "polarity", "contrast", "choice",
                   "boundary candidates", "methods ranged", "target finding", "picture"], body),
            "", "Choice: the score (0-1) of the region kept and of the best runner-up (shape fit × convexity × "
            "aspect ratio rectified with the camera matrix × contrast all round its boundary; docs/formats.md); "
            "**close** where the runner-up scores within 80 % of it: look at the overlay, and point at the target "
            "with `roi_px` or `point_px` if the wrong one was kept.  Overlay: the found outline (green), the "
            "fitted side lines or circle (magenta), the refined points of one method (red; dynamic_erf_4p where it "
            "ranged) with its l and Z, the runners-up (faint yellow); drawn on the undistorted photo."
            + (f"  {n_close} of {len(per_image)} choices were close." if n_close else ""),
            "", "A method that did not range a photo says why in `ranging_rows.csv` (`status`)."] + runners_up_lines(per_image)


def runners_up_lines(per_image: list[dict]) -> list[str]:
    """Per photo, the regions target finding kept and passed over (polarity, box x,y,w,h, score), close ones first."""
    lines = []
    for p in sorted(per_image, key=lambda p: not (p.get("finder") or {}).get("close")):
        fin = p.get("finder")
        if not fin:
            continue
        c = fin["chosen"]
        rest = "; ".join(f"{r['polarity']} {','.join(str(v) for v in r['bbox'])} ({r['score']:.2f})"
                         for r in fin.get("runners_up", [])[:3]) or "none"
        lines.append(f"- {p['image']}{' (**close**)' if fin.get('close') else ''}: kept {c['polarity']} "
                     f"{','.join(str(v) for v in c['bbox'])} ({c['score']:.2f}); runners-up {rest}")
    if not lines:
        return []
    return ["", "Target finding per photo: the region kept and the runners-up (polarity, box x,y,w,h in px of the "
                "undistorted photo, score); a runner-up's box is a ready `roi_px` if it is the target.", ""] + lines


def evaluate_photos(records: list[PhotoRecord], calibration, out: Path, photos_dir: str | Path | None = None,
                    methods=None, thresholds=None, camera_thresholds=None, channel: str = "luma",
                    progress: bool = True, backend: str = "local", workers: int | None = 1,
                    address: str | None = None, header: dict | None = None, undistort: str = "image",
                    cals: list | None = None, focal_source: str = "") -> Path:
    """Range every photo of ``records`` with every method and write ``report.md`` into ``out``
    (Tables 13-17, paired tests and verdicts against the reference distances)."""
    options = mo.study_options(thresholds, camera_thresholds)
    tau = mo.thresholds_in_use(thresholds)
    if camera_thresholds is not None:
        free = locate.registry.camera_free()  # photos: no camera model to give a method (patch_esf_fit)
        methods = mo.ordered(list(methods or free) + [
            v for v in mo.variant_labels(options) if options[v]["method"] in (methods or free)])
    result = run_photo_ranging(records, calibration, out, photos_dir, methods=methods, options=options,
                               channel=channel, progress=progress, backend=backend, workers=workers, address=address,
                               undistort=undistort, cals=cals)
    head = dict(header or {})
    head.setdefault("photos", len(records))

    head.setdefault("undistortion", UNDISTORT_LINES[undistort])
    head.setdefault("methods", len(result["methods"]))
    head["entropy thresholds"] = f"2P {tuple(tau['2p'])}, 4P {tuple(tau['4p'])} ({tau['label']})"
    if camera_thresholds is not None:
        ct = mo.thresholds_in_use(camera_thresholds)
        head["entropy thresholds for this camera (camera τ)"] = (
            f"2P {tuple(ct['2p'])}, 4P {tuple(ct['4p'])} (from {Path(camera_thresholds).name})")
    if focal_source:
        head["focal length"] = focal_source
    sections = photo_section(result["per_image"]) + focal_section(records, result.get("reference_fx"), focal_source)
    return write_report(out, result["rows"], result["methods"], calibration, result["examples"], head,
                        title="photo ranging report", reference=REFERENCE, sections=sections)


def focal_section(records: list[PhotoRecord], ref_fx: dict | None, source: str) -> list[str]:
    """The report's "Focal length" section: where fx came from and what that means for the figures."""
    if not source:
        return []
    out = ["", "## Focal length", "", source + "."]
    if ref_fx:
        refs = [r for r in records if r.reference]
        out += ["", f"fx = Z·l/S on the reference photo(s) ({', '.join(f'{r.image} at {r.distance_cm:g} cm' for r in refs)}), "
                "each method with its own l, so each method has its own fx: a method that measures every l a "
                "little large (or small) gets an fx as much larger, and its scale error cancels: its Z is exact at "
                "the reference distance, and elsewhere its errors are those of the *ratio* l_ref / l (what changes "
                "with distance: blur, sampling, the tilt's share) plus the reference distance's own error, which "
                "scales every Z alike.  The reference photos are not in the error tables.  The pose estimate needs "
                "the whole camera matrix and is left out (nan).", "",
                table(["method", "fx (px)", "reference photos"],
                      [[m, num(v.get("fx_px", float("nan")), 2), v.get("n", 0)] for m, v in ref_fx.items()])]
    return out
