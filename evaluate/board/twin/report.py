"""The twin study's files: report.md (real and twin side by side), twin_vs_real.csv, photo_model.json."""
from __future__ import annotations

import csv
import io

import numpy as np
from scipy.stats import rankdata

from edgetruth import __version__
from edgetruth.evaluate import method_order as mo
from edgetruth.evaluate.board.measure.rows import OPENCV_ROW, REFERENCE_ROW
from edgetruth.evaluate.report_format import num, table
from edgetruth.evaluate.run_dir import utc_stamp
from edgetruth.evaluate.stats import spearman
from edgetruth.fileio import atomic_write_text, write_json
from edgetruth.resources import source_commit


#: the diagnostic row: PAE2013's default (floating-window) variant, next to the study's smoothed one
PAE_DEFAULT = "pae2013_floating"
PAE_DEFAULT_LABEL = "PAE2013 (default floating variant; diagnostic)"
EXACT_OUTLINE_LABEL = "exact outline → study's lines (truth)"

CSV_COLUMNS = ("row", "label", "in_ranking", "straightness_real_px", "straightness_twin_px", "rank_straightness_real",
               "rank_straightness_twin", "calib_rms_real_px", "calib_rms_twin_px", "rank_calib_real",
               "rank_calib_twin", "loo_rms_real_px", "loo_rms_twin_px", "truth_rms_px", "truth_median_abs_px",
               "truth_mean_px", "truth_sd_px", "truth_points", "converged_real", "converged_twin")


def ranks(values) -> np.ndarray:
    """Ranks (1 = smallest, ties averaged) of the finite values; NaN elsewhere."""
    v = np.asarray(values, float)
    out = np.full(v.shape, np.nan)
    ok = np.isfinite(v)
    out[ok] = rankdata(v[ok])
    return out


def _label(row: str) -> str:
    return PAE_DEFAULT_LABEL if row == PAE_DEFAULT else mo.label(row)


def method_table(methods, diag, real_s: dict, twin_s: dict, errors: dict) -> list[dict]:
    """One dict per method row (ranked methods, then the diagnostic rows): real and twin figures and ranks."""
    out = []
    rk = {}
    for key in ("straightness_px", "calib_rms_px"):
        for side, s in (("real", real_s), ("twin", twin_s)):
            rk[(key, side)] = dict(zip(methods, ranks([s[m].get(key, np.nan) for m in methods])))
    for m in list(methods) + list(diag):
        r, t = real_s[m], twin_s[m]
        e = errors.get(m, {})
        out.append({
            "row": m, "label": _label(m), "in_ranking": m in methods,
            "straightness_real_px": r.get("straightness_px"), "straightness_twin_px": t.get("straightness_px"),
            "rank_straightness_real": rk[("straightness_px", "real")].get(m),
            "rank_straightness_twin": rk[("straightness_px", "twin")].get(m),
            "calib_rms_real_px": r.get("calib_rms_px"), "calib_rms_twin_px": t.get("calib_rms_px"),
            "rank_calib_real": rk[("calib_rms_px", "real")].get(m), "rank_calib_twin": rk[("calib_rms_px", "twin")].get(m),
            "loo_rms_real_px": r.get("loo_rms_px"), "loo_rms_twin_px": t.get("loo_rms_px"),
            "converged_real": r.get("converged_fraction"), "converged_twin": t.get("converged_fraction"), **e})
    return out


def rankings(methods, real_s: dict, twin_s: dict, errors: dict) -> list[dict]:
    def col(s, key):
        return [s[m].get(key, np.nan) for m in methods]

    return [
        {"what": "straightness: real vs twin", **spearman(col(real_s, "straightness_px"), col(twin_s, "straightness_px"))},
        {"what": "calibration RMS: real vs twin", **spearman(col(real_s, "calib_rms_px"), col(twin_s, "calib_rms_px"))},
        {"what": "leave-one-out RMS: real vs twin", **spearman(col(real_s, "loo_rms_px"), col(twin_s, "loo_rms_px"))},
        {"what": "twin: straightness vs per-point RMS against the truth",
         **spearman(col(twin_s, "straightness_px"), [errors.get(m, {}).get("truth_rms_px", np.nan) for m in methods])},
        {"what": "twin: straightness vs per-point SD against the truth (scatter about the bias)",
         **spearman(col(twin_s, "straightness_px"), [errors.get(m, {}).get("truth_sd_px", np.nan) for m in methods])},
        {"what": "twin: calibration RMS vs per-point RMS against the truth",
         **spearman(col(twin_s, "calib_rms_px"), [errors.get(m, {}).get("truth_rms_px", np.nan) for m in methods])},
        {"what": "real: straightness vs calibration RMS",
         **spearman(col(real_s, "straightness_px"), col(real_s, "calib_rms_px"))},
    ]


