"""The board study's files: report.md, summary.csv, per_side.csv, per_photo.csv, paired_tests.csv,
calibration/<row>.json and figures/ -- every one written atomically, after all the work is done."""
from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np
from scipy import stats as st

from edgetruth import __version__
from edgetruth.evaluate import method_order as mo
from edgetruth.evaluate.board.measure.rows import REFERENCE_ROWS
from edgetruth.evaluate.board.measure.summary import INTRINSICS
from edgetruth.evaluate.board.report import figures
from edgetruth.evaluate.board.tone import locator_fit as LF
from edgetruth.evaluate.report_format import ci, num, table
from edgetruth.evaluate.run_dir import utc_stamp
from edgetruth.evaluate.stats import spearman
from edgetruth.fileio import atomic_write_bytes, atomic_write_text, write_json
from edgetruth.resources import source_commit


SUMMARY_COLUMNS = (
    "row", "label", "straightness_px", "straightness_ci_lo", "straightness_ci_hi", "straightness_ci_photos_lo",
    "straightness_ci_photos_hi", "straightness_median_px",
    "sides_covered", "sides_total", "side_coverage", "points_per_side", "converged_fraction", "corners_used",
    "corners_total", "calib_rms_px", "calib_rms_ci_lo", "calib_rms_ci_hi", "calib_rms_ci_photos_lo",
    "calib_rms_ci_photos_hi", "loo_rms_px", "loo_rms_ci_lo", "loo_rms_ci_hi", "loo_rms_ci_photos_lo",
    "loo_rms_ci_photos_hi", *INTRINSICS, *(f"d_{k}" for k in INTRINSICS), "length_bias_model", "length_rmse_model",
    "length_bias_px", "length_rmse_px", "length_sides", "corner_vs_reference_px", "junction_split_px",
    "own_corner_outward_px", "refine_s", "failure")


#: The reading calls a chessboard's dark squares smaller or larger when every method's own corners lie at least
#: this far (px) on one side of the junctions (an exact render: 0.0004 px; OpenCV's photos: 0.16 px).
OWN_CORNER_NOTICE_PX = 0.01


def csv_text(header, rows) -> str:
    """CSV text: ``header``, then one line per dict of ``rows`` (floats as repr, NaN and None empty)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    for r in rows:
        w.writerow(["" if r.get(k) is None else _v(r.get(k)) for k in header])
    return buf.getvalue()


def _v(v):
    if isinstance(v, (float, np.floating)):
        return "" if not np.isfinite(v) else repr(float(v))
    return v


#: a summary's CIs (lo, hi), split into two columns each by ``flat_summary``
CI_KEYS = ("straightness_ci", "calib_rms_ci", "loo_rms_ci", "straightness_ci_photos", "calib_rms_ci_photos",
           "loo_rms_ci_photos")


def flat_summary(s: dict, keys=CI_KEYS) -> dict:
    """A row's summary with each CI of ``keys`` as two columns, ``KEY_lo`` and ``KEY_hi``."""
    out = dict(s)
    for k in keys:
        out[f"{k}_lo"], out[f"{k}_hi"] = s.get(k, (float("nan"), float("nan")))
    return out


