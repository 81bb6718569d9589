"""Tables and figures of the per-point truth on renders (``edgetruth.evaluate.points.scores``).

Points of one image share its pose, light and noise field, so they are not independent: every
interval and test here resamples or pairs *images* (cluster bootstrap of the RMSE over images;
Wilcoxon signed-rank on per-image RMSE, pairs = the same spec and image, Holm over the methods).
The cells are those of the ranging tables: the design's base cell (the standard experiment), the
levels of each factor on the same pose slots (SNR levels G1–G4 and targets T1–T4: Tables E4G/E4T;
any other factor: a table named after it), and the groups outside the design.

Fair figures (as the synthetic study, ``edgetruth.evaluate.stats``): per method its *coverage* (share
of the candidates it refines), bias and RMSE on its *refined* points, RMSE on the *common subset*
(the candidates every compared method refines, in the same cell), and RMSE on *all* candidates with
a decline scored at the pixel centre.  Rankings, paired tests and the cell tables use the common
subset; each table says which it uses.  Bias against the *optical edge* (the geometric outline
moved by the displacement the camera model predicts, ``edgetruth.render.optics.optical_edge``) is given
beside the bias against the outline, with the optics' own displacement apart.  Each method's RMSE is
also divided by its *exact per-point Cramér–Rao bound* (``edgetruth.evaluate.points.bound``: the
camera's PSF, the outline, the shading, the sensor's noise, over the method's own footprint) on the
same points; the old 11-pixel-row figure stays beside it as a named reference ("÷ row ref.").
"""
from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from edgetruth.evaluate.design import (INTERVALS_CM, REFERENCE_METHOD, SEED_ROBUSTNESS, factor_tables, main_rows,
                                       plain_groups)
from edgetruth.evaluate.method_order import label
from edgetruth.evaluate.points.scores import CORNER_EXCLUSION_PX, MATCH_RADIUS_PX
from edgetruth.evaluate.report_format import ci as _ci, num as _f, table as _table
from edgetruth.evaluate.stats import (bootstrap_indices, common_subset, friedman, holm, paired_comparisons,
                                      rank_biserial, wilcoxon_paired)
from edgetruth.fileio import atomic_write_text


N_BOOT = 2000
MAD_TO_SD = 1.4826


def _label(m: str) -> str:
    return label(m)


def image_columns(table) -> tuple[np.ndarray, np.ndarray]:
    """Per image: the 11-pixel-row reference bound (px; ``bound_row_px``, ``bound_px`` in older files)
    and the distance interval label."""
    return (np.array([r.get("bound_row_px", r.get("bound_px", np.nan)) for r in table.images], float),
            np.array([r.get("interval", "") for r in table.images]))


def per_image_sums(image: np.ndarray, e: np.ndarray, n_images: int) -> tuple[np.ndarray, np.ndarray]:
    """(sum of squared errors, number of points) per image."""
    ok = np.isfinite(e)
    sse = np.bincount(image[ok], weights=e[ok] ** 2, minlength=n_images)
    n = np.bincount(image[ok], minlength=n_images).astype(float)
    return sse, n


def cluster_rmse_ci(sse: np.ndarray, n: np.ndarray, n_boot: int = N_BOOT, seed: int = 0,
                    other: np.ndarray | None = None) -> tuple[float, float]:
    """Percentile bootstrap CI over images of the pooled RMSE; with ``other`` (a second method's
    per-image SSE on the same points) the CI of RMSE - RMSE(other)."""
    use = n > 0
    sse, n = sse[use], n[use]
    k = sse.size
    if k < 3:
        return float("nan"), float("nan")
    idx = bootstrap_indices(k, n_boot, seed)
    tot = n[idx].sum(1)
    v = np.sqrt(sse[idx].sum(1) / tot)
    if other is not None:
        v = v - np.sqrt(other[use][idx].sum(1) / tot)
    lo, hi = np.percentile(v, [2.5, 97.5])
    return float(lo), float(hi)


def common_mask(table, methods) -> np.ndarray:
    """Points every method in ``methods`` refines (``edgetruth.evaluate.stats.common_subset``) with a
    finite error for each."""
    methods = [m for m in methods if m in table.errors]
    if not methods:
        return np.ones(len(table.image), bool)
    out = common_subset(table.converged, methods)
    for m in methods:
        out &= np.isfinite(table.errors[m])
    return out