def _csv(rows) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    for r in rows:
        w.writerow(["" if r.get(k) is None or (isinstance(r.get(k), float) and not np.isfinite(r.get(k)))
                    else (repr(float(r[k])) if isinstance(r[k], (float, np.floating)) else r[k]) for k in CSV_COLUMNS])
    return buf.getvalue()


def _strip(obj):
    """JSON-safe copy of the photo model (the pooled ESF arrays dropped)."""
    if isinstance(obj, dict):
        return {k: _strip(v) for k, v in obj.items() if k != "esf"}
    if isinstance(obj, (list, tuple)):
        return [_strip(v) for v in obj]
    if isinstance(obj, (np.floating, float)):
        return float(obj) if np.isfinite(obj) else None
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.ndarray):
        return _strip(obj.tolist())
    return obj


def _pm(m: dict, path: tuple, nd: int = 2) -> str:
    v = m
    for k in path:
        if not isinstance(v, dict) or k not in v:
            return "—"
        v = v[k]
    return num(v, nd) if isinstance(v, (int, float, np.floating, np.integer)) else str(v)


def photo_model_table(pm_real: list[dict], pm_twin: list[dict]) -> str:
    cols = [("σ horizontal sides (px)", ("blur", "horizontal", "sigma_px"), 3),
            ("σ vertical sides (px)", ("blur", "vertical", "sigma_px"), 3),
            ("MTF50 horiz. (cy/px)", ("blur", "horizontal", "mtf50_cy_px"), 3),
            ("MTF50 vert. (cy/px)", ("blur", "vertical", "mtf50_cy_px"), 3),
            ("overshoot vert. (%)", ("blur", "vertical", "overshoot_pct"), 1),
            ("undershoot vert. (%)", ("blur", "vertical", "undershoot_pct"), 1),
            ("overshoot horiz. (%)", ("blur", "horizontal", "overshoot_pct"), 1),
            ("black mean", ("noise", "black", "mean"), 1), ("black SD", ("noise", "black", "sd"), 2),
            ("white mean", ("noise", "white", "mean"), 1), ("white SD", ("noise", "white", "sd"), 2),
            ("white at max (%)", ("noise", "white", "at_max_fraction"), 2),
            ("white across x / y (%)", "falloff", 1),
            ("black ρx / ρy", None, 2), ("black mean |Δx|", ("noise", "black", "mean_abs_dx"), 2),
            ("distinct values", ("levels",), 0)]
    body = []
    for r, t in zip(pm_real, pm_twin):
        for who, m in (("real " + r["photo"], r), ("twin " + t["photo"], t)):
            row = [who]
            for name, path, nd in cols:
                if path is None:
                    row.append(f"{_pm(m, ('noise', 'black', 'rho_x'))} / {_pm(m, ('noise', 'black', 'rho_y'))}")
                elif path == "falloff":
                    row.append(" / ".join(_pm(m, ("noise", "white", f"falloff_{k}_pct"), nd) for k in "xy"))
                elif path == ("noise", "white", "at_max_fraction"):
                    v = m.get("noise", {}).get("white", {}).get("at_max_fraction")
                    row.append(num(100 * v, 0) if v is not None else "—")
                else:
                    row.append(_pm(m, path, nd))
            body.append(row)
    return table(["image"] + [c[0] for c in cols], body)


