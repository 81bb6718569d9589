"""The digital twin of a photo set: render it, run the same board study on twin and photos, compare.

``edgetruth study twin zhang1998 -o DIR`` (or ``opencv_left``: OpenCV's chessboard photos; or your own photos,
``edgetruth study twin PHOTOS... --pattern 9x6 --twin DIR/twin.toml``, with the twin ``edgetruth twin`` derives):

1. **Render** the set's twin scene (``scenes/zhang1998_twin.toml``: Zhang's camera, board and poses;
   optics, noise and output measured on his photos, ``photo_model``; ``scenes/opencv_left_twin.toml``:
   ``twin.derive``'s, written by ``tools/twins/opencv_left_scene.py``) into ``DIR/renders`` with the render
   driver (resumable: a run that stops picks up where it was).  A chessboard twin renders the model's squares
   first, then the outer ring's.
2. **The same board study** (``study.compute_board_study``) on the twin's PNGs, read like photos
   (``edgetruth.image_io.read_gray``), and on the real photos: the same methods and options, the same
   squares, sides, lines, calibration and leave-one-out code.  Each study's own files go to
   ``DIR/real`` and ``DIR/twin``.
3. **Against the truth** (twin only): every method's points that the study assigned to a side are
   scored against the square's exact distorted outline from the render's JSON (signed distance, > 0 on
   the bright board; the study's assignment already leaves out the 3 px next to each corner): RMS,
   median |e|, mean (the bias) and SD (the scatter about it).  Two truth rows: the exact corners (the JSON's),
   and *the exact outline*: points on the exact outline at 0.5 px spacing, 3 px from the corners, through the
   study's line fit and intersection -- the floor of the study's procedure (a straight line through a side that
   the lens bends).
4. **The photo model** (``photo_model.measure_photo``) of each real photo and each twin image, side by side,
   and the twin settings the photos give (``photo_model.derive_twin``) next to those the scene uses.
5. **Rankings**: Spearman ρ (``stats.spearman``: its two-sided p, exact up to 9 pairs, and n) between real and twin
   over the study's methods, for straightness, calibration RMS and leave-one-out RMS; and, on the twin,
   between straightness and the per-point error against the truth.

``DIR/report.md`` sets real and twin side by side; ``DIR/twin_vs_real.csv`` holds every number of its
method table; ``DIR/photo_model.json`` the photo model of both.  The diagnostic row ``pae2013_floating``
(PAE2013's default floating-window variant; the studies run its smoothed one) is in the tables but not in
the rankings.
"""
from __future__ import annotations

import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from edgetruth import console, locate
from edgetruth.errors import InputError
from edgetruth.evaluate import method_order as mo
from edgetruth.evaluate.board.detect import chessboard as cb
from edgetruth.evaluate.board.inputs import MIN_PHOTOS, BoardInputs, resolve_inputs
from edgetruth.evaluate.board.measure.rows import Row, calibrate_row
from edgetruth.evaluate.board.measure.summary import row_summary
from edgetruth.evaluate.board.sides.lines import fit_lines
from edgetruth.evaluate.board.study import _jsonable, compute_board_study, write_board_run
from edgetruth.evaluate.board.tone.photo_model import PALETTE_LEVELS, derive_twin, measure_photo
from edgetruth.evaluate.board.twin.budget import (BUDGET_SEEDS, SEED_PREFIX, budget_rows, measured_terms,
                                                  per_method_rows, term_scenes, write_budget)
from edgetruth.evaluate.board.twin.circle_study import run_circle_twin_study
from edgetruth.evaluate.board.twin.derive import group_name
from edgetruth.evaluate.board.twin.flatness import board_flatness
from edgetruth.evaluate.board.twin.report import PAE_DEFAULT, ranks, spearman, write_twin_report  # noqa: F401
from edgetruth.evaluate.run_dir import check_same_settings, prepare_run_dir
from edgetruth.image_io import read_gray
from edgetruth.locate.registry import camera_free
from edgetruth.render.dataset.driver import check_variant_name, render_spec
from edgetruth.render.dataset.reader import open_dataset
from edgetruth.render.dataset.spec import _check_sample_counts, load_spec
from edgetruth.render.edge_truth import closed_polyline_signed_distance


