"""The "which pattern?" report: tables of every (pattern, detector) at every focus and light, which wins where, the
paired tests over the shared pose slots, the circle-centre bias against tilt, and two figures."""
from __future__ import annotations

import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from edgetruth.evaluate.board.report.figures import save_figure  # noqa: E402
from edgetruth.evaluate.report_format import num, signed, table  # noqa: E402
from edgetruth.evaluate.stats import holm, rank_biserial, wilcoxon_paired  # noqa: E402
from edgetruth.fileio import tmp_path  # noqa: E402

#: tilt bins (deg) of the circle-centre bias table
TILT_BINS_DEG = (0.0, 10.0, 20.0, 30.0, 40.0, 60.0)


def condition(row: dict) -> str:
    """A row's levels other than the pattern's: the condition rows are compared under."""
    return " / ".join(v for k, v in row["levels"].items() if k != "pattern") or "—"


def label(row: dict) -> str:
    return f"{row['pattern']} · {row['detector']}" + (f" ({row['method']})" if row["method"] else "")


def focal_figure(rows: list[dict], out: Path) -> str:
    """fx and fy errors (%) of every (pattern, detector), one panel per condition."""
    conds = sorted({condition(r) for r in rows})
    fig, axes = plt.subplots(1, len(conds), figsize=(4.2 * len(conds), 0.45 * len(rows) / max(1, len(conds)) + 1.6),
                             sharey=True, squeeze=False)
    for ax, c in zip(axes[0], conds):
        sub = [r for r in rows if condition(r) == c and not r.get("failed")]
        y = np.arange(len(sub))
        ax.barh(y - 0.2, [r["fx_pct"] for r in sub], 0.4, label="fx")
        ax.barh(y + 0.2, [r["fy_pct"] for r in sub], 0.4, label="fy")
        ax.axvline(0, color="k", lw=0.6)
        ax.set_yticks(y, [label(r) for r in sub], fontsize=7)
        ax.set_title(c, fontsize=9)
        ax.set_xlabel("error vs truth (%)")
    axes[0][0].legend(fontsize=7)
    return save_figure(fig, out / "focal_errors.png")


def bias_figure(rows: list[dict], out: Path) -> str:
    """Each circle's measured centre offset (px) against the board's tilt, per detector, beside the closed form."""
    fig, ax = plt.subplots(figsize=(6.0, 3.8))
    circ = [r for r in rows if r["kind"] == "circles_grid"]
    for k, det in enumerate(dict.fromkeys(r["detector"] for r in circ)):
        pts = [(c["tilt_deg"], c["offset_px"]) for r in circ if r["detector"] == det for c in r["circles"]]
        if pts:
            t, o = np.array(pts).T
            ax.scatter(t, o, s=4, alpha=0.35, color=f"C{k}", label=det)
    cf = [(c["tilt_deg"], c["closed_form_bias_px"]) for r in circ if r["detector"] == "conic" for c in r["circles"]]
    if cf:
        t, b = np.array(cf).T
        ax.scatter(t, b, s=3, color="k", marker="x", alpha=0.5, label="closed form (ellipse centre − centre image)")
    ax.set_xlabel("board tilt (deg)")
    ax.set_ylabel("centre offset from the true centre image (px)")
    ax.set_yscale("log")
    ax.legend(fontsize=7)
    return save_figure(fig, out / "circle_bias.png")


def paired_tests(rows: list[dict]) -> list[dict]:
    """Per condition, two-sided Wilcoxon signed-rank tests over the shared pose slots of the per-view point RMS
    (px): each edge detector against its pattern's OpenCV detector, and the best row of each pattern against the
    best of each other (Holm-corrected within a condition).  Effect size: the matched-pairs rank-biserial r."""
    out = []
    for c in sorted({condition(r) for r in rows}):
        sub = [r for r in rows if condition(r) == c and not r.get("failed")]
        pairs = []
        for kind in dict.fromkeys(r["kind"] for r in sub):
            rs = [r for r in sub if r["kind"] == kind]
            pairs += [(rs[0], r, "edge vs OpenCV") for r in rs[1:]]
        best = {}
        for r in sub:
            if r["kind"] not in best or r["point_rms_px"] < best[r["kind"]]["point_rms_px"]:
                best[r["kind"]] = r
        bs = list(best.values())
        pairs += [(a, b, "best vs best") for i, a in enumerate(bs) for b in bs[i + 1:]]
        tests = []
        for a, b, why in pairs:
            slots = sorted(set(v["slot"] for v in a["per_view"].values()) & set(v["slot"] for v in b["per_view"].values()))
            va = {v["slot"]: v["rms_px"] for v in a["per_view"].values()}
            vb = {v["slot"]: v["rms_px"] for v in b["per_view"].values()}
            x, y = np.array([va[s] for s in slots]), np.array([vb[s] for s in slots])
            w = wilcoxon_paired(x, y)
            tests.append({"condition": c, "a": label(a), "b": label(b), "why": why, **w,
                          "rank_biserial": rank_biserial(x, y) if len(slots) else float("nan")})
        if tests:
            for t, p in zip(tests, holm([t["p_value"] for t in tests])):
                t["p_holm"] = float(p)
        out += tests
    return out