def _rms(v: np.ndarray) -> float:
    return float(np.sqrt(np.mean(v ** 2))) if v.size else float("nan")


def _ratio(rmse: float, bound_rms: float) -> float:
    return rmse / bound_rms if np.isfinite(bound_rms) and bound_rms > 0 else float("nan")


def point_stats(table, m: str, bound_of_image: np.ndarray, common: np.ndarray | None = None) -> dict:
    """Method ``m``'s figures: on all candidates (declines at the pixel centre: ``bias``, ``rmse`` with
    an image-bootstrap CI, robust spread), ``coverage``, on its refined points (``bias_refined``,
    ``rmse_refined``, ``bias_optical``: against the optical edge; ``bound_rms``: the RMS of its exact
    per-point bound there, ``rmse_over_bound`` = rmse_refined ÷ bound_rms; ``rmse_over_row_bound``:
    the same over the 11-pixel-row reference of ``bound_of_image``), and on the ``common`` subset
    (``rmse_common`` with CI, ``bias_common``, ``bias_common_optical``, ``rmse_common_over_bound``)."""
    e = table.errors[m]
    ok = np.isfinite(e)
    conv = np.asarray(table.converged[m], bool)
    common = ok.copy() if common is None else np.asarray(common, bool) & ok
    opt = table.optical("centroid")
    bnd = table.bound(m) if hasattr(table, "bound") else np.full(len(e), np.nan)
    out = {"n": int(ok.sum()), "n_images": int(np.unique(table.image[ok]).size),
           "n_refined": int((ok & conv).sum()), "n_common": int(common.sum())}
    nan2 = (np.nan, np.nan)
    if not ok.any():
        return {**out, "bias": np.nan, "rmse": np.nan, "rmse_ci": nan2, "robust_sd": np.nan, "coverage": np.nan,
                "rmse_over_bound": np.nan, "bound_rms": np.nan, "bound_row_rms": np.nan,
                "rmse_over_row_bound": np.nan, "rmse_common_over_bound": np.nan, "bias_refined": np.nan,
                "rmse_refined": np.nan, "rmse_refined_ci": nan2, "bias_optical": np.nan, "rmse_common": np.nan,
                "rmse_common_ci": nan2, "bias_common": np.nan, "bias_common_optical": np.nan,
                "optical_offset": np.nan, "rmse_optical": np.nan, "rmse_optical_over_bound": np.nan}
    ee = e[ok]
    n_img = len(table.images)
    sse, n = per_image_sums(table.image, e, n_img)
    rm = _rms(ee)
    ref = ok & conv
    er, ec = e[ref], e[common]
    sse_r, n_r = per_image_sums(table.image[ref], er, n_img)
    sse_c, n_c = per_image_sums(table.image[common], ec, n_img)
    opt_r, opt_c = opt[ref], opt[common]
    has_opt = np.isfinite(opt_r).any()

    def brms(v):
        return float(np.sqrt(np.nanmean(v ** 2))) if np.isfinite(v).any() else float("nan")
    b_row = brms(bound_of_image[table.image[ref]])
    b_ref, b_com = brms(bnd[ref]), brms(bnd[common])
    rr = _rms(er)
    # against the optical edge: the error the bound's model describes (its expected image has no vignetting
    # tilt of the defocus disk, so its edge is the optical one; the optics' displacement is not noise)
    ro = _rms((er - opt_r)[np.isfinite(opt_r)]) if has_opt else float("nan")
    return {**out, "bias": float(np.mean(ee)), "rmse": rm, "rmse_ci": cluster_rmse_ci(sse, n),
            "robust_sd": float(MAD_TO_SD * np.median(np.abs(ee - np.median(ee)))),
            "coverage": float(np.mean(conv[ok])), "bound_rms": b_ref, "rmse_over_bound": _ratio(rr, b_ref),
            "bound_row_rms": b_row, "rmse_over_row_bound": _ratio(rr, b_row),
            "rmse_common_over_bound": _ratio(_rms(ec), b_com),
            "bias_refined": float(np.mean(er)) if er.size else np.nan, "rmse_refined": rr,
            "rmse_refined_ci": cluster_rmse_ci(sse_r, n_r),
            "bias_optical": float(np.nanmean(er - opt_r)) if has_opt else np.nan,
            "rmse_optical": ro, "rmse_optical_over_bound": _ratio(ro, b_ref),
            "rmse_common": _rms(ec), "rmse_common_ci": cluster_rmse_ci(sse_c, n_c),
            "bias_common": float(np.mean(ec)) if ec.size else np.nan,
            "bias_common_optical": float(np.nanmean(ec - opt_c)) if np.isfinite(opt_c).any() else np.nan,
            "optical_offset": float(np.nanmean(opt[ok])) if np.isfinite(opt[ok]).any() else np.nan}