def settings_table(derived: dict, jobs) -> str:
    if "derived_by" in derived:
        return (f"This set's settings were measured and derived by {derived['derived_by']}; the scene's header "
                "says how each was found.")
    if "per_photo" not in derived:
        return f"(not derived: {derived.get('error', 'unknown')})"
    body = []
    for p, j in zip(derived["per_photo"], jobs):
        cam, sen = j.camera, j.sensor
        body.append([
            p["photo"], j.group,
            f"{p['x']['aberration_sigma_um']:.2f} / {cam.aberration_sigma_um:.2f}",
            f"{p['y']['aberration_sigma_um']:.2f} / "
            f"{(cam.aberration_sigma_y_um if cam.aberration_sigma_y_um is not None else cam.aberration_sigma_um):.2f}",
            f"{p['x']['sharpen_amount']:.2f} / {sen.sharpen_amount:.2f}",
            f"{num(p['x']['sharpen_sigma_px'], 2)} / {sen.sharpen_sigma_px:.2f}",
            f"{p['y']['sharpen_amount']:.2f}",
            f"{p['output_gain']:.3f} / {sen.output_gain:.3f}",
            f"{p['output_offset_dn']:.1f} / {sen.output_offset_dn:.1f}",
            ("clipped, " + f"{p['white']:.1f}") if p["white_clipped"] else f"{p['white']:.1f}",
            f"{derived['output_noise_dn']:.2f} / {sen.output_noise_dn:.2f}",
            (f"{p.get('output_levels_rgb')} × {[round(g, 3) for g in p.get('output_rgb_gains') or []]}"
             if p["palette_reduced"] else "—") + " / " +
            (f"{[int(v) for v in sen.output_levels_rgb]} × {list(sen.output_rgb_gains)}, {sen.output_dither}"
             if sen.quantised else "—"),
            f"{p['x']['fit_rms']:.3f}, {p['y']['fit_rms']:.3f}",
        ])
    return table(["photo", "twin group", "σ x (µm) derived / scene", "σ y (µm)", "sharpen x amount", "sharpen σ (px)",
                  "sharpen y amount (fit)", "output gain", "offset (DN)", "white (DN)", "noise SD (DN)",
                  "palette (levels × gains)", "ESF fit RMS x, y"], body)


