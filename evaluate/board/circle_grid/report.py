"""The circle-grid study's files: report.md, summary.csv, per_circle.csv, per_photo.csv, paired_tests.csv,
calibration/<row>.json and figures/ -- every one written atomically, after all the work is done (the board study's
writers, ``report.files``, where the files are alike)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from edgetruth import __version__
from edgetruth.evaluate import method_order as mo
from edgetruth.evaluate.board import circles as C
from edgetruth.evaluate.board.circle_grid.rows import DIST_MODEL, REFERENCE_ROW, intrinsics
from edgetruth.evaluate.board.circle_grid.summary import LENS
from edgetruth.evaluate.board.report import figures
from edgetruth.evaluate.board.report.files import (PAIRED_COLUMNS, csv_text, flat_summary, json_safe,
                                                   paired_tables, paired_test_rows, ranking)
from edgetruth.evaluate.calibration import DIST_MODELS
from edgetruth.evaluate.report_format import ci, num, table
from edgetruth.evaluate.run_dir import utc_stamp
from edgetruth.fileio import atomic_write_text, write_json
from edgetruth.resources import source_commit

CI_KEYS = ("ellipse_ci", "ellipse_ci_photos", "calib_rms_ci", "calib_rms_ci_photos", "loo_rms_ci",
           "loo_rms_ci_photos")
SUMMARY_COLUMNS = (
    "row", "label", "ellipse_rms_px", "ellipse_ci_lo", "ellipse_ci_hi", "ellipse_ci_photos_lo", "ellipse_ci_photos_hi",
    "ellipse_median_px", "circles_fitted", "circles_total", "points_per_circle", "fit_kept_fraction",
    "converged_fraction", "centres_used", "centres_total", "calib_rms_px", "calib_rms_ci_lo", "calib_rms_ci_hi",
    "calib_rms_ci_photos_lo", "calib_rms_ci_photos_hi", "loo_rms_px", "loo_rms_ci_lo", "loo_rms_ci_hi",
    "loo_rms_ci_photos_lo", "loo_rms_ci_photos_hi", *LENS, "centre_vs_blobs_px", "rounds", "moved_px", "refine_s",
    "failure")
PER_CIRCLE_COLUMNS = ("image", "circle", "row", "x_px", "y_px", "residual_px", "loo_residual_px", "n_points", "n_fit",
                      "ellipse_rms_px")
#: the name the report gives the circle analogue of straightness
ELLIPSE_NAME = "ellipse residual"


def header_lines(run, channel: str, methods: list[str], options: dict, thresholds) -> list[str]:
    """The report's header: version, time, inputs, board, method options, the procedure in one line."""
    inp, s, b = run.inp, run.setup, run.inp.circles
    tau = mo.thresholds_in_use(thresholds)
    w, h = s.size
    spacing = (f"OpenCV's squareSize {b.spacing:.4g} {b.units} (rows {b.spacing:.4g} {b.units} apart, neighbours in "
               f"a row {2 * b.spacing:.4g} {b.units})" if b.pattern.asymmetric else
               f"centres {b.spacing:.4g} {b.units} apart")
    return [
        f"edgetruth {__version__}, commit {source_commit()[:12]}; {utc_stamp()} (UTC); study time {run.elapsed_s:.1f} s.",
        "",
        f"- Photos: {', '.join(inp.names)} ({w}×{h} px, read as gray with rule `{channel}`); used: "
        f"{', '.join(s.names)}" + (f"; skipped: {', '.join(n for n, _ in s.skipped)}" if s.skipped else "") + ".",
        f"- Board: {b.source}: a{'n asymmetric' if b.pattern.asymmetric else ' symmetric'} grid of "
        f"{b.pattern.cols}×{b.pattern.rows} circles, {spacing}"
        + (f", circles {b.diameter:.4g} {b.units} across" if b.diameter else "")
        + f"; radius from the blobs {s.radius:.4g} {b.units}.",
        f"- Reference row: {run.reference_label} ({REFERENCE_ROW}): cv2.findCirclesGrid's centroids (its default "
        "SimpleBlobDetector on the photo as 8 bits), calibrated as plain OpenCV does.",
        f"- Methods ({len(methods)}): {', '.join(methods)}; entropy thresholds "
        f"2P {tuple(tau['2p'])}, 4P {tuple(tau['4p'])} ({tau['label']}).",
        f"- {mo.options_line(methods, options)}",
        "- Candidates: `locate.candidates` (Canny on the σ = 1 px smoothed image), once per photo, the same for "
        f"every method; those within {C.BAND_PX} px of a circle's outline as the blob calibration predicts it are "
        "refined.",
        "- Procedure (docs/board.md, Circle grids): each method's converged points per circle → undistorted with the "
        f"calibration's lens → ellipse (direct least squares; points beyond {C.OUTLIER_PX} px dropped, refitted) → "
        "the image of the circle's centre from the ellipse and the board plane's vanishing line (`corrected`), "
        f"iterated with the calibration's own lens and poses (at most {C.MAX_ROUNDS} rounds, to {C.TOL_PX:g} px) → "
        f"OpenCV calibrateCamera ({DIST_MODELS[DIST_MODEL][1]}; flags 0).",
    ]