def image_comparisons(table, methods, reference: str = REFERENCE_METHOD, mask: np.ndarray | None = None) -> list[dict]:
    """The reference against every method on the same images and points (``mask``: e.g. the common
    subset; default all): Wilcoxon signed-rank on per-image RMSE (Holm over the methods),
    rank-biserial r, pooled ΔRMSE with an image-bootstrap 95 % CI."""
    n_img = len(table.images)
    mask = np.ones(len(table.image), bool) if mask is None else np.asarray(mask, bool)

    def sums(m):
        e = np.where(mask, table.errors[m], np.nan)
        return per_image_sums(table.image, e, n_img)
    sse_r, n_r = sums(reference)
    rows = []
    for m in methods:
        if m == reference:
            continue
        sse_m, n_m = sums(m)
        use = (n_r > 0) & (n_m == n_r)
        a, b = np.sqrt(sse_r[use] / n_r[use]), np.sqrt(sse_m[use] / n_m[use])
        w = wilcoxon_paired(a, b)
        tot = n_r[use].sum()
        rows.append({"method": m, "n_images": int(use.sum()), "p_value": w["p_value"], "rank_biserial": rank_biserial(a, b),
                     "rmse_difference": float(np.sqrt(sse_r[use].sum() / tot) - np.sqrt(sse_m[use].sum() / tot))
                     if tot else np.nan,
                     "rmse_difference_ci": cluster_rmse_ci(sse_r[use], n_r[use], other=sse_m[use])})
    for r, p in zip(rows, holm([r["p_value"] for r in rows]) if rows else []):
        r["p_holm"] = float(p)
        r["significant"] = bool(p < 0.05)
    return rows


def cells(table) -> dict:
    """The image masks of the ranging tables' cells: {"base": mask, "factors": [(FactorTable, {level:
    mask}), ...] (Table 16's factor, Table 17's, then every other factor of the design), "groups":
    (FactorTable, {group: mask}) or None (the groups outside the design), "G": {level: mask}, "T": ...}."""
    recs = [dict(r, _k=k) for k, r in enumerate(table.images)]
    n = len(recs)

    def mask(sel):
        m = np.zeros(n, bool)
        m[[r["_k"] for r in sel]] = True
        return m

    def by_level(ft):
        return {lv: mask([r for r in ft.rows if r["group"] == lv]) for lv in ft.levels}
    out = {"base": mask(main_rows(recs)), "G": {}, "T": {}, "factors": [], "groups": None}
    for ft in factor_tables(recs):
        masks = by_level(ft)
        out["factors"].append((ft, masks))
        if ft.key in ("G", "T"):
            out[ft.key] = masks
    plain = plain_groups(recs)
    if plain is not None:
        out["groups"] = (plain, by_level(plain))
    return out


def level_tests(table, m: str, level_masks: dict) -> dict:
    """Per-image RMSE of method ``m`` on each level's images, paired on the pose slot (blocks = the
    same spec and slot): Friedman's test across the levels (three or more), Kendall's W, Wilcoxon
    signed-rank between consecutive levels with Holm's correction and the rank-biserial r
    (``steps``), and whether the pooled RMSE never falls."""
    n_img = len(table.images)
    sse, n = per_image_sums(table.image, table.errors[m], n_img)

    def slot(k):
        return str(table.images[k].get("spec", "")), str(table.images[k].get("slot", ""))
    slots = sorted({slot(k) for mk in level_masks.values() for k in np.flatnonzero(mk)})
    row = {s: i for i, s in enumerate(slots)}
    blocks = np.full((len(slots), len(level_masks)), np.nan)
    pooled = []
    for j, mk in enumerate(level_masks.values()):
        for k in np.flatnonzero(mk & (n > 0)):
            blocks[row[slot(k)], j] = np.sqrt(sse[k] / n[k])
        pooled.append(float(np.sqrt(sse[mk].sum() / n[mk].sum())) if n[mk].sum() else np.nan)
    fr = friedman(blocks)
    full = blocks[np.all(np.isfinite(blocks), axis=1)]
    steps = paired_comparisons(full, list(level_masks)) if len(level_masks) >= 2 else []
    return {**fr, "n_blocks": int(full.shape[0]), "k": len(level_masks), "pooled": pooled,
            "non_decreasing": bool(np.all(np.diff(pooled) >= 0)), "steps": steps}