def json_safe(obj):
    """``obj`` with numpy values as plain Python ones and non-finite floats as None, for JSON."""
    if isinstance(obj, dict):
        return {k: json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return json_safe(obj.tolist())
    if isinstance(obj, (float, np.floating)):
        return float(obj) if np.isfinite(obj) else None
    if isinstance(obj, (np.integer,)):
        return int(obj)
    return obj


def calibration_json(row, summary: dict, photo_names: list[str]) -> dict:
    out = {"row": row.label, "label": summary["label"], "photos": photo_names, "failure": row.failure}
    if row.cal is not None:
        out["calibration"] = row.cal.to_dict()
        out["calibration"]["flags"] = "CALIB_ZERO_TANGENT_DIST | CALIB_FIX_K3 (k1, k2; skew 0)"
        out["per_view_rms_px"] = [float(np.sqrt(np.nanmean(r ** 2))) for r in row.cal.residual_px]
        out["leave_one_out"] = {"rms_px": row.loo["rms_px"], "per_view_rms_px": row.loo["per_view_rms_px"],
                                "fold_intrinsics": row.loo["intrinsics"]}
        if "d_fx" in summary:
            out["difference_from_reference"] = {k: summary[f"d_{k}"] for k in INTRINSICS}
    out["corners_px"] = {n: c for n, c in zip(photo_names, row.corners)}
    return json_safe(out)


# ------------------------------------------------------------------------------------------- markdown
def header_lines(inp, used_names: list[str], size: tuple[int, int], channel: str, methods: list[str], options: dict,
                 thresholds, reference: dict | None, reference_row: str | None, elapsed_s: float,
                 tone: dict | None = None) -> list[str]:
    """The report's header: version, time, inputs, method options, the procedure in one line.  ``reference_row``:
    the key of the reference row in ``REFERENCE_ROWS``, None when there is none; ``tone``: how the stored values
    were decoded (``study.tone_summary``; None: as stored)."""
    tau = mo.thresholds_in_use(thresholds)
    w, h = size
    chess = inp.model.pattern is not None
    if chess and inp.model.charuco is not None:
        squares = ("OpenCV's ChArUco corners (CharucoDetector: markers, interpolation, cornerSubPix; every corner "
                   "found) → the dark squares between them (the board's own layout)")
    if chess:
        squares = squares if inp.model.charuco is not None else (
            "OpenCV's chessboard corners (findChessboardCorners, cornerSubPix) → the dark squares between "
            "them (a 180° turn or a mirror puts the dark squares on the model's)")
        model_line = (f"- Model: {inp.model.source}: the {len(inp.model)} dark squares between the "
                      f"{inp.model.pattern[0]}×{inp.model.pattern[1]} inner corners, side "
                      f"{inp.model.square:.4g} {inp.model.units}.")
    else:
        squares = "dark quads → the model's squares by a homography (symmetric boards: no mirror, model +x closest " \
                  "to image +x)"
        model_line = (f"- Model: `{inp.model.source}`, {len(inp.model)} squares, side "
                      f"{np.median(inp.model.side_lengths):.4g} {inp.model.units}.")
    ref_line = "the set's own corners" if not chess else "the inner corners OpenCV finds the board by"
    corners = ("corners where the two grid lines through each inner corner meet, each fitted to the points on both "
               "its halves" if chess else "corners by intersection")
    return [
        f"edgetruth {__version__}, commit {source_commit()[:12]}; {utc_stamp()} (UTC); study time {elapsed_s:.1f} s.",
        "",
        f"- Photos: {', '.join(inp.names)} ({w}×{h} px, read as gray with rule `{channel}`); used: "
        f"{', '.join(used_names)}.",
        model_line,
        f"- Reference: {reference['source'] if reference else 'none'}"
        + (f"; reference row: {ref_line} ({reference_row})" if reference_row else "") + ".",
        tone_line(tone),
        f"- Methods ({len(methods)}): {', '.join(methods)}; entropy thresholds "
        f"2P {tuple(tau['2p'])}, 4P {tuple(tau['4p'])} ({tau['label']}).",
        f"- {mo.options_line(methods, options)}",
        "- Candidates: `locate.candidates` (Canny on the σ = 1 px smoothed image), once per photo, the same for "
        "every method; those within 5 px of a detected square's side are refined.",
        f"- Procedure (docs/board.md): {squares} → each method's converged points within 3 px then 1.5 px of a "
        f"side, 3 px from its corners, normal within 30° → total-least-squares line per side → {corners} → "
        "OpenCV calibrateCamera (k1, k2; CALIB_ZERO_TANGENT_DIST | CALIB_FIX_K3).",
    ]


def tone_line(tone: dict | None) -> str:
    """The header's line on the tone (``--tone``, evaluate/board/tone/values.py)."""
    if tone is None:
        return ("- Tone: the stored values, as stored (`--tone` decodes them first: srgb, power:G, or auto on a "
                "chessboard).")
    fit = tone.get("fit")
    if not fit:
        return f"- Tone (`--tone {tone['spec']}`): {tone['describe']}."
    per = list(fit["per_photo"].values())
    return (f"- Tone (`--tone {tone['spec']}`): power {fit['power']:.3f} (95 % CI {fit['ci95'][0]:.3f}–"
            f"{fit['ci95'][1]:.3f}, {len(per)} photos; per photo {min(per):.2f}–{max(per):.2f}), measured as the "
            f"power at which {fit['method']}'s own corners meet the junctions (mean offset "
            f"{fit['offset_stored_px']:+.3f} px as stored, {fit['offset_fit_px']:+.4f} px decoded; tone.json); "
            f"{tone['describe']}; "
            + ("one power fits every photo" if fit["one_power_fits"] else "one power does not fit every photo "
               f"(Cochran's Q p {p_text(fit['cochran_q_p'])}; Reading)") + ".")


def _tone_table(fit: dict) -> list[str]:
    """The measured tone per photo (``--tone auto``), brightest last: levels, white noise, power and its SE."""
    photos = sorted(fit["per_photo"], key=lambda k: fit["white_level"][k])
    body = [[k, num(fit["dark_level"][k], 1), num(fit["white_level"][k], 1), num(fit["white_sd"][k], 2),
             num(fit["per_photo"][k], 3), num(fit["per_photo_se"][k], 3)] for k in photos]
    rho, p = fit["spearman_rho_white_sd"], fit["spearman_p_white_sd"]
    return ["## Tone per photo (`--tone auto`)", "",
            f"Each photo's power: the zero of {fit['method']}'s mean outward offset of its own corners, from the local "
            "slope at the set's power; levels: the median stored value at the dark and the light squares' centres; "
            "white SD: the noise of the light squares' centre patches about their means (docs/board.md, Tone).  "
            + (f"White SD against the white level: Spearman ρ = {rho:+.2f}, p {p_text(p)} (shot noise alone makes it "
               "rise; a curve flattening towards white makes it fall)." if np.isfinite(rho) else ""), "",
            table(["photo", "dark", "white", "white SD", "power", "SE"], body), ""]


def p_text(p: float) -> str:
    """'= 0.012' or '< 1e-300' (a p below what a double holds)."""
    return "< 1e-300" if p < 1e-300 else f"= {p:.2g}"


def tone_agreement(fit: dict) -> str:
    """Whether one power describes every photo (Cochran's Q), and how the per-photo powers follow the white level."""
    per = list(fit["per_photo"].values())
    q = f"Cochran's Q = {fit['cochran_q']:.1f}, p {p_text(fit['cochran_q_p'])}, {len(per)} photos"
    rho = (f"Spearman ρ = {fit['spearman_rho_power_white']:+.2f}, p {p_text(fit['spearman_p_power_white'])}"
           if np.isfinite(fit["spearman_rho_power_white"]) else "ρ undefined")
    if fit["one_power_fits"]:
        return f"One power describes every photo ({q}; per photo {min(per):.2f}–{max(per):.2f})."
    return (f"One power does not describe every photo ({q}): per photo it runs from {min(per):.2f} to "
            f"{max(per):.2f}, against the photos' white level {rho} (tone.json).  A power that changes with the "
            "exposure is a tone curve that is not a power law (a highlight shoulder, clipping), or not a tone curve "
            "at all; the decoded study corrects the set on average only.")


def _straightness_table(sums) -> str:
    body = [[s["label"], num(s["straightness_px"]), ci(s["straightness_ci"]), ci(s["straightness_ci_photos"]),
             num(s["straightness_median_px"]),
             f"{s['sides_covered']}/{s['sides_total']}", num(s["points_per_side"], 1),
             num(100 * s["converged_fraction"], 1)] for s in sums if s["row"] not in REFERENCE_ROWS]
    return table(["method", "straightness RMS (px)", "95 % CI (sides)", "95 % CI (photos)", "median side RMS (px)",
                  "sides covered",
                  "points / side", "converged (%)"], body)


def _calibration_table(sums, reference) -> str:
    body = []
    for s in sums:
        if "calib_rms_px" not in s:
            body.append([s["label"], "—", "—", "—", "—", "—", "—", *("—",) * 6, s.get("failure") or "—"])
            continue
        body.append([s["label"], num(s["calib_rms_px"]), ci(s["calib_rms_ci"]), ci(s["calib_rms_ci_photos"]),
                     num(s["loo_rms_px"]), ci(s["loo_rms_ci"]), ci(s["loo_rms_ci_photos"]), num(s["fx"], 2),
                     num(s["fy"], 2), num(s["cx"], 2), num(s["cy"], 2),
                     num(s["k1"], 4), num(s["k2"], 4), f"{s['corners_used']}/{s['corners_total']}"])
    if reference:
        # a reference computed here names itself (its source), a published one says so
        first = (reference.get("source", "reference") if "row_label" in reference
                 else f"published ({reference.get('source', 'reference')})")
        body.append([first, num(reference["rms_px"]) if "rms_px" in reference else "—", "—", "—", "—", "—", "—",
                     *(num(reference[k], 2) for k in ("fx", "fy", "cx", "cy")), num(reference["k1"], 4),
                     num(reference["k2"], 4), "—"])
    return table(["row", "calib RMS (px)", "95 % CI (corners)", "95 % CI (photos)", "LOO RMS (px)",
                  "95 % CI (corners)", "95 % CI (photos)", "fx", "fy", "cx", "cy", "k1", "k2", "corners"], body)


def _difference_table(sums) -> str:
    body = [[s["label"], *(num(s[f"d_{k}"], 2) for k in ("fx", "fy", "cx", "cy")),
             *(num(s[f"d_{k}"], 4) for k in ("k1", "k2")), num(s.get("corner_vs_reference_px", float("nan")))]
            for s in sums if "d_fx" in s]
    return table(["row", "Δfx", "Δfy", "Δcx", "Δcy", "Δk1", "Δk2", "mean |corner − set's corner| (px)"], body)


def _junction_table(sums) -> str:
    nan = float("nan")
    body = [[s["label"], num(s.get("corner_vs_reference_px", nan)), num(s.get("junction_split_px", nan)),
             num(s.get("own_corner_outward_px", nan))] for s in sums if "corner_vs_reference_px" in s]
    return table(["row", "mean |corner − OpenCV's corner| (px)", "the two squares' own corners apart (px)",
                  "own corner outward of the junction (px)"], body)


def _length_table(sums, units: str) -> str:
    body = [[s["label"], num(s["length_bias_model"], 4), num(s["length_rmse_model"], 4), num(s["length_bias_px"]),
             num(s["length_rmse_px"]), s["length_sides"]] for s in sums if "length_bias_model" in s]
    return table(["row", f"bias ({units})", f"RMSE ({units})", "bias (px)", "RMSE (px)", "sides"], body)


def _per_photo_table(sums, photo_names: list[str]) -> str:
    """Straightness / calibration RMS / LOO RMS per photo (px), one line per row."""
    body = []
    for s in sums:
        st = s.get("per_photo_straightness_px", [float("nan")] * len(photo_names))
        ca = s.get("calib_per_photo_px", [float("nan")] * len(photo_names))
        lo = s.get("loo_per_photo_px", [float("nan")] * len(photo_names))
        body.append([s["label"], *(f"{num(a)} / {num(b)} / {num(c)}" for a, b, c in zip(st, ca, lo))])
    return table(["row", *photo_names], body)


def paired_tables(comparisons, labels: dict) -> list[str]:
    """The report's lines of the paired tests (``measure.compare``), one table per family; ``labels``: row -> label."""
    out = []
    for c in comparisons:
        if not c["tests"]:
            continue
        f = c["friedman"]
        out += [f"### {c['label']}", "",
                f"{c['n_units']} units every row has; Friedman over {len(c['rows'])} rows: "
                f"χ² = {num(f['statistic'], 1)}, p = {f['p_value']:.2g}, Kendall's W = {num(f['kendall_w'])}. "
                f"Baseline: {labels.get(c['baseline'], c['baseline'])}.  By photo: the units come from "
                f"{c['tests'][0]['n_photos']} photos and are not independent within one; the last three columns "
                "resample photos, count the photos whose own mean Δ has the overall sign, and test the photos' "
                "mean Δ (Wilcoxon, Holm).",
                ""]
        body = [[labels.get(t["row"], t["row"]), num(t["mean_row"], 4), num(t["mean_baseline"], 4),
                 num(t["median_difference"], 4), ci(t["mean_difference_ci"], 4), num(t["rank_biserial"], 2),
                 f"{t['p_holm']:.2g}", "yes" if t["significant"] else "no", ci(t["mean_difference_ci_photos"], 4),
                 f"{t['photos_same_sign']}/{t['n_photos']}", f"{t['p_holm_photos']:.2g}"] for t in c["tests"]]
        out += [table(["row", "mean", "baseline mean", "median Δ", "mean Δ 95 % CI", "rank-biserial", "p (Holm)",
                       "significant", "by photo: mean Δ 95 % CI", "same sign", "p (Holm)"], body), ""]
    return out


def ranking(sums, key: str, nd: int = 3) -> str:
    """'label value, ...' of the rows with a finite ``key``, lowest first."""
    rows = sorted((s for s in sums if np.isfinite(s.get(key, float("nan")))), key=lambda s: s[key])
    return ", ".join(f"{s['label']} {s[key]:.{nd}f}" for s in rows)


def reading(sums, comparisons, reference, tone: dict | None = None, photos: list[dict] | None = None) -> list[str]:
    """A short reading of the measured tables: rankings as measured, nothing tuned.  ``photos``: the per-photo
    table, whose saturated whites (a chessboard's) get a line."""
    methods = [s for s in sums if s["row"] not in REFERENCE_ROWS]
    ref = next((s for s in sums if s["row"] in REFERENCE_ROWS), None)
    lines = ["Rankings as measured (lowest first):", "",
             f"- Straightness (px): {ranking(methods, 'straightness_px')}.",
             f"- Calibration RMS (px): {ranking(sums, 'calib_rms_px')}.",
             f"- Leave-one-image-out RMS (px): {ranking(sums, 'loo_rms_px')}.",
             f"- Side-length RMSE (px): {ranking(sums, 'length_rmse_px')}."]
    both = [s for s in methods if np.isfinite(s["straightness_px"]) and np.isfinite(s.get("calib_rms_px", np.nan))]
    if len(both) >= 3:
        sp = spearman([s["straightness_px"] for s in both], [s["calib_rms_px"] for s in both])
        rho, p = sp["rho"], sp["p"]
        lines += ["", f"Across the {len(both)} methods, straightness and calibration RMS rank alike to Spearman "
                      f"ρ = {rho:.2f} (p = {p:.2g}): a straighter side does "
                      f"{'' if rho > 0.5 and p < 0.05 else 'not clearly '}give a better calibration here."]
    if ref is not None and "calib_rms_px" in ref:
        below = [s["label"] for s in methods if s.get("calib_rms_px", np.inf) < ref["calib_rms_px"]]
        lines += ["", f"{ref['label']} calibrate to {ref['calib_rms_px']:.3f} px (LOO {ref['loo_rms_px']:.3f} px); "
                      + (f"{len(below)} method(s) come below: {', '.join(below)}." if below else
                         "no method's corners come below them.")]
    lengths = [s for s in sums if np.isfinite(s.get("length_bias_px", np.nan))]
    if lengths:
        lo, hi = min(s["length_bias_px"] for s in lengths), max(s["length_bias_px"] for s in lengths)
        lines += ["", f"Side lengths in the board plane: the bias lies between {lo:.3f} and {hi:.3f} px across rows"
                      + (f" ({ref['label']}: {ref['length_bias_px']:.3f} px)" if ref is not None and
                         "length_bias_px" in ref else "")
                      + ("; every row shares its sign, so it belongs to the board as photographed (its print, the "
                         "camera's blur of dark on white) more than to any method." if lo * hi > 0 else ".")]
    own = [s["own_corner_outward_px"] for s in methods if np.isfinite(s.get("own_corner_outward_px", np.nan))]
    if own:
        lo, hi = min(own), max(own)
        if hi < -OWN_CORNER_NOTICE_PX or lo > OWN_CORNER_NOTICE_PX:
            where, what = (("inside", "smaller than the light ones (a tone curve after the blur does this, and so "
                            "does flare)") if hi < 0 else ("outside", "larger than the light ones (ink spread does "
                                                           "this)"))
            lines += ["", f"Each dark square's own side lines put its corners {min(abs(lo), abs(hi)):.3f}–"
                          f"{max(abs(lo), abs(hi)):.3f} px {where} the junctions: the dark squares image {what}.  "
                          "The corners at the junctions, on lines through both halves, do not see it (Table 3; "
                          "docs/board.md, Chessboards)."]
        else:
            lines += ["", f"Each dark square's own side lines put its corners within {lo:+.3f} to {hi:+.3f} px of "
                          "the junctions (Table 3)."]
    sat = [p["photo"] for p in photos or [] if p.get("white_saturated") == "yes"]
    if sat:
        lines += ["", f"{len(sat)} of {len(photos)} photos have a saturated white (their light squares' centres are "
                      f"flat, white SD below half the dark squares'): {', '.join(sat)}.  A clipped white makes the dark "
                      "squares image small to their own side lines, more the more of the white is clipped (clipped "
                      "renders and OpenCV's photos, docs/board.md, Tone); the corners at the junctions do not see "
                      "it, and `--tone auto` measures it per photo."]
    if tone is not None and tone.get("fit"):
        fit = tone["fit"]
        lines += ["", f"The photos were decoded with the power {fit['power']:.3f} measured at the junctions, so "
                      f"{fit['method']}'s own corners meet them on average by construction; the other methods' "
                      "offsets (Table 3) are measured.  A power above 1 says the stored edges had their dark side "
                      "lifted, as a tone curve does; flare would do the same, and the power does not tell them "
                      "apart.  " + tone_agreement(fit)]
    if reference and both:
        dfx = [abs(s["d_fx"]) for s in both if "d_fx" in s]
        if dfx:
            lines += ["", f"fx of the methods lies within {min(dfx):.2f}–{max(dfx):.2f} px of the published "
                          f"{reference['fx']:.2f} px."]
    sig = next((c for c in comparisons if c["family"] == "straightness" and c["tests"]), None)
    if sig:
        better = [t for t in sig["tests"] if t["significant"] and t["median_difference"] < 0]
        worse = [t for t in sig["tests"] if t["significant"] and t["median_difference"] > 0]
        lab = {s["row"]: s["label"] for s in sums}
        lines += ["", f"Against {lab.get(sig['baseline'], sig['baseline'])} on the same sides (Wilcoxon, Holm): "
                      f"{len(better)} method(s) significantly straighter "
                      f"({', '.join(lab.get(t['row'], t['row']) for t in better) or 'none'}), "
                      f"{len(worse)} significantly "
                      f"less straight; by photo (n = {sig['tests'][0]['n_photos']}; Wilcoxon over the photos' means, "
                      f"Holm) {sum(t['significant_photos'] for t in better)} and "
                      f"{sum(t['significant_photos'] for t in worse)} of them, and "
                      f"{sum(t['photos_same_sign'] == t['n_photos'] for t in better + worse)} of the "
                      f"{len(better) + len(worse)} differ the same way on every photo."]
    return lines


#: paired_tests.csv's columns (``paired_test_rows``)
PAIRED_COLUMNS = ("family", "baseline", "row", "n_units", "n_pairs", "mean_row", "mean_baseline", "median_difference",
                  "mean_difference_ci_lo", "mean_difference_ci_hi", "rank_biserial", "p_value", "p_holm",
                  "significant", "n_photos", "photos_same_sign", "mean_difference_ci_photos_lo",
                  "mean_difference_ci_photos_hi", "p_value_photos", "p_holm_photos", "significant_photos",
                  "friedman_p", "kendall_w")


def paired_test_rows(comparisons) -> list[dict]:
    """paired_tests.csv: one dict per test of every family (``measure.compare``), its CIs split into lo and hi."""
    return [{"family": c["family"], "baseline": c["baseline"], "n_units": c["n_units"],
             "friedman_p": c["friedman"]["p_value"], "kendall_w": c["friedman"]["kendall_w"], **t,
             "mean_difference_ci_lo": t["mean_difference_ci"][0], "mean_difference_ci_hi": t["mean_difference_ci"][1],
             "mean_difference_ci_photos_lo": t["mean_difference_ci_photos"][0],
             "mean_difference_ci_photos_hi": t["mean_difference_ci_photos"][1]}
            for c in comparisons for t in c["tests"]]


def write_outputs(out: Path, *, title: str, header_lines: list[str], photos_table: list[dict], rows, summaries,
                  comparisons, reference, model, photo_names, per_side, locator=None, tone=None,
                  overlays=None) -> Path:
    """Every output file of the study; returns report.md's path.  ``tone``: how the stored values were decoded
    (``study.tone_summary``), written as tone.json when given; ``overlays``: [(file name, PNG bytes)] per photo
    used, written into figures/ and linked from the "Squares found" table."""
    (out / "calibration").mkdir(exist_ok=True)
    (out / "figures").mkdir(exist_ok=True)
    pictures = {}
    for (fname, data), photo in zip(overlays or [], photo_names):
        atomic_write_bytes(out / "figures" / fname, data)
        pictures[photo] = f"[overlay](figures/{fname})"
    atomic_write_text(out / "summary.csv", csv_text(SUMMARY_COLUMNS, [flat_summary(s) for s in summaries]))
    atomic_write_text(out / "per_side.csv", csv_text(
        ("image", "square", "side", "method", "n_points", "rms_px", "length_model", "length_measured", "length_err",
         "length_err_px"), per_side))
    atomic_write_text(out / "per_photo.csv", csv_text(tuple(photos_table[0]), photos_table))
    photo_headers = {"photo": "photo", "squares_found": "squares found", "squares_total": "of",
                     "missing": "missing (model order, from 0)",
                     "quad_residual_px": "quad corners about homography (px)",
                     "candidates_near_sides": "candidates near sides", "used": "used",
                     "dark_level": "dark", "white_level": "white", "dark_sd": "dark SD", "white_sd": "white SD",
                     "white_saturated": "white saturated"}
    atomic_write_text(out / "paired_tests.csv", csv_text(PAIRED_COLUMNS, paired_test_rows(comparisons)))
    if locator:
        write_json(out / "locator.json", json_safe(locator))
    if tone:
        write_json(out / "tone.json", json_safe(tone))
    tone_table = _tone_table(tone["fit"]) if tone and tone.get("fit") else []
    for row, s in zip(rows, summaries):
        write_json(out / "calibration" / f"{row.label}.json", calibration_json(row, s, photo_names))
    if reference:  # the intrinsics every row is compared with, and where they come from
        write_json(out / "calibration" / "reference.json", json_safe(reference))
    errors_px = {r.label: np.concatenate([e.ravel() for e in r.lengths["error_px"]]) for r in rows if r.lengths}
    figs = [figures.straightness(summaries, out / "figures"), figures.calibration_rms(summaries, out / "figures"),
            figures.side_length_error(summaries, errors_px, out / "figures")]
    labels = {s["row"]: s["label"] for s in summaries}
    lines = [f"# {title}", "", *header_lines, "",
             "## Squares found", "", table([photo_headers[k] for k in photos_table[0]] + (["picture"] if pictures else []),
                                           [[num(v, 2) if isinstance(v, float) else ("—" if v in ("", None) else v)
                                             for v in p.values()] + ([pictures.get(p["photo"], "—")] if pictures else [])
                                            for p in photos_table]), "",
             *(["Overlays: the squares found (green) and one method's fitted side lines (magenta) on each photo used.",
                ""] if pictures else []),
             "## Table 1 — straightness and coverage (per method)", "",
             "RMS of each side's refined points about its total-least-squares line, pooled over every covered side "
             "of every photo (95 % percentile bootstrap CIs resampling sides, and resampling photos with all their "
             "sides: a photo's sides are not independent of each other); a side is covered with at least 5 "
             "points; converged: share of the Canny candidates within 5 px of a detected square's side that the "
             "method refined.", "",
             _straightness_table(summaries), "",
             "## Table 2 — calibration (k1, k2; skew 0) of each row's corners", "",
             "Calibration RMS: OpenCV's reprojection RMS over all corners of all photos; LOO: each photo's corners "
             "reprojected with intrinsics calibrated on the other photos and the pose found by solvePnP; CIs resample "
             "corners, and photos with all their corners (calibration held fixed).", "",
             _calibration_table(summaries, reference), ""]
    if reference:
        lines += ["## Table 3 — differences from the published calibration", "",
                  f"Each row's intrinsics minus {reference.get('source', 'the reference')} "
                  f"(fx {reference['fx']:.2f}, fy {reference['fy']:.2f}, cx {reference['cx']:.2f}, "
                  f"cy {reference['cy']:.2f}, k1 {reference['k1']:.4f}, k2 {reference['k2']:.4f}); last column: mean "
                  "distance of the row's corners to the set's own corners.", "",
                  _difference_table(summaries), ""]
    elif model.pattern is not None:
        lines += ["## Table 3 — junctions: corners against OpenCV's, and each square's own", "",
                  "A method's corner at an inner corner of a chessboard is the intersection of the two grid lines "
                  "through it, each fitted to the points on both its halves (a side of either dark square; on the "
                  "grid's border, the side continued into the outer ring).  Against OpenCV's corner (cornerSubPix) "
                  "at the same inner corner; and, where two dark squares meet, how far apart the two "
                  "squares' own corners (from each square's own side lines) fall, a distance that any difference "
                  "between how large dark and light squares print or image puts there, and the mean signed distance "
                  "of a square's own corner from the junction along the square's diagonal (< 0: its own side lines "
                  "make the dark square smaller; docs/board.md).", "",
                  _junction_table(summaries), ""]
    lines += ["## Table 4 — side lengths in the board plane", "",
              "Corners back-projected with the row's own calibration and pose; error = measured − model; px: the "
              "error at the side's image scale.", "", _length_table(summaries, model.units), "",
              "## Table 5 — per photo", "",
              "Straightness / calibration RMS / leave-one-image-out RMS (px) of each photo.", "",
              _per_photo_table(summaries, photo_names), "",
              "## Paired tests", "",
              "Every row against the baseline on the units all rows have; Holm-adjusted within each family; "
              "rank-biserial > 0: the row's values tend to be larger (worse) than the baseline's.", "",
              *paired_tables(comparisons, labels),
              *tone_table, "## Reading", "", *reading(summaries, comparisons, reference, tone, photos_table), "",
              *([*LF.reading_lines(locator), ""] if locator else []),
              "## Figures", ""]
    for f, cap in zip(figs, ("straightness per method", "calibration and leave-one-out RMS",
                             "side-length errors")):
        lines += [f"![{cap}](figures/{f})", ""]
    lines += ["## Files", "",
              "`summary.csv` (one line per row, every figure above), `per_side.csv` (one line per photo, square, side "
              "and row; squares and sides numbered from 0 in the model's order), `per_photo.csv`, `paired_tests.csv`, "
              "`calibration/<row>.json` (intrinsics, poses, per-photo and LOO RMS, the corners used; `reference.json`: the "
              "reference intrinsics, where there are any), `figures/`"
              + (", `locator.json` (edgetruth's locator against the best method, its misfit per photo)" if locator
                 else "") + ".",
              ""]
    report = out / "report.md"
    atomic_write_text(report, "\n".join(lines))
    return report
