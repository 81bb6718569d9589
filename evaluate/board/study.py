"""The board study: subpixel edge methods judged on real photographs of a board of squares.

No ground truth is known for a photo, so the methods are judged by what a correct edge must do:
the points of a straight printed side lie on a line (*straightness*), and corners from the side
lines must calibrate a camera consistently (*reprojection RMS*, *leave-one-image-out RMS*,
intrinsics against the set's published ones, *side lengths* in the board plane against the
model).  Steps (docs/board.md):

1. photos, model and (for a shipped set) the set's own corners and calibration
   (``inputs``, ``model``, ``reference``); everything checked before any work;
2. per photo: the dark quads (``quads``) and the model's squares among them (``correspond``), or for a
   chessboard its squares from OpenCV's corner grid (``chessboard``), and the Canny candidates, once,
   shared by every method;
3. per method: the refined points, side lines and corners (``sides``, ``measure``); then per row
   (every method, and the set's own corners as the reference row) the calibration, LOO and side
   lengths (``calibrate``);
4. per-row figures (``summary``), paired tests (``compare``), files (``report``, ``figures``).

Nothing is written until every step has run; the run directory holds ``run.json``.  Running again
into the same directory with the same settings re-makes it (the study takes well under a minute);
with other settings it is refused.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from edgetruth import console, locate
from edgetruth.errors import InputError
from edgetruth.evaluate import method_order as mo
from edgetruth.evaluate.board.circle_grid.study import compute_circle_study, write_circle_run
from edgetruth.evaluate.board.detect import chessboard as cb
from edgetruth.evaluate.board.detect.charuco import plain_opencv_calibration as charuco_plain
from edgetruth.evaluate.board.detect.squares import locate_squares
from edgetruth.evaluate.board.inputs import MIN_PHOTOS, BoardInputs, load_photos, load_photos_scaled, resolve_inputs
from edgetruth.evaluate.board.measure.compare import compare_all
from edgetruth.evaluate.board.measure.grid_corners import DEFAULT_METHOD
from edgetruth.evaluate.board.measure.rows import OPENCV_ROW, REFERENCE_ROW, Row, calibrate_row, method_row
from edgetruth.evaluate.board.measure.summary import INTRINSICS, per_side_rows, row_summary
from edgetruth.evaluate.board.report.overlays import board_overlay, overlay_name, png_bytes
from edgetruth.evaluate.board.tone import locator_fit as LF, values as tone_mod
from edgetruth.evaluate.board.tone.fit import estimate_power, require_chessboard
from edgetruth.evaluate.run_dir import check_same_settings, prepare_run_dir
from edgetruth.locate.registry import camera_free


KIND = "study board"


def settings_of(inp: BoardInputs, methods: list[str], options: dict, channel: str) -> dict:
    """What a run directory records of a study, to refuse a rerun of other settings into it."""
    model = inp.circles.source if inp.circles is not None else inp.model.source
    return {"photos": [str(p.resolve()) for p in inp.photos], "set": inp.set_name, "model": model,
            "methods": methods, "options": _jsonable(options), "channel": channel}


def _jsonable(options: dict) -> dict:
    return {m: {k: (np.asarray(v).tolist() if isinstance(v, (np.ndarray, tuple)) else v) for k, v in o.items()}
            for m, o in options.items()}


def check_output(out: Path, settings: dict) -> Path:
    """Refuse a foreign directory or a board study of other settings, before any work."""
    return check_same_settings(out, KIND, settings, "a board study")


@dataclass
class BoardRun:
    """Everything one board study computed (``compute_board_study``), before anything is written."""

    inp: BoardInputs
    names: list  # the photos used
    size: tuple  # (w, h)
    rows: list
    summaries: list
    comparisons: list
    per_side: list
    photo_table: list
    reference: dict | None
    #: the reference row's key (``measure.REFERENCE_ROWS``), None when there is none
    reference_row: str | None
    elapsed_s: float
    #: edgetruth's locator against the best method and its model misfit (``locator_fit``), when it ran
    locator: dict | None = None
    #: how the stored values were decoded (``tone_summary``); None: as stored
    tone: dict | None = None
    #: per photo used: (file name in figures/, PNG bytes) of its overlay (``evaluate.board.report.overlays``)
    overlays: list | None = None


def compute_board_study(inp: BoardInputs, methods: list[str], options: dict, channel: str = "luma",
                        progress: bool = True, images=None, keep_points: bool = False,
                        tone: dict | None = None) -> BoardRun:
    """Steps 2-4 of the study (module docstring) on checked inputs; nothing is written.  ``images``: the photos
    already read, and decoded by their tone (else read here, as stored); ``keep_points``: each method row keeps its
    refined points (``Row.points``); ``tone``: how ``images`` were decoded (``tone_summary``), for the report."""
    t0 = time.perf_counter()
    images = load_photos(inp.photos, channel) if images is None else images
    h, w = images[0].shape

    cands, quads, smaps, photo_table, keep, chess_refs, model = locate_squares(inp, images, progress)
    if model is not inp.model:
        inp = replace(inp, model=model)
    ref_row = REFERENCE_ROW if inp.reference_corners is not None else None
    jn = None
    if chess_refs is not None:  # a chessboard: corners at the junctions; OpenCV's own corners are the reference row
        jn = cb.junctions(model)
        inp = replace(inp, reference_corners=chess_refs)
        ref_row = OPENCV_ROW
    if len(keep) < MIN_PHOTOS:
        raise InputError(f"board study: the model's squares were found on {len(keep)} photo(s) "
                         f"({', '.join(inp.names[i] for i in keep) or 'none'}); need {MIN_PHOTOS}: check the model "
                         "matches the board in the photos")
    used_images = [images[i] for i in keep]
    names = [inp.names[i] for i in keep]

    rows: list[Row] = []
    for label in console.track(methods, desc="methods", unit="method", enabled=progress):
        method, kw = mo.resolve(label, options)
        rows.append(method_row(label, method, kw, used_images, cands, quads, smaps, keep_points=keep_points,
                               junctions=jn))
    if ref_row is not None:
        rows.append(Row(ref_row, [inp.reference_corners[i] for i in keep]))
    for r in console.track(rows, desc="calibration", unit="row", enabled=progress):
        calibrate_row(r, inp.model, (w, h))

    reference = None
    if inp.reference_calibration is None and model.charuco is not None:
        # a ChArUco set's reference: plain OpenCV's own calibration of every photo with corners (its 5-term lens,
        # each corner once), beside the rows (k1, k2, the squares' corners, the photos with every corner)
        plain = charuco_plain(inp.photos, model.charuco.board)
        if plain is not None:
            inp = replace(inp, reference_calibration={**plain, "row_label": "plain OpenCV"})
    if inp.reference_calibration is not None:
        reference = {k: inp.reference_calibration[k] for k in INTRINSICS}
        reference["source"] = inp.reference_calibration.get("source", "reference")
        for k in ("row_label", "rms_px"):
            if k in inp.reference_calibration:
                reference[k] = inp.reference_calibration[k]
    ref_corners = [inp.reference_corners[i] for i in keep] if inp.reference_corners is not None else None
    summaries = [row_summary(r, inp.model, reference, ref_corners) for r in rows]
    comparisons = compare_all(rows)
    per_side = per_side_rows(rows, inp.model, names)
    locator = None
    for label in methods:
        method, kw = mo.resolve(label, options)
        if method == LF.METHOD and any(r.label == label and r.cal is not None for r in rows):
            misfit = LF.locator_misfit(used_images, cands, inp.model, names, **kw)
            locator = LF.locator_summary(rows, summaries, label, misfit)
            break
    return BoardRun(inp, names, (w, h), rows, summaries, comparisons, per_side, photo_table, reference,
                    ref_row, time.perf_counter() - t0, locator, tone, board_overlays(rows, used_images, quads, names))


def board_overlays(rows: list, images, quads, names) -> list:
    """Per photo used, the overlay of its detected squares and one method's fitted sides (dynamic_erf_4p where
    it ran, else the first method row): [(file name, PNG bytes)]."""
    method_rows = [r for r in rows if r.is_method and r.sides]
    row = next((r for r in method_rows if r.label == "dynamic_erf_4p"), method_rows[0] if method_rows else None)
    out = []
    for i, (img, q, name) in enumerate(zip(images, quads, names)):
        sides = row.sides[i].corners if row is not None and row.sides[i] is not None else None
        text = f"green: squares found; magenta: {row.label}'s side lines" if row is not None else "squares found"
        out.append((overlay_name(name), png_bytes(board_overlay(img, q, sides, text=text))))
    return out


def check_tone(text: str | None, inp: BoardInputs) -> tone_mod.Tone:
    """``--tone`` parsed and checked before any work: ``auto`` needs a chessboard and a camera-free method."""
    t = tone_mod.parse_tone(text, DEFAULT_METHOD)
    if t.kind != "auto":
        return t
    require_chessboard(inp.model)
    method = mo.resolve(t.method)[0]
    try:
        locate.get_method(method)
    except InputError as exc:
        raise InputError(f"--tone {t.spec}: {exc}") from None
    if not camera_free([method]):
        raise InputError(f"--tone {t.spec}: {method} needs a camera model, which the board study does not have; "
                         "choose another method (`edgetruth methods`)")
    return t


def decode_photos(inp: BoardInputs, tone: tone_mod.Tone, channel: str, options: dict, progress: bool):
    """The photos read and decoded by ``tone`` (for ``auto``, by the power ``tone_fit.estimate_power`` measures), and
    the tone's summary for the report (``tone_summary``; None for stored values)."""
    images, scales = load_photos_scaled(inp.photos, channel)
    fit = None
    if tone.kind == "auto":
        if progress:
            console.say(f"tone: measuring the power at the junctions with {tone.method} ...")
        method, kw = mo.resolve(tone.method, options)
        fit = estimate_power(inp, images, scales, tone.method, method, kw)
        tone = fit.tone()
    return [tone_mod.decode(img, tone, f) for img, f in zip(images, scales)], tone_summary(tone, scales, fit)