#: the SNR levels' trend (its first name)
level_trend = level_tests


def describe_level_tests(t: dict) -> str:
    """One line: the paired tests of ``level_tests`` (n slots, Friedman, each step's r and p)."""
    if t["k"] == 2 and t["steps"]:
        s = t["steps"][0]
        return (f"paired on n = {s['n_pairs']} pose slots: Wilcoxon signed-rank {s['from']}→{s['to']} on per-image "
                f"RMSE, median Δ {_f(s['median_difference'], 4)} px, r = {_f(s['rank_biserial'], 2)}, "
                f"p = {s['p_value']:.3g} (two levels: no Friedman test)")
    steps = "; ".join(f"{s['from']}→{s['to']} median Δ {_f(s['median_difference'], 4)} px, r = "
                      f"{_f(s['rank_biserial'], 2)}, p(Holm) = {s['p_holm']:.3g}" for s in t["steps"])
    p = f"{t['p_value']:.3g}" if np.isfinite(t["p_value"]) else "—"
    return (f"paired on n = {t['n_blocks']} pose slots: Friedman χ² = {_f(t['statistic'], 2)}, p = {p}, "
            f"Kendall's W = {_f(t['kendall_w'], 2)}" + (f"; {steps}" if steps else ""))


def window_shares(table, m: str) -> dict:
    w = table.windows.get(m)
    if w is None or not len(w):
        return {}
    return {int(k): float(np.mean(w == k)) for k in (5, 7, 9, 11)}


def cell_name(ft) -> str:
    """A factor table's ``cell`` in ``render_points_summary.csv``: snr (Table E4G), target (E4T), the
    factor's own name, or ``group`` for the groups outside the design."""
    return {"G": "snr", "T": "target"}.get(ft.key, ft.factor)


def named_cells(c: dict) -> list[tuple[str, str, np.ndarray]]:
    """(cell, level, image mask) of every cell in ``cells``: the base cell, each factor's levels, the
    groups outside the design."""
    out = [("base", "", c["base"])]
    for ft, masks in c["factors"] + ([c["groups"]] if c["groups"] else []):
        out += [(cell_name(ft), lv, mk) for lv, mk in masks.items()]
    return out


def summary_rows(table, methods) -> list[dict]:
    """``render_points_summary.csv``: method × cell × distance interval (and "all")."""
    bound, interval = image_columns(table)
    c = cells(table)
    out = []
    for factor, level, mk in named_cells(c):
        for iv in ["all"] + [f"{a}-{b}" for a, b in INTERVALS_CM]:
            sel = mk if iv == "all" else mk & (interval == iv)
            if not sel.any():
                continue
            sub = table.select(sel)
            common = common_mask(sub, methods)
            for m in methods:
                s = point_stats(sub, m, bound, common)
                out.append({"cell": factor, "level": level, "interval": iv, "method": m, "n_points": s["n"],
                            "n_images": s["n_images"], "bias_px": s["bias"], "rmse_px": s["rmse"],
                            "rmse_ci_lo_px": s["rmse_ci"][0], "rmse_ci_hi_px": s["rmse_ci"][1],
                            "robust_sd_px": s["robust_sd"], "coverage": s["coverage"], "bound_rms_px": s["bound_rms"],
                            "rmse_over_bound": s["rmse_over_bound"],
                            "rmse_common_over_bound": s["rmse_common_over_bound"],
                            "bound_row_rms_px": s["bound_row_rms"], "rmse_over_row_bound": s["rmse_over_row_bound"],
                            "n_refined": s["n_refined"],
                            "bias_refined_px": s["bias_refined"], "rmse_refined_px": s["rmse_refined"],
                            "n_common": s["n_common"], "rmse_common_px": s["rmse_common"],
                            "bias_common_px": s["bias_common"], "bias_optical_px": s["bias_optical"],
                            "bias_common_optical_px": s["bias_common_optical"],
                            "optical_offset_px": s["optical_offset"], "rmse_optical_px": s["rmse_optical"],
                            "rmse_optical_over_bound": s["rmse_optical_over_bound"],
                            **{f"window{w}_share": v for w, v in window_shares(sub, m).items()}})
    return out