def write_twin_report(out, *, set_name, spec, jobs, keep, methods, diag, real_run, twin_run, errors, floor, pm_real,
                      pm_twin, derived, timings, options, thresholds, corners=None, flatness=None, budget=None):
    real_s = {s["row"]: s for s in real_run.summaries}
    twin_s = {s["row"]: s for s in twin_run.summaries}
    rows = method_table(methods, diag, real_s, twin_s, errors)
    rk = rankings(methods, real_s, twin_s, errors)
    atomic_write_text(out / "twin_vs_real.csv", _csv(rows))
    write_json(out / "photo_model.json", _strip({"real": pm_real, "twin": pm_twin, "derived": derived}))
    if corners:
        write_json(out / "corners_per_photo.json", corners)
    if flatness:
        write_json(out / "board_flatness.json", flatness)

    def n3(v):
        return num(v, 3)

    body = []
    for r in rows:
        body.append([r["label"] + ("" if r["in_ranking"] else " *"), n3(r["straightness_real_px"]),
                     n3(r["straightness_twin_px"]),
                     f"{num(r['rank_straightness_real'], 0)} / {num(r['rank_straightness_twin'], 0)}"
                     if r["in_ranking"] else "—",
                     n3(r["calib_rms_real_px"]), n3(r["calib_rms_twin_px"]),
                     f"{num(r['rank_calib_real'], 0)} / {num(r['rank_calib_twin'], 0)}" if r["in_ranking"] else "—",
                     n3(r["loo_rms_real_px"]), n3(r["loo_rms_twin_px"]), n3(r.get("truth_rms_px")),
                     n3(r.get("truth_median_abs_px")), f"{num(r.get('truth_mean_px'), 3)}",
                     n3(r.get("truth_sd_px"))])
    ref_key = REFERENCE_ROW if REFERENCE_ROW in real_s else OPENCV_ROW
    ref_r, ref_t = real_s.get(ref_key, {}), twin_s.get(ref_key, {})
    ref_label = ("Zhang's corners (real) / exact corners (twin)" if ref_key == REFERENCE_ROW else
                 "OpenCV's corners (cornerSubPix), real / twin")
    body.append([ref_label, "—", "—", "—", n3(ref_r.get("calib_rms_px")),
                 n3(ref_t.get("calib_rms_px")), "—", n3(ref_r.get("loo_rms_px")), n3(ref_t.get("loo_rms_px")),
                 "0", "0", "0", "0"])
    body.append([f"{_floor_label()} (twin)", "—", n3(floor.get("straightness_px")), "—", "—",
                 n3(floor.get("calib_rms_px")), "—", "—", n3(floor.get("loo_rms_px")), "—", "—", "—", "—"])
    rank_body = [[r["what"], num(r["rho"], 3), f"{r['p']:.3g}" if np.isfinite(r["p"]) else "—", r["n"]] for r in rk]

    # per photo: straightness (median over the ranked methods), real and twin
    per_photo = []
    for i, name in enumerate(real_run.names):
        rr = [real_s[m]["per_photo_straightness_px"][i] for m in methods]
        tt = [twin_s[m]["per_photo_straightness_px"][i] for m in methods]
        dev = [real_s[m]["per_photo_straightness_px"][i] for m in methods if m == "canny_devernay"]
        devt = [twin_s[m]["per_photo_straightness_px"][i] for m in methods if m == "canny_devernay"]
        per_photo.append([name, twin_run.names[i], n3(float(np.median(rr))), n3(float(np.median(tt))),
                          n3(dev[0]) if dev else "—", n3(devt[0]) if devt else "—",
                          n3(real_s[diag[0]]["per_photo_straightness_px"][i]) if diag else "—",
                          n3(twin_s[diag[0]]["per_photo_straightness_px"][i]) if diag else "—"])

    lines = [f"# Digital twin — {set_name}: real photos and their twin, side by side", "",
             f"edgetruth {__version__}, commit {source_commit()[:12]}; {utc_stamp()} (UTC).  Time: render "
             f"{timings['render_s']:.0f} s, both board studies {timings['studies_s']:.0f} s, photo model "
             f"{timings['photo_model_s']:.0f} s"
             + (f", error budget {timings['budget_s']:.0f} s" if "budget_s" in timings else "")
             + f"; {timings['total_s']:.0f} s in all.", "",
             f"- Twin: spec `{spec.name}` (identity {spec.identity_sha256[:12]}), {spec.render.spp} spp, images "
             f"{', '.join(j.name for j in jobs)} for photos {', '.join(real_run.names)} (the photos' order).",
             f"- The same board study (`edgetruth study board`, docs/board.md) on both, the twin's PNGs read like "
             f"photos (`edgetruth.image_io.read_gray`); its files: `real/`, `twin/`.",
             f"- Methods ({len(methods)}, ranked): {', '.join(methods)}; options as every study's "
             f"({mo.STUDY_OPTIONS}).  * = a diagnostic row, not ranked.",
             "- Against the truth (twin only): each method's points that the study assigned to a side (3 px from "
             "the corners left out), signed distance to the square's exact distorted outline (> 0 on the white "
             "board).", "",
             "## Rankings", "",
             "Spearman ρ between the methods' figures (n methods; p two-sided: exact up to 9, else "
             "`scipy.stats.spearmanr`'s).", "",
             table(["ranking", "ρ", "p", "n"], rank_body), "",
             "## Table 1 — per method: real and twin", "",
             "Straightness: RMS of each side's points about its total-least-squares line, pooled (px).  Calibration: "
             "OpenCV's reprojection RMS of the corners from the side lines (k1, k2); LOO: leave-one-image-out RMS. "
             "Ranks: 1 = smallest.  Truth: the twin's points against the exact outline.", "",
             table(["method", "straightness real", "twin", "rank real / twin", "calib RMS real", "twin",
                    "rank real / twin", "LOO RMS real", "twin", "twin vs truth: RMS", "median |e|", "mean", "SD"], body), "",
             f"The last row is the floor of the study's procedure: points on the exact outline (0.5 px apart, 3 px "
             f"from the corners), the same total-least-squares lines and intersections: its straightness is the "
             f"lens's bow of a side about its chord line, its calibration RMS what fitting straight lines to bent "
             f"sides costs before any method adds its own error.", "",
             "## Table 2 — per photo: straightness", "",
             "Median over the ranked methods, and Canny–Devernay and PAE2013's default variant alone (px).", "",
             table(["photo", "twin image", "median real", "median twin", "Devernay real", "Devernay twin",
                    "PAE default real", "PAE default twin"], per_photo), "",
             *corner_lines(corners),
             "## Table 3 — the photo model: what the camera did, real and twin", "",
             "`edgetruth.evaluate.board.tone.photo_model` on every photo and every twin image alike: ERF σ of the "
             "squares' horizontal sides (blur along y) and vertical sides (blur along x), median over sides; MTF50 "
             "of the pooled ESF; its over/undershoot in % of the step (sharpening); flat regions (inside the "
             "squares, a ring around them, 4 px from the sides): mean, residual SD about a quadratic surface, lag-1 "
             "correlation along x and y, share at the region's top value (clipping), the white regions' change "
             "across the board (a plane through their means: from the leftmost to the rightmost and the top to the "
             "bottom one, % of the level; lens shading and light), mean |difference| of horizontal neighbours; "
             "distinct values in the image.", "",
             photo_model_table(pm_real, pm_twin), "",
             "## Table 4 — the twin's settings: derived from the photos / used by the scene", "",
             *([] if "derived_by" in derived else [
                 "`photo_model.derive_twin` on the real photos (its docstring: how each is derived) next to the "
                 f"values the scene `{spec.name}` renders with.  Noise from "
                 f"{', '.join(derived.get('noise_from', []))}.", ""]),
             settings_table(derived, jobs), "",
             *closed_loop_lines(derived), "",
             *flatness_lines(flatness, bent=any(g.board_bend_mm is not None for g in spec.groups)),
             *(budget or []),
             "## Reading", "", *reading(rows, rk, methods, diag, floor, real_s, twin_s), *flatness_reading(flatness),
             "- How each setting was measured and what each fix changed (the ρ before and after each): "
             "docs/board.md, \"Digital twin\".", "",
             "## Files", "",
             "`twin_vs_real.csv` (Table 1), `photo_model.json` (Table 3 and 4 in full), "
             + ("`corners_per_photo.json` (Table 2b), " if corners else "")
             + ("`board_flatness.json` (Table 5), " if flatness else "") + "`real/` and `twin/` (each "
             "a board study's own files: report.md, summary.csv, per_side.csv, calibration/, figures/), "
             "`renders/` (the twin's dataset: PNG, EXR and truth JSON per image)"
             + ("; `budget.json`, `budget.csv` and `budget/<term>/` (each term's scene and renders)" if budget else "")
             + ".", ""]
    report = out / "report.md"
    atomic_write_text(report, "\n".join(lines))
    return report