KIND = "study twin"
#: shipped photo sets with a twin scene: set name -> shipped spec name
TWINS = {"zhang1998": "zhang1998_twin", "opencv_left": "opencv_left_twin"}
#: sets whose twin settings were derived outside ``photo_model.derive_twin`` (a chessboard in JPEG, stored close to
#: linear): where they come from, for the report's settings table
DERIVED_ELSEWHERE = {"opencv_left": "`edgetruth twin` (evaluate/board/twin/derive.py, through "
                                    "tools/twins/opencv_left_scene.py; docs/board.md)"}
EXACT_OUTLINE = "exact_outline"
OUTLINE_STEP_PX = 0.5
CORNER_EXCLUSION_PX = 3.0


def check_set(name: str) -> str:
    if name not in TWINS:
        raise InputError(f"{name}: no twin for this set; sets with a twin: {', '.join(TWINS)}")
    return TWINS[name]


def check_images(images, n_total: int) -> list[int]:
    """1-based photo numbers -> sorted 0-based indices (at least ``MIN_PHOTOS``, each once, in range)."""
    if images is None:
        return list(range(n_total))
    idx = sorted(set(int(i) for i in images))
    if len(idx) != len(list(images)):
        raise InputError("--images: a photo is given twice; give each once")
    if any(i < 1 or i > n_total for i in idx):
        raise InputError(f"--images: photo numbers run from 1 to {n_total}")
    if len(idx) < MIN_PHOTOS:
        raise InputError(f"--images: {len(idx)} photo(s); leave-one-image-out calibration needs at least {MIN_PHOTOS}")
    return [i - 1 for i in idx]


def twin_spec(spec_name: str, spp: int | None):
    """The shipped twin spec, at ``spp`` samples per pixel when given (checked like a spec's)."""
    spec = load_spec(spec_name)
    if spp is None or spp == spec.render.spp:
        return spec
    _check_sample_counts({"spp": spp, "sampler": spec.render.sampler}, "--spp")
    return replace(spec, render=replace(spec.render, spp=int(spp)))


# --- the twin's truth ------------------------------------------------------------------------------
def truth_inputs(samples, model, real: BoardInputs) -> BoardInputs:
    """The twin's photos as board-study inputs: its PNGs, the set's model, the exact corners (model order, from
    the JSON) as the reference row, the twin camera's intrinsics as the reference calibration."""
    corners, paths = [], []
    for s in samples:
        sq = s.truth["squares"]
        # a chessboard twin renders its outer ring's squares after the model's (render.scene.targets)
        c = np.asarray(sq["corners_distorted_px"], float)[:len(model)]
        if c.shape != model.corners.shape:
            raise InputError(f"{s.name}: the render's squares ({c.shape[0]}) are not the model's ({len(model)})")
        corners.append(c)
        paths.append(s.dataset.path / s.dataset.manifest["images"][s.name]["files"]["png"]["path"])
    cam = samples[0].truth["camera"]
    ref = {"fx": cam["fx_px"], "fy": cam["fy_px"], "cx": cam["cx_px"], "cy": cam["cy_px"],
           "k1": cam["dist_coeffs_opencv"][0], "k2": cam["dist_coeffs_opencv"][1],
           "source": f"the twin's camera ({cam['name']})"}
    return BoardInputs(paths, model, corners, ref, f"{real.set_name} twin")