SUMMARY_FIELDS = ("cell", "level", "interval", "method", "n_points", "n_images", "bias_px", "rmse_px", "rmse_ci_lo_px",
                  "rmse_ci_hi_px", "robust_sd_px", "coverage", "bound_rms_px", "rmse_over_bound",
                  "rmse_common_over_bound", "bound_row_rms_px", "rmse_over_row_bound", "n_refined",
                  "bias_refined_px", "rmse_refined_px", "n_common", "rmse_common_px", "bias_common_px",
                  "bias_optical_px", "bias_common_optical_px", "optical_offset_px", "rmse_optical_px",
                  "rmse_optical_over_bound", "window5_share",
                  "window7_share", "window9_share", "window11_share")


def write_summary(path: Path, rows: list[dict]) -> None:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=SUMMARY_FIELDS, extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items() if k in SUMMARY_FIELDS})
    atomic_write_text(path, buf.getvalue())


def figures(table, methods, fig_dir: Path) -> dict:
    import matplotlib  # lazy: matplotlib is heavy
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # lazy: matplotlib is heavy

    fig_dir.mkdir(parents=True, exist_ok=True)
    bound, interval = image_columns(table)
    c = cells(table)
    rep = [m for m in list(SEED_ROBUSTNESS) + [m + "_camera" for m in ("dynamic_erf_4p",)] + ["canny_devernay", "pae2013"]
           if m in methods and m != "canny_pixel"] or [m for m in methods if m != "canny_pixel"] or list(methods)
    out = {}
    labels = [f"{a}-{b}" for a, b in INTERVALS_CM]
    present = [lb for lb in labels if (c["base"] & (interval == lb)).any()]
    panels = [("fig_points_distance", "reference distance (cm)", present,
               [c["base"] & (interval == lb) for lb in present])]
    seed = {"G": ("fig_points_snr", "SNR level (light halves, gain doubles)"), "T": ("fig_points_target", "target")}
    for ft, lm in c["factors"] + ([c["groups"]] if c["groups"] else []):
        if ft.key in seed:
            key, xlabel = seed[ft.key]
        elif ft.key == "group":
            key, xlabel = "fig_points_group", "group (outside the design)"
        else:
            key, xlabel = f"fig_points_factor_{ft.factor}", f"factor {ft.factor}"
        panels.append((key, xlabel, list(lm), list(lm.values())))
    for key, xlabel, ticks, masks in panels:
        if len(ticks) < 2:
            continue
        fig, ax = plt.subplots(figsize=(7, 4))
        subs = [table.select(mk) for mk in masks]
        commons = [common_mask(sb, methods) for sb in subs]
        for m in rep:
            st = [point_stats(sb, m, bound, cm) for sb, cm in zip(subs, commons)]
            y = np.array([s["rmse_common"] for s in st])
            lo = np.array([s["rmse_common_ci"][0] for s in st])
            hi = np.array([s["rmse_common_ci"][1] for s in st])
            ax.errorbar(range(len(ticks)), y, yerr=[np.nan_to_num(y - lo), np.nan_to_num(hi - y)], marker="o",
                        capsize=3, label=_label(m))
        b = [float(np.sqrt(np.nanmean(bound[mk] ** 2))) if mk.any() and np.isfinite(bound[mk]).any() else np.nan
             for mk in masks]
        ax.plot(range(len(ticks)), b, "k--", lw=1, label="11-pixel-row reference (approx., not a floor)")
        ax.set_xticks(range(len(ticks)), ticks)
        ax.set_xlabel(xlabel)
        ax.set_ylabel("per-point RMSE on the common subset (px), 95 % CI")
        ax.set_yscale("log")
        ax.legend(fontsize=7)
        fig.tight_layout()
        p = fig_dir / f"{key}.png"
        fig.savefig(p, dpi=110)
        plt.close(fig)
        out[key] = p
    return out