def tone_summary(tone: tone_mod.Tone, scales: list[float], fit=None) -> dict | None:
    """What the report says of the tone: its option text, a phrase, the full scale, and the fit (``PowerFit``)."""
    if tone.kind == "stored" and fit is None:
        return None
    full = scales[0] if len(set(scales)) == 1 else None
    return {"spec": tone.spec if fit is None else f"auto:{fit.method}", "power": tone.power,
            "describe": tone.describe(full), "fit": fit.as_json() if fit is not None else None}


def write_board_run(run: BoardRun, out: Path, channel: str, methods: list[str], options: dict, thresholds,
                    title: str | None = None) -> Path:
    """The study's files (``report.write_outputs``) of ``run`` into the existing directory ``out``."""
    from edgetruth.evaluate.board.report.files import header_lines, write_outputs  # lazy: files loads matplotlib

    inp = run.inp
    header = header_lines(inp, run.names, run.size, channel, methods, options, thresholds, run.reference,
                          run.reference_row, run.elapsed_s, run.tone)
    title = title or f"Board study — {inp.set_name or f'{len(inp.photos)} photos'}"
    return write_outputs(out, title=title, header_lines=header, photos_table=run.photo_table, rows=run.rows,
                         summaries=run.summaries, comparisons=run.comparisons, reference=run.reference,
                         model=inp.model, photo_names=run.names, per_side=run.per_side, locator=run.locator,
                         tone=run.tone, overlays=run.overlays)