def bias_table(rows: list[dict]) -> list[list]:
    """Mean centre offset (px) per tilt bin for each circle detector, beside the closed-form bias."""
    circ = [r for r in rows if r["kind"] == "circles_grid"]
    dets = list(dict.fromkeys(r["detector"] for r in circ))
    body = []
    for lo, hi in zip(TILT_BINS_DEG[:-1], TILT_BINS_DEG[1:]):
        cells = []
        cf = [c["closed_form_bias_px"] for r in circ if r["detector"] == dets[0] for c in r["circles"]
              if lo <= c["tilt_deg"] < hi] if dets else []
        if not cf:
            continue
        for d in dets:
            o = [c["offset_px"] for r in circ if r["detector"] == d for c in r["circles"] if lo <= c["tilt_deg"] < hi]
            cells.append(num(float(np.mean(o)), 4) if o else "—")
        body.append([f"{lo:.0f}–{hi:.0f}°", len(cf), num(float(np.mean(cf)), 4), *cells])
    return [["tilt", "circles", "closed-form bias (px)", *[f"{d} offset (px)" for d in dets]], body]


def verdicts(rows: list[dict]) -> list[str]:
    """Per condition, in words: the row with the smallest focal error and the one with the most exact points."""
    lines = []
    for c in sorted({condition(r) for r in rows}):
        sub = [r for r in rows if condition(r) == c and not r.get("failed")]
        if not sub:
            lines.append(f"- **{c}**: no detector calibrated.")
            continue
        f = min(sub, key=lambda r: r["max_focal_error_pct"])
        p = min(sub, key=lambda r: r["point_rms_px"])
        d = min(sub, key=lambda r: r["distortion_field_px"]["rms"])
        lines.append(f"- **{c}**: the smallest focal error is {label(f)} (max(|fx|, |fy|) "
                     f"{f['max_focal_error_pct']:.3f} %); the most exact points {label(p)} ({p['point_rms_px']:.4f} px "
                     f"RMS from the truth); the closest distortion field {label(d)} "
                     f"({d['distortion_field_px']['rms']:.3f} px RMS).")
    return lines


def write_report(rows: list[dict], out: Path, header: dict) -> Path:
    """``report.md`` and ``figures/`` in ``out``."""
    figs = out / "figures"
    figs.mkdir(parents=True, exist_ok=True)
    fig_focal = focal_figure(rows, figs)
    fig_bias = bias_figure(rows, figs) if any(r["kind"] == "circles_grid" for r in rows) else None
    tests = paired_tests(rows)
    lines = ["# Which pattern? Chessboard, circle grid and ChArUco on the same poses", "",
             f"Spec `{header['spec']}`: {header['slots']} pose slots shared by every cell (the same board-centre "
             f"distance, offset, tilt and roll), {header['camera']}; {header['n_images']} renders with exact truth.  "
             f"Each cell is calibrated (Zhang, OpenCV's 5-term lens) with each detector of its pattern; the edge "
             f"detectors use {header['method']}.  Command: `{header['command']}`.", "",
             "Errors are against the renders' exact truth: fx, fy relative (%), cx, cy (px), the distortion field "
             "(|d_cal(p) − d_true(p)| over a grid of the image, d(p) = p − K·undistort(p), px), and the points "
             "(each view's detected points against the true corner or centre images, px).  Each board is compared "
             "at its own printed size (the spec's), not at equal point counts.", "",
             "## Which wins where (as measured)", "", *verdicts(rows), "",
             "## Every pattern and detector", ""]
    body = [[condition(r), r["pattern"], r["detector"] + (f" ({r['method']})" if r["method"] else ""),
             f"{r['n_views']}/{r['of_views']}", r["n_points"], signed(r["fx_pct"], 4), signed(r["fy_pct"], 4),
             signed(r["cx_px"], 3), signed(r["cy_px"], 3), num(r["distortion_field_px"]["rms"], 3),
             num(r["reprojection_rms_px"], 4), num(r["point_rms_px"], 4)]
            for r in sorted(rows, key=lambda r: (condition(r), r["pattern"]))]
    lines += [table(["condition", "pattern", "detector", "views", "points", "fx err %", "fy err %", "cx err px",
                     "cy err px", "dist. field px", "reproj. RMS px", "points vs truth px"], body), "",
              f"![fx and fy errors](figures/{fig_focal})", "",
              "## Paired tests over the pose slots", "",
              "Two-sided Wilcoxon signed-rank tests of the per-view point RMS (px) on the shared slots; Holm-corrected "
              "within each condition; r = matched-pairs rank-biserial (negative: the first row's points are closer).",
              ""]
    lines += [table(["condition", "a", "b", "n", "median a − b (px)", "r", "p", "p (Holm)"],
                    [[t["condition"], t["a"], t["b"], t["n_pairs"], signed(t["median_difference"], 4),
                      signed(t["rank_biserial"], 2), f"{t['p_value']:.3g}", f"{t['p_holm']:.3g}"] for t in tests]), ""]
    if fig_bias:
        head, body = bias_table(rows)
        lines += ["## The circle-centre bias against tilt", "",
                  "Each circle's measured image point against the true image of its centre, beside the closed-form "
                  "perspective bias (the true ellipse centre minus the true centre image, pinhole; "
                  "`render.scene.circle_conic`).  `conic` carries the bias; `corrected` removes it "
                  "(docs/patterns.md).  Every circle of every circle-grid cell, pooled over the conditions.", "",
                  table(head, body), "", f"![circle-centre bias](figures/{fig_bias})", ""]
    failed = [r for r in rows if r.get("failed")]
    if failed:
        lines += ["## Detectors that did not calibrate", "",
                  table(["condition", "pattern", "detector", "why"],
                        [[condition(r), r["pattern"], r["detector"], r["failed"]] for r in failed]), ""]
    path = out / "report.md"
    tmp = tmp_path(path)
    tmp.write_text("\n".join(lines) + "\n")
    os.replace(tmp, path)
    return path