def flatness_lines(flatness: dict | None, bent: bool = False) -> list[str]:
    """Table 5: is the board flat, on the photos, the twin and the twin's exact outline (``flatness_rows``);
    ``bent``: the twin's spec curls its boards (``board_bend_mm``)."""
    if not flatness:
        return []
    exact = ("The twin's boards are curled (its spec's `board_bend_mm`): the exact outline's row reads that bend "
             "back through the study's procedure alone, without any method's error." if bent else
             "The exact outline's row is the study's procedure alone on a flat board: its corners carry only the "
             "small smooth error of straight lines fitted to sides the lens bows, which a bend of a hundredth of a "
             "millimetre takes in part -- significant at that RMS, not a bend.")
    body = []
    for label, f in flatness.items():
        q, c = f["quadratic"], f["cubic"]
        body.append([label, mo.label(f["method"]), f["views"],
                     f["corners"], num(f["rms_px"], 3), num(q["rms_bent_px"], 3),
                     f"{100 * q['bend_share']:.0f} % ({100 * q['bend_share_chance']:.0f} %)",
                     f"{q['f_statistic']:.2f}", f"{q['p_value']:.2g}", num(q["depth_mm_median"], 2),
                     f"{100 * c['bend_share']:.0f} % ({100 * c['bend_share_chance']:.0f} %)"])
    return ["## Table 5 — is the board flat? real and twin", "",
            "The corners calibrated afresh with OpenCV's 5-term model (a bend can stand in for the lens terms the "
            "study's k1, k2 leave out), then refitted with the board's height in each view a quadratic of its board "
            "coordinates (3 terms a view), or a cubic (7), by `evaluate/board_bend.py`: the share of the residual "
            "energy the bend takes (what chance gives), the F test of the nested fits, and the bend's median "
            "peak-to-valley depth over a view's corners (mm).  " + exact, "",
            table(["corners of", "method", "views", "corners", "RMS flat (px)", "RMS bent (px)",
                   "quadratic bend takes (chance)", "F", "p", "depth (mm)", "cubic takes (chance)"], body), ""]