def run_board_study(items: list[str], out, model: str | None = None, methods=None, channel: str = "luma",
                    thresholds=None, progress: bool = True, pattern: str | None = None, square=None,
                    tone: str | None = None, marker=None) -> Path:
    """Run the board study (module docstring) into ``out``; returns the path of its report.md.  The board: ``model``
    (a model file of separate squares), ``pattern``/``square`` (a chessboard, a ChArUco board, or a circle grid:
    ``evaluate.board.circle_grid``), or the shipped set's own.  ``tone``:
    how the stored values are decoded before locating (``tone.parse_tone``; default as stored)."""
    inp = resolve_inputs(list(items), model, pattern, square, marker)
    if inp.circles is not None and tone not in (None, "stored"):
        raise InputError(f"--tone {tone}: a circle grid's photos are studied as stored (OpenCV's blob centroids, the "
                         "reference row, read them so); drop --tone")
    # all methods but those that need a camera model (patch_esf_fit's PSF tables): there is none here
    methods = mo.ordered(camera_free() if methods is None else methods)
    for m in methods:
        locate.get_method(mo.resolve(m)[0])
    options = mo.study_options(thresholds)
    if inp.circles is not None:
        return _run_circles(inp, out, methods, options, channel, thresholds, progress)
    tone_t = check_tone(tone, inp)
    settings = settings_of(inp, methods, options, channel)
    if tone_t.kind != "stored":  # absent when stored, so earlier runs' directories still match
        settings["tone"] = tone_t.spec
    out = check_output(Path(out), settings)
    images, summary = decode_photos(inp, tone_t, channel, options, progress)
    run = compute_board_study(inp, methods, options, channel, progress, images=images, tone=summary)
    out = prepare_run_dir(out, KIND, settings)
    return write_board_run(run, out, channel, methods, options, thresholds)


def _run_circles(inp: BoardInputs, out, methods: list[str], options: dict, channel: str, thresholds,
                 progress: bool) -> Path:
    """``run_board_study`` on a circle grid (``evaluate.board.circle_grid``)."""
    out = check_output(Path(out), settings_of(inp, methods, options, channel))
    run = compute_circle_study(inp, methods, options, channel, progress)
    out = prepare_run_dir(out, KIND, settings_of(inp, methods, options, channel))
    return write_circle_run(run, out, channel, methods, options, thresholds)