def report_section(table, methods, out_dir: Path) -> list[str]:
    """The report's per-point section (markdown lines); writes ``render_points_summary.csv`` and figures."""
    bound, interval = image_columns(table)
    write_summary(out_dir / "render_points_summary.csv", summary_rows(table, methods))
    c = cells(table)
    base = table.select(c["base"])
    common = common_mask(base, methods)
    st = {m: point_stats(base, m, bound, common) for m in methods}
    order = sorted(methods, key=lambda m: st[m]["rmse_common"] if np.isfinite(st[m]["rmse_common"]) else np.inf)
    n_img = int(c["base"].sum())
    has_opt = np.isfinite(base.optical("centroid")).any()
    L = ["", "## Table E1 — per-point edge error on the renders (px), base cell, all methods", "",
         f"Every method refines the *same* Canny boundary candidates of the raw (distorted) image; each point's error "
         f"is its signed distance to the exact distorted outline of the ground truth (> 0 on the bright board). "
         f"Scored: candidates within {MATCH_RADIUS_PX} px of the outline, squares' candidates farther than "
         f"{CORNER_EXCLUSION_PX:g} px from a corner.  {n_img} images, {len(base.image)} candidates, "
         f"{int(common.sum())} in the common subset.  Four figures per method, as in the synthetic study: "
         "*coverage* (share of the candidates it refines; a decline answers with the candidate pixel); bias and RMSE "
         "on its *refined* points; RMSE on the *common subset* (the candidates every method here refines: the "
         "like-with-like comparison, and the order of the rows); RMSE on *all* candidates with the declines scored "
         "at the pixel centre (what a user keeping every point gets).  CI: 95 % bootstrap over images (a cluster "
         "bootstrap: an image's points share its pose and noise).  robust SD = 1.4826·MAD (all candidates).  "
         + ("bias vs optical edge: the refined points' mean error against the outline moved by the displacement "
            "the camera model predicts (render/optics/optical_edge.py; its centroid), the optics' own share "
            "apart in Table E3; RMSE vs optical ÷ bound: the RMSE on the refined points against that optical "
            "edge over the same bound -- the bound's expected image has no such displacement, so this is the "
            "figure an efficient estimator brings to 1.  " if has_opt else "")
         + "RMSE ÷ bound: the RMSE on the method's refined points over the RMS of its *exact per-point "
         "Cramér–Rao bound* there (edgetruth/evaluate/points/bound.py, docs/bound.md): for each point, the lowest "
         "standard deviation any unbiased estimate of its distance to the outline can have, given exactly the pixels "
         "the method reads (its declared footprint) -- the camera's PSF at the point's field height (Airy ⊗ "
         "aberration ⊗ defocus disk ⊗ OLPF, box-integrated), the outline's orientation and curvature, the shading "
         "on both sides, the sensor's signal-dependent noise, with the normal, both levels and the PSF's scale "
         "unknown.  A ratio near 1 is a method at the limit; a ratio below ~0.97 would be a bug or a biased "
         "estimator that shrinks its answer.  RMSE includes bias (the optics' and the method's), the bound only the "
         "noise.  ÷ row ref.: the same RMSE over the old *approximate* figure (an axis-aligned 11-pixel row, "
         "Gaussian-equivalent PSF; a reference only, not a floor for oblique sides or 2-D methods).", "",
         _table(["method", "coverage", "bias (refined)"] + (["bias vs optical edge"] if has_opt else [])
                + ["RMSE (refined)", "RMSE (common subset)", "common 95 % CI", "RMSE (all, declines at pixel)",
                   "robust SD", "bound (px)", "RMSE ÷ bound"] + (["RMSE vs optical ÷ bound"] if has_opt else [])
                + ["÷ row ref."],
                [[_label(m), _f(100 * st[m]["coverage"], 1) + " %", _f(st[m]["bias_refined"], 4)]
                 + ([_f(st[m]["bias_optical"], 4)] if has_opt else [])
                 + [_f(st[m]["rmse_refined"], 4), _f(st[m]["rmse_common"], 4), _ci(st[m]["rmse_common_ci"], 4),
                    _f(st[m]["rmse"], 4), _f(st[m]["robust_sd"], 4), _f(st[m]["bound_rms"], 4),
                    _f(st[m]["rmse_over_bound"], 2)]
                 + ([_f(st[m]["rmse_optical_over_bound"], 2)] if has_opt else []) + [_f(st[m]["rmse_over_row_bound"], 2)]
                 for m in order])]
    if REFERENCE_METHOD in methods:
        comp = image_comparisons(base, order, mask=common)
        L += ["", "## Table E2 — per-point: ProposedDynamicERF_4P vs each method on the common subset", "",
              "On the common subset only (the candidates every method refines: the same points for both sides of "
              "each pair).  Wilcoxon signed-rank on per-image RMSE (pairs: the same spec and image), Holm over the "
              "methods; r = matched-pairs rank-biserial (< 0: Dynamic 4P has the smaller per-image RMSE); "
              "ΔRMSE = pooled RMSE(Dynamic 4P) − RMSE(method), image-bootstrap 95 % CI.", "",
              _table(["method", "images", "ΔRMSE (px)", "ΔRMSE 95 % CI", "r", "p", "p (Holm)", "significant"],
                     [[_label(r["method"]), r["n_images"], _f(r["rmse_difference"], 4), _ci(r["rmse_difference_ci"], 4),
                       _f(r["rank_biserial"], 2), f"{r['p_value']:.2g}", f"{r['p_holm']:.2g}",
                       "yes" if r["significant"] else "no"] for r in comp])]
    best = order[0] if order else None
    if best is not None and best != REFERENCE_METHOD and len(order) > 1:
        comp = image_comparisons(base, order, reference=best, mask=common)
        L += ["", f"## Table E2b — per-point: the lowest-RMSE method ({_label(best)}) vs each on the common subset", "",
              f"As Table E2, with {_label(best)} (the lowest RMSE on the common subset) in Dynamic 4P's place: "
              f"r < 0 and ΔRMSE < 0 mean {_label(best)} has the smaller per-image RMSE.", "",
              _table(["method", "images", "ΔRMSE (px)", "ΔRMSE 95 % CI", "r", "p", "p (Holm)", "significant"],
                     [[_label(r["method"]), r["n_images"], _f(r["rmse_difference"], 4), _ci(r["rmse_difference_ci"], 4),
                       _f(r["rank_biserial"], 2), f"{r['p_value']:.2g}", f"{r['p_holm']:.2g}",
                       "yes" if r["significant"] else "no"] for r in comp])]
    present = [f"{a}-{b}" for a, b in INTERVALS_CM if (c["base"] & (interval == f"{a}-{b}")).any()]
    if present:
        subs = {lb: table.select(c["base"] & (interval == lb)) for lb in present}
        comm = {lb: common_mask(sb, methods) for lb, sb in subs.items()}
        sti = {(m, lb): point_stats(subs[lb], m, bound, comm[lb]) for m in order for lb in present}

        def cell(s):
            txt = f"{_f(s['rmse_common'], 4)} (bias {_f(s['bias_common'], 4)}"
            return txt + (f"; vs optical {_f(s['bias_common_optical'], 4)})" if has_opt else ")")
        rows = [[_label(m)] + [cell(sti[(m, lb)]) for lb in present] for m in order]
        if has_opt:
            rows.append(["*optics: predicted displacement of the edge*"]
                        + [_f(float(np.nanmean(subs[lb].optical("centroid")[comm[lb]])), 4)
                           + f" (50 %: {_f(float(np.nanmean(subs[lb].optical('median')[comm[lb]])), 4)})"
                           for lb in present])
        L += ["", "## Table E3 — per-point RMSE (px) per distance interval, base cell, common subset", "",
              "RMSE and bias on each interval's common subset; bias against the geometric outline and, where the "
              "truth carries it, against the optical edge (the outline moved by the displacement the camera model "
              "predicts: a defocused edge off axis moves because the thin lens's vignetting weight tilts the defocus "
              "disk; docs/optics.md).  The last row is that displacement itself (centroid; 50 % level), the optics' "
              "share of the bias, > 0 towards the bright board." if has_opt else
              "RMSE and bias on each interval's common subset, against the geometric outline.", "",
              _table(["method"] + [f"{lb} cm" for lb in present], rows)]
    seed_titles = {"G": "SNR levels G1–G4", "T": "targets T1–T4"}
    for ft, lm in c["factors"] + ([c["groups"]] if c["groups"] else []):
        levels = list(lm)
        if len(levels) < 2 and ft.key != "group":
            continue
        body = []
        lsubs = {lv: table.select(lm[lv]) for lv in levels}
        lcomm = {lv: common_mask(sb, methods) for lv, sb in lsubs.items()}
        for m in order:
            body.append([_label(m)] + [(lambda s: f"{_f(s['rmse_common'], 4)} {_ci(s['rmse_common_ci'], 4)} "
                                                  f"({_f(100 * s['coverage'], 1)} %; refined "
                                                  f"{_f(s['rmse_refined'], 4)}, ÷ bound "
                                                  f"{_f(s['rmse_over_bound'], 2)}; all {_f(s['rmse'], 4)})")(
                point_stats(lsubs[lv], m, bound, lcomm[lv])) for lv in levels])
        if ft.key in seed_titles:
            head = f"Table E4{ft.key} — per-point RMSE (px) across the {seed_titles[ft.key]} (same pose slots)"
        elif ft.key == "group":
            head = ("Groups outside the design — per-point RMSE (px) per group (each group drew its own poses: "
                    "not paired)")
        else:
            head = f"{ft.title} — per-point RMSE (px) across the levels (same pose slots)"
        L += ["", f"## {head}", "",
              "Each cell: RMSE on the level's common subset [95 % CI] (coverage; RMSE on the refined points and its "
              "ratio to the exact per-point bound there, as in Table E1; on all candidates, declines at the pixel "
              "centre).", "",
              _table(["method"] + levels, body)]
        paired = ft.key != "group" and all(str(table.images[k].get("slot", "")) != ""
                                           for mk in lm.values() for k in np.flatnonzero(mk))
        if not paired:
            continue
        tr = {m: level_tests(table, m, lm) for m in order if m != "canny_pixel"}
        if ft.key == "G":
            up = [m for m, t in tr.items() if t["non_decreasing"]]
            ps = [t["p_value"] for t in tr.values() if np.isfinite(t["p_value"])]
            L += ["", f"Per point, the error grows with the noise: the pooled RMSE never falls from {levels[0]} to "
                  f"{levels[-1]} for {len(up)} of {len(tr)} subpixel methods"
                  + (f" (not for {', '.join(_label(m) for m in tr if m not in up)})" if len(up) < len(tr) else "")
                  + f"; paired on the pose slots (per-image RMSE, Friedman across the levels, n = "
                  f"{max(t['n_blocks'] for t in tr.values())} slots) p ≤ {max(ps):.2g} for every one of them, Kendall's W "
                  f"{min(t['kendall_w'] for t in tr.values()):.2f}–{max(t['kendall_w'] for t in tr.values()):.2f}. "
                  "The ranging errors of Table 16 need not follow: there the edge part is a small share of the "
                  "ranging error (the model floor and the calibration dominate; Table 13's size RMSE in px against "
                  "its cm)." if ps else ""]
        L += ["", "Paired tests across the levels, per method (per-image RMSE on all candidates, declines at the "
                  "pixel centre, on the pose slots every level rendered; Friedman across the levels, then Wilcoxon signed-rank between consecutive levels, "
                  "Holm-adjusted; r = matched-pairs rank-biserial, > 0: the later level has the larger error): "]
        L += [f"- {_label(m)}: " + describe_level_tests(t) for m, t in tr.items()]
    dyn = [m for m in methods if m in table.windows]
    if dyn:
        groups = [("base", c["base"])] + [(ft.cell_label(lv), mk) for ft, lm in c["factors"] for lv, mk in lm.items()]
        if c["groups"]:
            groups += [(f"group {g}", mk) for g, mk in c["groups"][1].items()]
        body = []
        for m in dyn:
            for name, mk in groups:
                sh = window_shares(table.select(mk), m)
                if sh:
                    body.append([_label(m), name] + [f"{100 * sh[w]:.1f} %" for w in (5, 7, 9, 11)])
        L += ["", "## Window shares of the dynamic methods on the renders (scored points)", "",
              "Shipped thresholds (calibrated on synthetic edges) and, where present, thresholds calibrated "
              "for this camera on disjoint renders (`(camera τ)`).  cell: the base cell, a factor's level "
              "(G2, T3, factor=level), or a group outside the design.", "",
              _table(["method", "cell", "5", "7", "9", "11"], body)]
    figs = figures(table, methods, out_dir / "figures")
    names = {"fig_points_distance": "per-point RMSE vs distance (base cell)",
             "fig_points_snr": "per-point RMSE vs SNR level", "fig_points_target": "per-point RMSE vs target",
             "fig_points_group": "per-point RMSE per group outside the design"}
    if figs:
        L += [""]
    for k, p in figs.items():
        rel = Path(p).relative_to(out_dir)
        name = names.get(k) or f"per-point RMSE vs factor {k.removeprefix('fig_points_factor_')}"
        L += [f"**Figure — {name}**", "", f"![{name}]({rel})", ""]
    return L