def calibration_json(row, summary: dict, names: list[str]) -> dict:
    """calibration/<row>.json: intrinsics, poses, per-photo and LOO RMS, the centres used."""
    out = {"row": row.label, "label": summary["label"], "photos": names, "failure": row.failure,
           "model": DIST_MODEL}
    if row.cal is not None:
        out["calibration"] = {"intrinsics": intrinsics(row.cal["K"], row.cal["dist"]), "K": row.cal["K"],
                              "dist": row.cal["dist"], "rms_px": row.cal["rms_px"],
                              "rvecs": [p[0] for p in row.cal["poses"]], "tvecs": [p[1] for p in row.cal["poses"]],
                              "flags": f"0 ({DIST_MODELS[DIST_MODEL][1]})"}
        out["per_view_rms_px"] = row.cal["per_view_rms_px"]
        out["leave_one_out"] = {"rms_px": row.loo["rms_px"], "per_view_rms_px": row.loo["per_view_rms_px"],
                                "fold_intrinsics": row.loo["intrinsics"]}
    if row.is_method:
        out["centres"] = {"kind": "corrected", "rounds": row.rounds, "moved_px": row.moved_px}
    out["centres_px"] = dict(zip(names, row.points))
    return json_safe(out)


def _photos_table(run) -> list[dict]:
    s = run.setup
    why = dict(s.skipped)
    n = s.obj.shape[0]
    return [{"photo": name, "grid_found": "no" if name in why else "yes",
             "blobs_seen": s.blobs_seen.get(name, n), "used": "no" if name in why else "yes",
             "why_skipped": why.get(name, "")} for name in run.inp.names]


def _ellipse_table(sums) -> str:
    body = [[s["label"], num(s["ellipse_rms_px"]), ci(s["ellipse_ci"]), ci(s["ellipse_ci_photos"]),
             num(s["ellipse_median_px"]), f"{s['circles_fitted']}/{s['circles_total']}", num(s["points_per_circle"], 1),
             num(100 * s["fit_kept_fraction"], 1), num(100 * s["converged_fraction"], 1), s["rounds"]]
            for s in sums if s["row"] != REFERENCE_ROW]
    return table(["method", f"{ELLIPSE_NAME} RMS (px)", "95 % CI (circles)", "95 % CI (photos)",
                  "median circle (px)", "circles fitted", "points / circle", "kept by the fit (%)", "converged (%)",
                  "rounds"], body)


def _calibration_table(sums) -> str:
    body = []
    for s in sums:
        if "calib_rms_px" not in s:
            body.append([s["label"], *("—",) * 15, s.get("failure") or "—"])
            continue
        body.append([s["label"], num(s["calib_rms_px"]), ci(s["calib_rms_ci"]), ci(s["calib_rms_ci_photos"]),
                     num(s["loo_rms_px"]), ci(s["loo_rms_ci"]), ci(s["loo_rms_ci_photos"]),
                     *(num(s[k], 2) for k in ("fx", "fy", "cx", "cy")), *(num(s[k], 4) for k in LENS[4:]),
                     f"{s['centres_used']}/{s['centres_total']}", num(s["centre_vs_blobs_px"])])
    return table(["row", "calib RMS (px)", "95 % CI (circles)", "95 % CI (photos)", "LOO RMS (px)",
                  "95 % CI (circles)", "95 % CI (photos)", "fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3",
                  "centres", "mean |centre − blob| (px)"], body)


def _per_photo_table(sums, names) -> str:
    nan = [float("nan")] * len(names)
    body = [[s["label"], *(f"{num(a)} / {num(b)} / {num(c)}" for a, b, c in
                           zip(s.get("per_photo_ellipse_px", nan), s.get("calib_per_photo_px", nan),
                               s.get("loo_per_photo_px", nan)))] for s in sums]
    return table(["row", *names], body)


def _tests_line(c: dict, labels: dict) -> str:
    """One family's paired tests in a sentence: how many rows differ significantly from the baseline, each way,
    over the circles and by photo."""
    lower = [t for t in c["tests"] if t["significant"] and t["median_difference"] < 0]
    higher = [t for t in c["tests"] if t["significant"] and t["median_difference"] > 0]
    n_ph = c["tests"][0]["n_photos"]
    return (f"- {c['label']}: against {labels.get(c['baseline'], c['baseline'])}, {len(lower)} of {len(c['tests'])} "
            f"rows significantly lower ({', '.join(labels.get(t['row'], t['row']) for t in lower) or 'none'}), "
            f"{len(higher)} higher ({', '.join(labels.get(t['row'], t['row']) for t in higher) or 'none'}); by photo "
            f"(n = {n_ph}) {sum(t['significant_photos'] for t in c['tests'])} significant.")