def flatness_reading(flatness: dict | None) -> list[str]:
    """One reading line on Table 5, from its numbers."""
    if not flatness or "photos" not in flatness or "twin" not in flatness:
        return []
    r, t = flatness["photos"]["quadratic"], flatness["twin"]["quadratic"]
    return [f"- Board flatness (Table 5): a bend per view takes {100 * r['bend_share']:.0f} % of the photos' residual "
            f"energy (p = {r['p_value']:.2g}, {r['depth_mm_median']:.2f} mm deep) and {100 * t['bend_share']:.0f} % "
            f"of the twin's (p = {t['p_value']:.2g}); chance gives {100 * r['bend_share_chance']:.0f} %."]


def corner_lines(corners: list[dict] | None) -> list[str]:
    """Table 2b (a chessboard): per photo, the squares' own corners against the junctions, real and twin, and the
    twin's bias against its truth; with the Spearman ρ of the offsets over the photos and the bias by saturation."""
    if not corners:
        return []
    real = [c["own_corner_outward_real_px"] for c in corners]
    twin = [c["own_corner_outward_twin_px"] for c in corners]
    rho = spearman(real, twin)
    sat = [c["twin_truth_mean_px"] for c in corners if c["white_saturated"]]
    clear = [c["twin_truth_mean_px"] for c in corners if not c["white_saturated"]]
    body = [[c["photo"], "yes" if c["white_saturated"] else "no", num(c["own_corner_outward_real_px"], 3),
             num(c["own_corner_outward_twin_px"], 3), num(c["twin_truth_mean_px"], 3)] for c in corners]
    lines = ["## Table 2b — per photo: the squares' own corners, real and twin", "",
             f"{mo.label(corners[0]['method'])}: median over the junctions of each dark square's own corner (its own "
             "side lines) from the junction's corner (the grid lines), outward of the square (< 0: the dark squares image "
             "small); the twin's mean signed error of the points against the exact outline (< 0: inside the dark "
             "squares); white saturated: the photo's light squares flatter than its dark ones (`levels`).", "",
             table(["photo", "white saturated", "own corner outward, real (px)", "twin (px)",
                    "twin: points vs truth, mean (px)"], body), ""]
    lines.append(f"Over the {rho['n']} photos the own-corner offsets of real and twin rank alike with Spearman "
                 f"ρ = {rho['rho']:.2f} (p = {rho['p']:.2g}).  On the twin the points' mean error against the truth "
                 "is "
                 + (f"{_span(clear)} px on the {_photos(len(clear))} with unsaturated whites" if clear else "—")
                 + " and " + (f"{_span(sat)} px on the {_photos(len(sat))} with saturated ones." if sat else "—."))
    return lines + [""]


def _span(values) -> str:
    lo, hi = f"{min(values):+.3f}", f"{max(values):+.3f}"
    return lo if lo == hi else f"{lo} to {hi}"


def _photos(n: int) -> str:
    return f"{n} photo" + ("" if n == 1 else "s")


def closed_loop_lines(derived: dict) -> list[str]:
    cl = derived.get("closed_loop") or []
    if not cl:
        return []
    return ["Closed loop on the noise (photos without a coarse palette): the twin renders its own noise too (the "
            "Monte-Carlo noise of the diffraction tail's samples in the dark squares near white, the quiet sensor's, "
            "both through the sharpening), so the output noise that gives the photo's black SD is:", "",
            table(["photo", "black SD real", "twin", "twin output noise (DN)", "twin's other noise (DN)",
                   "output noise for the photo's SD (DN)"],
                  [[c["photo"], num(c["real_black_sd"], 2), num(c["twin_black_sd"], 2), num(c["twin_noise_dn"], 2),
                    num(c["twin_other_sd"], 2), num(c["noise_for_real_sd"], 2)] for c in cl])]


def _floor_label() -> str:
    return EXACT_OUTLINE_LABEL