def outline_points(truth: dict, step_px: float = OUTLINE_STEP_PX,
                   n_squares: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(x, y, label) of points on the exact distorted outline of every square (of the first ``n_squares``: the
    model's) (the JSON's polylines, resampled at ``step_px``), ``CORNER_EXCLUSION_PX`` from the corners; label
    ``4 * square + side``."""
    sq = truth["squares"]
    xs, ys, labs = [], [], []
    polys = list(zip(sq["polylines_distorted_px"], sq["polylines_parameter"]))[:n_squares]
    for s, (poly, par) in enumerate(polys):
        poly, par = np.asarray(poly, float), np.asarray(par, float)
        side = np.minimum((4 * par).astype(int), 3)
        for k in range(4):
            pts = poly[side == k]
            nxt = poly[(np.flatnonzero(side == k)[-1] + 1) % len(poly)]  # the next corner
            pts = np.vstack([pts, nxt])
            seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
            arc = np.r_[0.0, np.cumsum(seg)]
            t = np.arange(CORNER_EXCLUSION_PX, arc[-1] - CORNER_EXCLUSION_PX + 1e-9, step_px)
            xs.append(np.interp(t, arc, pts[:, 0]))
            ys.append(np.interp(t, arc, pts[:, 1]))
            labs.append(np.full(len(t), 4 * s + k))
    return np.concatenate(xs), np.concatenate(ys), np.concatenate(labs)


def exact_outline_row(truths: list[dict], model):
    """The study's line fit and intersection applied to points on the exact outline: the floor of its procedure."""
    corners, fits = [], []
    for t in truths:
        x, y, lab = outline_points(t, n_squares=len(model))
        f = fit_lines(lab, x, y, len(model))
        fits.append(f)
        corners.append(f.corners)
    return Row(EXACT_OUTLINE, corners, fits)


def point_errors(row, truths: list[dict]) -> dict:
    """Signed distance of a method row's assigned points to their square's exact distorted outline (> 0 on the
    bright board), all photos: RMS, median |e|, mean, SD (the scatter about the mean), n."""
    errs = []
    for pts, t in zip(row.points or [], truths):
        lab = pts["label"]
        if lab is None:
            continue
        polys = t["squares"]["polylines_distorted_px"]
        ok = lab >= 0
        sq = lab[ok] // 4
        x, y = pts["x"][ok], pts["y"][ok]
        for s in np.unique(sq):
            m = sq == s
            errs.append(closed_polyline_signed_distance(np.asarray(polys[s], float), x[m], y[m]))
    e = np.concatenate(errs) if errs else np.zeros(0)
    if not e.size:
        return {"truth_rms_px": float("nan"), "truth_median_abs_px": float("nan"), "truth_mean_px": float("nan"),
                "truth_sd_px": float("nan"), "truth_points": 0}
    return {"truth_rms_px": float(np.sqrt(np.mean(e * e))), "truth_median_abs_px": float(np.median(np.abs(e))),
            "truth_mean_px": float(np.mean(e)), "truth_sd_px": float(np.std(e)), "truth_points": int(e.size)}


#: the method whose per-photo corners and bias the twin report tabulates (when the study runs it)
PER_PHOTO_METHOD = "erf4p_fixed11"


def per_photo_corners(real_run, twin_run, truths: list[dict], method: str) -> list[dict] | None:
    """On a chessboard, per photo for ``method``: the median outward offset (px) of each square's own corner from the
    junction's corner on the photo and on the twin (``summary.outward_offsets``: > 0 out of the dark square), the
    twin's mean signed error of the points against the exact outline, and whether the photo's white is saturated
    (``levels``).  None for a board of separate squares (no junctions) or when ``method`` did not run."""
    from edgetruth.evaluate.board.measure.summary import outward_offsets  # lazy: the tests patch it on its module

    model = twin_run.inp.model
    if model.pattern is None or not (len(real_run.names) == len(twin_run.names) == len(truths)):
        return None  # separate squares, or a photo or render whose board was not found
    rows = {r.label: r for r in real_run.rows}, {r.label: r for r in twin_run.rows}
    if method not in rows[0] or method not in rows[1]:
        return None
    jn = cb.junctions(model)
    real_off, twin_off = (outward_offsets(r[method], jn) for r in rows)
    sat = {p["photo"]: p.get("white_saturated") == "yes" for p in real_run.photo_table}
    out = []
    for i, name in enumerate(real_run.names):
        row = rows[1][method]
        e = point_errors(replace(row, points=[row.points[i]]), [truths[i]])
        out.append({"photo": name, "method": method, "white_saturated": sat.get(name, False),
                    "own_corner_outward_real_px": float(np.nanmedian(real_off[i])),
                    "own_corner_outward_twin_px": float(np.nanmedian(twin_off[i])),
                    "twin_truth_mean_px": e["truth_mean_px"]})
    return out


# --- the study ------------------------------------------------------------------------------------
def settings_of(set_name: str, methods, options, images, spp, spec_sha: str, channel: str) -> dict:
    return {"set": set_name, "methods": methods, "options": _jsonable(options), "images": [i + 1 for i in images],
            "spp": spp, "spec_identity": spec_sha, "channel": channel}


def own_inputs(photos: list[str], twin: str | None, model_path=None, pattern=None, square=None):
    """Your own photos and their twin (``edgetruth twin`` writes one) -> (label, BoardInputs, spec name or path)."""
    if twin is None:
        raise InputError("study twin PHOTOS...: give one shipped set's name (zhang1998, opencv_left), or your "
                         "photos with their twin scene, --twin FILE (`edgetruth twin PHOTOS --pattern ... -o DIR` "
                         "writes DIR/twin.toml)")
    real = resolve_inputs(list(photos), model_path, pattern, square)
    return real.set_name, real, twin


def photos_by_group(real: BoardInputs, spec, spec_name) -> BoardInputs:
    """The photos a twin with fewer images renders (``edgetruth twin`` leaves out a photo without the board): those
    whose names its one-image groups carry (``derive.group_name``), in the twin's order, one line naming the others.
    An ``InputError`` where the groups do not name the photos each once."""
    groups = [g.name for g in spec.groups]
    where: dict[str, list[int]] = {}
    for i, photo in enumerate(real.photos):
        where.setdefault(group_name(photo.name), []).append(i)
    if spec.n_images != len(groups) or any(len(where.get(g, [])) != 1 for g in groups):
        raise InputError(f"{spec_name}: {spec.n_images} images for {len(real.photos)} photos, and its groups do not "
                         "name the photos one each; the twin must render one image per photo (give the photos "
                         "`edgetruth twin` measured, in its order)")
    idx = [where[g][0] for g in groups]
    rest = [p.name for i, p in enumerate(real.photos) if i not in set(idx)]
    console.say(f"study twin: {spec_name} has no image of {', '.join(rest)}; comparing the {len(idx)} photos it "
                "renders, paired by name")
    return replace(real, photos=[real.photos[i] for i in idx],
                   reference_corners=None if real.reference_corners is None else
                   [real.reference_corners[i] for i in idx])


def paired(real_names: list, real_used: list, twin_names: list, twin_used: list) -> list[int]:
    """The positions where the board study found the board on both the photo and its twin image; when some are
    missing, one line says which (an ``InputError`` when fewer than ``MIN_PHOTOS`` pairs remain)."""
    ru, tu = set(real_used), set(twin_used)
    both = [k for k, (r, t) in enumerate(zip(real_names, twin_names)) if r in ru and t in tu]
    lost = [f"{r} / {t}" for k, (r, t) in enumerate(zip(real_names, twin_names)) if k not in both]
    if lost and len(both) < MIN_PHOTOS:
        raise InputError(f"study twin: the board was found on both a photo and its twin image for {len(both)} pair(s) "
                         f"only (not on {', '.join(lost)}: photo / twin image); need {MIN_PHOTOS}: render with more "
                         "--spp, or check the twin")
    if lost:
        console.say(f"study twin: the board was not found on {', '.join(lost)} (photo / twin image); comparing the "
                    f"{len(both)} pairs where it was")
    return both


def model_unit_m(set_name: str, model, spec) -> float:
    """Metres per board-model unit, for Table 5's depths: the shipped sets' own; else the side of the twin's first
    square (a chessboard twin renders the model's squares first, in its order) over the model's."""
    if set_name in MODEL_UNIT_M:
        return MODEL_UNIT_M[set_name]

    def side(q) -> float:
        q = np.asarray(q, float)
        return float(np.linalg.norm(q[1, :2] - q[0, :2]))

    squares = getattr(spec, "squares", None)
    if squares is None or side(model.corners[0]) <= 0:
        return 1.0
    return side(squares.quads_model_m[0]) / side(model.corners[0])


def run_twin_study(set_name, out, methods=None, images=None, spp: int | None = None, thresholds=None,
                   channel: str = "luma", variant: str | None = None, progress: bool = True,
                   twin: str | None = None, model_path=None, pattern=None, square=None,
                   budget: list[str] | None = None) -> Path:
    """Render the twin of ``set_name`` and compare it with the photos (module docstring); returns report.md.
    ``twin``: the twin scene (a shipped spec name or a TOML path; default the set's own, ``TWINS``), e.g.
    ``opencv_left_twin_bent``, whose boards curl as the photos' do.  ``set_name`` may also be a list of your own
    photos (files, folders, globs; ``resolve_inputs`` with ``model_path`` or ``pattern`` and ``square``): then
    ``twin`` is required, e.g. the ``twin.toml`` of ``edgetruth twin``.  ``budget``: the error budget (``budget``:
    [] every term the twin renders, or the terms named), rendered into ``DIR/budget``."""
    t0 = time.perf_counter()
    if isinstance(set_name, str):
        spec_name = check_set(set_name)
        spec_name = spec_name if twin is None else twin
        real_all = resolve_inputs([set_name])
    else:
        set_name, real_all, spec_name = own_inputs(set_name, twin, model_path, pattern, square)
    spec = twin_spec(spec_name, spp)
    set_name = set_name or spec.name  # your own photos: named by their twin
    if spec.n_images != len(real_all.photos):
        real_all = photos_by_group(real_all, spec, spec_name)
    keep = check_images(images, len(real_all.photos))
    if real_all.circles is not None:  # a circle grid's twin: its own study (``circle_study``)
        return run_circle_twin_study(real_all, spec, spec_name, out, methods=methods, keep=keep,
                                     thresholds=thresholds, channel=channel, variant=variant, progress=progress,
                                     budget=budget, spp=spp)
    # all methods but those that need a camera model (patch_esf_fit's PSF tables): there is none here
    methods = mo.ordered(camera_free() if methods is None else methods)
    for m in methods:
        locate.get_method(mo.resolve(m)[0])
    options = mo.study_options(thresholds)
    diag = [PAE_DEFAULT] if "pae2013" in methods else []
    if diag:
        options[PAE_DEFAULT] = {"method": "pae2013", "variant": "floating"}
    rows_methods = methods + diag
    check_variant_name(variant)
    settings = settings_of(set_name, methods, options, keep, spec.render.spp, spec.identity_sha256, channel)
    if budget is not None:  # only then: an earlier run without a budget keeps its settings
        settings["budget"] = sorted(budget) or "all"
    out = _check_twin_output(Path(out), settings)

    # 1. render (resumable), into the run directory
    out = prepare_run_dir(out, KIND, settings)
    render_dir = out / "renders"
    t_r = time.perf_counter()
    render_spec(spec, render_dir, variant=variant, progress=progress, only=keep,
                announce=lambda s: console.say(s) if progress else None)
    render_s = time.perf_counter() - t_r
    ds = open_dataset(render_dir)
    by_index = {s.index: s for s in ds.square_boards()}
    missing = [i for i in keep if i not in by_index]
    if missing:
        raise InputError(f"{render_dir}: image(s) {', '.join(str(i) for i in missing)} did not render; run again")
    samples = [by_index[i] for i in keep]
    truths = [s.truth for s in samples]

    real = replace(real_all, photos=[real_all.photos[i] for i in keep],
                   reference_corners=None if real_all.reference_corners is None else
                   [real_all.reference_corners[i] for i in keep])
    twin = truth_inputs(samples, real.model, real)

    # 2. the same board study on both
    t_s = time.perf_counter()
    real_images = [read_gray(p, channel=channel) for p in real.photos]
    twin_images = [read_gray(p, channel=channel) for p in twin.photos]
    def studies():
        return (compute_board_study(real, rows_methods, options, channel, progress, images=real_images),
                compute_board_study(twin, rows_methods, options, channel, progress, images=twin_images,
                                    keep_points=True))

    real_run, twin_run = studies()
    both = paired(real.names, real_run.names, twin.names, twin_run.names)
    if len(both) < len(keep):  # compare only the pairs where both studies found the board
        keep, samples = [keep[k] for k in both], [samples[k] for k in both]
        truths = [s.truth for s in samples]
        real = replace(real, photos=[real.photos[k] for k in both], reference_corners=None if
                       real.reference_corners is None else [real.reference_corners[k] for k in both])
        twin = truth_inputs(samples, real.model, real)
        real_images, twin_images = [real_images[k] for k in both], [twin_images[k] for k in both]
        real_run, twin_run = studies()
    study_s = time.perf_counter() - t_s

    # 3. the twin against its truth

    errors = {r.label: point_errors(r, truths) for r in twin_run.rows if r.is_method}
    corners = per_photo_corners(real_run, twin_run, truths, PER_PHOTO_METHOD)
    floor_row = calibrate_row(exact_outline_row(truths, twin.model), twin.model, twin_run.size)
    floor = row_summary(floor_row, twin.model, twin_run.reference, twin.reference_corners)
    flatness = flatness_rows(model_unit_m(set_name, real.model, spec), real_run, twin_run, floor_row,
                             PER_PHOTO_METHOD)

    # 4. the photo model of both, and the settings the photos give
    t_p = time.perf_counter()
    pm_real = [measure_photo(img, real.model, p.name, p) for img, p in zip(
        console.track(real_images, desc="photo model (real)", unit="photo", enabled=progress), real.photos)]
    pm_twin = [measure_photo(img, real.model, p.name, p) for img, p in zip(
        console.track(twin_images, desc="photo model (twin)", unit="photo", enabled=progress), twin.photos)]
    jobs = [spec.jobs[i] for i in keep]
    defocus = [float(j.camera.defocus_radius_px(j.pose.distance_m)) for j in jobs]
    if set_name in DERIVED_ELSEWHERE:
        derived = {"derived_by": DERIVED_ELSEWHERE[set_name]}
    elif set_name not in BASE_LEVELS:  # your own photos: the scene says how it was made
        beside = Path(str(spec_name)).parent / "measurements.json"
        derived = {"derived_by": f"`edgetruth twin` ({beside})" if beside.is_file() else
                   f"whoever wrote {spec_name} (`edgetruth twin` writes a measurements.json beside its twin.toml)"}
    else:
        try:
            base_black, base_white = BASE_LEVELS[set_name]
            derived = derive_twin(pm_real, spec.camera, defocus, base_white=base_white, base_black=base_black)
            derived["closed_loop"] = closed_loop_noise(pm_real, pm_twin, [j.sensor for j in jobs])
        except (KeyError, ValueError) as exc:  # pragma: no cover - a photo whose board was not found
            derived = {"error": str(exc)}
    photo_s = time.perf_counter() - t_p

    # 5. files
    for sub, run, title in (("real", real_run, f"Board study — {set_name} (real photos)"),
                            ("twin", twin_run, f"Board study — {set_name} twin (renders)")):
        (out / sub).mkdir(exist_ok=True)
        write_board_run(run, out / sub, channel, rows_methods, options, thresholds, title=title)
    timings = {"render_s": render_s, "studies_s": study_s, "photo_model_s": photo_s}
    budget_lines = None
    if budget is not None:
        t_b = time.perf_counter()
        budget_lines = run_budget(out, spec_name, budget, spp, keep, real, twin_run, real_run, methods, rows_methods,
                                  options, channel, variant, progress)
        timings["budget_s"] = time.perf_counter() - t_b
    timings["total_s"] = time.perf_counter() - t0
    return write_twin_report(out, set_name=set_name, spec=spec, jobs=jobs, keep=keep, methods=methods, diag=diag,
                             real_run=real_run, twin_run=twin_run, errors=errors, floor=floor, pm_real=pm_real,
                             pm_twin=pm_twin, derived=derived, timings=timings, options=options,
                             thresholds=thresholds, corners=corners, flatness=flatness, budget=budget_lines)


def run_budget(out: Path, spec_name, terms: list[str], spp, keep: list[int], real: BoardInputs, twin_run, real_run,
               methods: list[str], rows_methods: list[str], options: dict, channel: str, variant, progress: bool):
    """The error budget (``budget``): each term's scene rendered into ``out/budget/<term>/renders`` (resumable),
    the board study on its images (the photos ``keep``), the budget's files; returns the report's lines."""
    scenes = term_scenes(spec_name, out / "budget", names=terms or None, spp=spp, seeds=BUDGET_SEEDS)
    if terms and set(terms) - {n for n in scenes if not n.startswith(SEED_PREFIX)}:
        console.say("budget: the twin does not render " + ", ".join(sorted(set(terms) - set(scenes))) + ": left out")
    off, photos = {}, {"": len(real_run.names), "all": len(twin_run.names)}
    for name, path in scenes.items():
        render_dir = path.parent / "renders"
        render_spec(load_spec(path), render_dir, variant=variant, progress=progress, only=keep,
                    announce=lambda s: None)
        by_index = {s.index: s for s in open_dataset(render_dir).square_boards()}
        inp = truth_inputs([by_index[i] for i in keep], real.model, real)
        images = [read_gray(p, channel=channel) for p in inp.photos]
        try:
            run = compute_board_study(inp, rows_methods, options, channel, progress, images=images)
        except InputError as exc:  # too few boards found with the term off: say so, keep the others
            console.say(f"budget: {name}: {exc}")
            continue
        off[name] = {s["row"]: s for s in run.summaries}
        photos[name] = len(run.names)
    real_s = {s["row"]: s for s in real_run.summaries}
    twin_s = {s["row"]: s for s in twin_run.summaries}
    rows = budget_rows(real_s, twin_s, off, methods)
    return write_budget(out, rows, per_method_rows(real_s, twin_s, off, methods), len(methods), photos,
                        measured_terms(real_run, PER_PHOTO_METHOD))


def closed_loop_noise(pm_real: list[dict], pm_twin: list[dict], sensors) -> list[dict]:
    """Per photo not reduced to a coarse palette: the output noise that would make the twin's black SD equal the
    photo's, from the twin's measured black SD s_t with its output noise n: the twin's other noise (Monte-Carlo,
    sensor, through the sharpening) is s_t² − n² − 1/12, and n' = sqrt(s_real² − other − 1/12)."""
    out = []
    for r, t, sen in zip(pm_real, pm_twin, sensors):
        if r.get("levels", 0) < PALETTE_LEVELS or not t.get("found"):
            continue
        s_r, s_t, n = r["noise"]["black"]["sd"], t["noise"]["black"]["sd"], sen.output_noise_dn
        other = s_t ** 2 - n ** 2 - 1.0 / 12.0
        out.append({"photo": r["photo"], "real_black_sd": s_r, "twin_black_sd": s_t, "twin_noise_dn": n,
                    "twin_other_sd": math.sqrt(max(other, 0.0)),
                    "noise_for_real_sd": math.sqrt(max(s_r ** 2 - other - 1.0 / 12.0, 0.0))})
    return out


#: The twin's own stored (black, white) with output_gain 1 and offset 0 (its print and exposure; measured on
#: its renders, the same on all five poses to 0.5): what ``derive_twin`` maps to each photo's levels.
BASE_LEVELS = {"zhang1998": (41.1, 215.2)}
#: metres per board-model unit, for the flatness check's depths: Zhang's model is in inches; OpenCV's chessboard
#: model counts squares, and its twin assumes 25 mm squares (docs/board.md)
MODEL_UNIT_M = {"zhang1998": 0.0254, "opencv_left": 0.025}


def flatness_rows(unit_m: float, real_run, twin_run, floor_row, method: str) -> dict:
    """Table 5: the bent-board check (``flatness.board_flatness``) on ``method``'s corners of the photos and of the
    twin, and on the twin's exact outline; {label: result}, empty results left out."""
    out = {}
    for label, run, row in (("photos", real_run, None), ("twin", twin_run, None),
                            ("twin, exact outline", twin_run, floor_row)):
        if row is None:
            row = next((r for r in run.rows if r.label == method), None)
        if row is None or row.corners is None:
            continue
        res = board_flatness(row.corners, run.inp.model.corners, run.size, unit_m)
        if res:
            out[label] = {"method": method if label != "twin, exact outline" else EXACT_OUTLINE, **res}
    return out


def _check_twin_output(out: Path, settings: dict) -> Path:
    return check_same_settings(out, KIND, settings, "a twin study")