def reading(sums, comparisons=()) -> list[str]:
    """Rankings as measured, the paired tests in a line per family, and the methods against OpenCV's centroids;
    nothing tuned."""
    methods = [s for s in sums if s["row"] != REFERENCE_ROW]
    ref = next((s for s in sums if s["row"] == REFERENCE_ROW), None)
    lines = ["Rankings as measured (lowest first):", "",
             f"- {ELLIPSE_NAME.capitalize()} (px): {ranking(methods, 'ellipse_rms_px')}.",
             f"- Calibration RMS (px): {ranking(sums, 'calib_rms_px')}.",
             f"- Leave-one-image-out RMS (px): {ranking(sums, 'loo_rms_px')}."]
    if ref is not None and "calib_rms_px" in ref:
        below = [s["label"] for s in methods if s.get("loo_rms_px", np.inf) < ref["loo_rms_px"]]
        lines += ["", f"{ref['label']} calibrate to {ref['calib_rms_px']:.3f} px (LOO {ref['loo_rms_px']:.3f} px, "
                      f"fx {ref['fx']:.2f} px); "
                      + (f"{len(below)} of {len(methods)} method(s) come below its LOO RMS as measured (whether "
                         "significantly: the paired tests)." if below else
                         "no method's centres come below its LOO RMS.")]
    labels = {s["row"]: s["label"] for s in sums}
    tested = [c for c in comparisons if c["tests"]]
    if tested:
        lines += ["", "Paired tests (Wilcoxon over the circles every row has, Holm; by photo: over the photos' means):",
                  "", *(_tests_line(c, labels) for c in tested)]
    failed = [s["label"] for s in sums if s.get("failure")]
    if failed:
        lines += ["", f"Rows that did not calibrate: {', '.join(failed)} (Table 2)."]
    return lines


def write_circle_outputs(out: Path, run, title: str, header: list[str]) -> Path:
    """Every output file of the circle-grid study ``run`` (``study.CircleRun``) into the existing ``out``; returns
    report.md's path."""
    (out / "calibration").mkdir(exist_ok=True)
    (out / "figures").mkdir(exist_ok=True)
    sums, names = run.summaries, run.setup.names
    photos = _photos_table(run)
    atomic_write_text(out / "summary.csv", csv_text(SUMMARY_COLUMNS, [flat_summary(s, CI_KEYS) for s in sums]))
    atomic_write_text(out / "per_circle.csv", csv_text(PER_CIRCLE_COLUMNS, run.per_circle))
    atomic_write_text(out / "per_photo.csv", csv_text(tuple(photos[0]), photos))
    atomic_write_text(out / "paired_tests.csv", csv_text(PAIRED_COLUMNS, paired_test_rows(run.comparisons)))
    for row, s in zip(run.rows, sums):
        write_json(out / "calibration" / f"{row.label}.json", calibration_json(row, s, names))
    fig = figures.calibration_rms([s for s in sums if "calib_rms_px" in s], out / "figures")
    labels = {s["row"]: s["label"] for s in sums}
    lines = [f"# {title}", "", *header, "",
             "## Photos", "",
             table(["photo", "grid found", "blobs seen", "used", "why skipped"],
                   [[p["photo"], p["grid_found"], p["blobs_seen"], p["used"], p["why_skipped"] or "—"]
                    for p in photos]), "",
             f"## Table 1 — {ELLIPSE_NAME} (per method)", "",
             "The circle analogue of straightness: each circle's refined points, undistorted with the row's own "
             "calibration, against the ellipse fitted to them; the first-order geometric distance (px), RMS pooled "
             f"over every point the fit kept (within {C.OUTLIER_PX} px of its first fit) on every circle of every "
             "photo (95 % percentile bootstrap CIs resampling circles, and photos with all their circles); "
             "converged: share of the Canny candidates near the outlines that the method refined.", "",
             _ellipse_table(sums), "",
             f"## Table 2 — calibration ({DIST_MODELS[DIST_MODEL][1]}) of each row's circle centres", "",
             "Calibration RMS: OpenCV's reprojection RMS over every circle of every photo used; LOO: each photo's "
             "centres reprojected with the lens calibrated on the other photos and the pose found by solvePnP (the "
             "centres held fixed); CIs resample circles, and photos with all their circles (calibration held fixed); "
             "last column: mean distance of the row's centres from OpenCV's blob centroids.", "",
             _calibration_table(sums), "",
             "## Table 3 — per photo", "",
             f"{ELLIPSE_NAME.capitalize()} / calibration RMS / leave-one-image-out RMS (px) of each photo used.", "",
             _per_photo_table(sums, names), "",
             "## Paired tests", "",
             "Every row against the baseline on the circles all rows have; Holm-adjusted within each family; "
             "rank-biserial > 0: the row's values tend to be larger (worse) than the baseline's.", "",
             *paired_tables(run.comparisons, labels),
             "## Reading", "", *reading(sums, run.comparisons), "",
             "## Figures", "", f"![calibration and leave-one-out RMS](figures/{fig})", "",
             "## Files", "",
             "`summary.csv` (one line per row, every figure above), `per_circle.csv` (one line per photo, circle and "
             "row; circles in OpenCV's order from 0), `per_photo.csv`, `paired_tests.csv`, `calibration/<row>.json` "
             "(intrinsics, poses, per-photo and LOO RMS, the centres used), `figures/`.", ""]
    report = out / "report.md"
    atomic_write_text(report, "\n".join(lines))
    return report