def reading(rows, rk, methods, diag, floor, real_s, twin_s) -> list[str]:
    """What the numbers say, computed from them (nothing here is typed in by hand)."""
    out = []
    s, c, loo = rk[0], rk[1], rk[2]
    out.append(f"- Straightness ranks alike on real and twin with ρ = {s['rho']:.2f} (p = {s['p']:.2g}, n = {s['n']}); "
               f"calibration RMS with ρ = {c['rho']:.2f} (p = {c['p']:.2g}); leave-one-out with ρ = {loo['rho']:.2f} "
               f"(p = {loo['p']:.2g}).")
    ranked = [r for r in rows if r["in_ranking"] and np.isfinite(r["rank_straightness_real"] or np.nan)
              and np.isfinite(r["rank_straightness_twin"] or np.nan)]
    if ranked:
        worst = sorted(ranked, key=lambda r: -abs(r["rank_straightness_real"] - r["rank_straightness_twin"]))[:3]
        worst = [r for r in worst if r["rank_straightness_real"] != r["rank_straightness_twin"]]
        out.append("- Largest straightness rank differences (real / twin rank, value): " + ("; ".join(
            f"{r['label']} {r['rank_straightness_real']:.1f} / {r['rank_straightness_twin']:.1f} "
            f"({r['straightness_real_px']:.3f} / {r['straightness_twin_px']:.3f} px)" for r in worst) or "none")
            + ".")
        ratio = np.median([r["straightness_twin_px"] / r["straightness_real_px"] for r in ranked])
        out.append(f"- Level: the twin's straightness is {ratio:.2f}× the real one's (median over methods).")
    for d in diag:
        if "pae2013" in real_s:
            out.append(f"- PAE2013: the default floating-window variant scatters {real_s[d]['straightness_px']:.3f} px "
                       f"on the photos and {twin_s[d]['straightness_px']:.3f} px on the twin; the smoothed variant "
                       f"(the studies') {real_s['pae2013']['straightness_px']:.3f} and "
                       f"{twin_s['pae2013']['straightness_px']:.3f} px.")
    t, sd = rk[3], rk[4]
    out.append(f"- On the twin, straightness ranks like the per-point RMS against the truth with ρ = {t['rho']:.2f} "
               f"(p = {t['p']:.2g}) and like its SD (the scatter about each method's bias) with ρ = {sd['rho']:.2f} "
               f"(p = {sd['p']:.2g}); calibration RMS like the RMS with ρ = {rk[5]['rho']:.2f} "
               f"(p = {rk[5]['p']:.2g}).")
    bias = [r["truth_mean_px"] for r in rows if r["in_ranking"] and np.isfinite(r.get("truth_mean_px") or np.nan)]
    if bias and max(bias) < 0:
        out.append(f"- Every method's points lie inside the squares on the twin: mean signed error "
                   f"{min(bias):+.3f} to {max(bias):+.3f} px (the edge moves towards the dark side through the "
                   "output's tone curve and clipping); the bias is common to all and is what the RMS against the truth "
                   "mostly measures.")
    elif bias:
        out.append(f"- The methods' mean signed error against the twin's truth runs from {min(bias):+.3f} to "
                   f"{max(bias):+.3f} px (> 0: out on the white board).")
    best = min((r for r in rows if r["in_ranking"] and np.isfinite(r.get("truth_rms_px") or np.nan)),
               key=lambda r: r["truth_rms_px"], default=None)
    if best is not None:
        out.append(f"- Closest to the truth on the twin: {best['label']} (RMS {best['truth_rms_px']:.3f} px, median "
                   f"|e| {best['truth_median_abs_px']:.3f} px, mean {best['truth_mean_px']:+.3f} px).")
    cal = [r["calib_rms_twin_px"] for r in rows if r["in_ranking"] and np.isfinite(r["calib_rms_twin_px"] or np.nan)]
    if cal and np.isfinite(floor.get("calib_rms_px", np.nan)):
        out.append(f"- The study's procedure alone (exact outline → lines → corners) calibrates to "
                   f"{floor['calib_rms_px']:.3f} px on the twin; the methods' corners to {min(cal):.3f}–{max(cal):.3f} "
                   + (f"px; the exact corners to {twin_s[REFERENCE_ROW]['calib_rms_px']:.3f} px."
                      if REFERENCE_ROW in twin_s else "px."))
    return out
