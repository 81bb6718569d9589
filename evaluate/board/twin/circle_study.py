"""The digital twin of circle-grid photos: render it, run the same circle-grid study on twin and photos, compare.

``edgetruth study twin PHOTOS... --pattern circles:10x8 --square 0.025 --twin DIR/twin.toml`` (the twin ``edgetruth
twin`` derives with ``measure_circles``):

1. **Render** the twin (resumable) into ``DIR/renders``; its images pair with the photos by group name.
2. **The same circle-grid study** (``circle_grid.study.compute_circle_study``) on the twin's PNGs and on the photos:
   the same methods, grid finding, ellipses, corrected centres, calibration and leave-one-out.  Each study's own
   files go to ``DIR/real`` and ``DIR/twin``.
3. **Against the truth** (twin only): every row's centres (OpenCV's blob centroids and each method's corrected
   centres) against the image of each circle's centre in the render's JSON (``centre_distorted_px``): RMS and mean
   offset, px.  This is the error a user wants to know and the photos cannot give.
4. **Rankings and size**: Spearman ρ (``stats.spearman``) between real and twin over the methods for the ellipse
   residual, calibration RMS and leave-one-out RMS; and, on the twin, between the ellipse residual and the centres'
   error against the truth; and the median over the methods of twin ÷ real for each figure.

``DIR/report.md`` sets real and twin side by side; ``DIR/twin_vs_real.csv`` holds its method table.
"""
from __future__ import annotations

import csv
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from edgetruth import console, locate
from edgetruth.errors import InputError
from edgetruth.evaluate import method_order as mo
from edgetruth.evaluate.board.circle_grid.rows import REFERENCE_ROW
from edgetruth.evaluate.board.circle_grid.study import compute_circle_study, write_circle_run
from edgetruth.evaluate.board.inputs import BoardInputs
from edgetruth.evaluate.board.twin.budget import (BUDGET_SEEDS, budget_rows, circle_figures, per_method_rows,
                                                  term_scenes, write_budget)
from edgetruth.evaluate.run_dir import check_same_settings, prepare_run_dir
from edgetruth.evaluate.stats import spearman
from edgetruth.fileio import atomic_write_text, write_json
from edgetruth.locate.registry import camera_free
from edgetruth.render.dataset.driver import check_variant_name, render_spec
from edgetruth.render.dataset.reader import open_dataset
from edgetruth.render.dataset.spec import load_spec

KIND = "study twin (circle grid)"
#: the figures compared, real against twin: (summary key, words)
FIGURES = (("ellipse_rms_px", "ellipse residual"), ("calib_rms_px", "calibration RMS"),
           ("loo_rms_px", "leave-one-out RMS"))


def centre_errors(row, names: list[str], truths: dict[str, dict]) -> dict:
    """A row's centres (per photo (n, 2), OpenCV's order) against the JSON's image of each circle's centre: RMS of
    the distance, the mean offset (x, y) and n, over every finite centre of the photos ``names``."""
    d = []
    for pts, name in zip(row.points, names):
        truth = np.asarray(truths[name]["circles"]["centre_distorted_px"], float)
        if truth.shape != np.shape(pts):
            raise InputError(f"{name}: the render's circles ({len(truth)}) are not the grid's ({len(pts)})")
        e = np.asarray(pts, float) - truth
        d.append(e[np.all(np.isfinite(e), axis=1)])
    e = np.concatenate(d) if d else np.zeros((0, 2))
    if not len(e):
        return {"centre_rms_px": float("nan"), "centre_mean_x_px": float("nan"), "centre_mean_y_px": float("nan"),
                "centres": 0}
    return {"centre_rms_px": float(np.sqrt(np.mean(np.sum(e * e, axis=1)))),
            "centre_mean_x_px": float(e[:, 0].mean()), "centre_mean_y_px": float(e[:, 1].mean()),
            "centres": int(len(e))}


def comparison_rows(real_run, twin_run, errors: dict) -> list[dict]:
    """One line per row of the study (methods, then the reference): each figure real and twin, and the twin's
    centre error against the truth."""
    real = {s["row"]: s for s in real_run.summaries}
    twin = {s["row"]: s for s in twin_run.summaries}
    out = []
    for s in twin_run.summaries:
        r = real.get(s["row"], {})
        line = {"row": s["row"], "label": s["label"]}
        for key, _ in FIGURES:
            line[f"real_{key}"] = r.get(key, float("nan"))
            line[f"twin_{key}"] = twin[s["row"]].get(key, float("nan"))
        line.update(errors.get(s["row"], {}))
        out.append(line)
    return out


def agreement(lines: list[dict]) -> dict:
    """Over the method rows: Spearman real vs twin per figure, the twin's ellipse residual vs its centre error,
    and the median twin ÷ real per figure."""
    m = [ln for ln in lines if ln["row"] != REFERENCE_ROW]
    out = {"rank": [], "ratio": {}}
    for key, words in FIGURES:
        a = [ln[f"real_{key}"] for ln in m]
        b = [ln[f"twin_{key}"] for ln in m]
        out["rank"].append({"what": f"{words}: real vs twin", **spearman(a, b)})
        ratio = [y / x for x, y in zip(a, b) if np.isfinite(x) and np.isfinite(y) and x > 0]
        out["ratio"][key] = float(np.median(ratio)) if ratio else float("nan")
        out["ratio"][f"real_median_{key}"] = float(np.nanmedian(a)) if np.isfinite(a).any() else float("nan")
        out["ratio"][f"twin_median_{key}"] = float(np.nanmedian(b)) if np.isfinite(b).any() else float("nan")
    out["rank"].append({"what": "twin: ellipse residual vs centre error against the truth",
                        **spearman([ln["twin_ellipse_rms_px"] for ln in m],
                                   [ln.get("centre_rms_px", np.nan) for ln in m])})
    return out


def _f(v, fmt=".4f") -> str:
    return "—" if v is None or not np.isfinite(v) else f"{v:{fmt}}"


def write_report(out: Path, set_name: str, spec_name, lines: list[dict], agree: dict, names: list[str],
                 timings: dict, budget_lines: list[str] | None = None) -> Path:
    """report.md, twin_vs_real.csv and twin_vs_real.json of the study (and the budget's section, when given)."""
    keys = list(lines[0])
    with open(out / "twin_vs_real.csv.tmp", "w", newline="") as fh:
        w = csv.DictWriter(fh, keys, extrasaction="ignore")
        w.writeheader()
        w.writerows(lines)
    (out / "twin_vs_real.csv.tmp").replace(out / "twin_vs_real.csv")
    write_json(out / "twin_vs_real.json", {"rows": lines, "agreement": agree, "photos": names, "timings": timings})
    r = agree["ratio"]
    text = [f"# Digital twin — {set_name} (circle grid)", "",
            f"The twin `{spec_name}` rendered beside {len(names)} photos ({', '.join(names)}), the circle-grid board "
            "study on both (docs/board.md, 'Circle grids' and 'Your own twin').", "",
            "## How large: twin ÷ real (median over the methods)", "",
            "| figure | real (median) | twin (median) | twin ÷ real |", "|---|---|---|---|"]
    for key, words in FIGURES:
        text.append(f"| {words} (px) | {_f(r[f'real_median_{key}'])} | {_f(r[f'twin_median_{key}'])} | "
                    f"{_f(r[key], '.2f')} |")
    text += ["", "## Rankings (Spearman over the methods)", "", "| what | ρ | p | n |", "|---|---|---|---|"]
    for a in agree["rank"]:
        text.append(f"| {a['what']} | {_f(a['rho'], '.2f')} | {_f(a['p'], '.2g')} | {a['n']} |")
    text += ["", "## Per row", "",
             "Centre error: the row's centres on the twin against the image of each circle's centre (the render's "
             "truth), RMS of the distance and the mean offset.", "",
             "| row | ellipse real | ellipse twin | calib RMS real | calib RMS twin | LOO real | LOO twin | "
             "twin centre error RMS | mean x, y |", "|---|---|---|---|---|---|---|---|---|"]
    for ln in lines:
        text.append(f"| {ln['label']} | {_f(ln['real_ellipse_rms_px'])} | {_f(ln['twin_ellipse_rms_px'])} | "
                    f"{_f(ln['real_calib_rms_px'])} | {_f(ln['twin_calib_rms_px'])} | {_f(ln['real_loo_rms_px'])} | "
                    f"{_f(ln['twin_loo_rms_px'])} | {_f(ln.get('centre_rms_px'))} | "
                    f"{_f(ln.get('centre_mean_x_px'), '+.4f')}, {_f(ln.get('centre_mean_y_px'), '+.4f')} |")
    text += ["", *(budget_lines or [])]
    text += [f"Timings: " + ", ".join(f"{k} {v:.1f} s" for k, v in timings.items()) + ".",
             "Each study's own report: `real/report.md`, `twin/report.md`.", ""]
    atomic_write_text(out / "report.md", "\n".join(text))
    return out / "report.md"


def circle_pngs(spec, render_dir: Path, keep: list[int], variant, progress: bool) -> tuple[list, list]:
    """Render ``spec``'s images ``keep`` into ``render_dir`` (resumable) -> (their PNG paths, samples), in order."""
    render_spec(spec, render_dir, variant=variant, progress=progress, only=keep,
                announce=lambda s: console.say(s) if progress else None)
    by_index = {s.index: s for s in open_dataset(render_dir) if s.kind == "circles_grid"}
    missing = [i for i in keep if i not in by_index]
    if missing:
        raise InputError(f"{render_dir}: image(s) {', '.join(str(i) for i in missing)} did not render (or are not "
                         "circle grids); run again, or check --twin")
    samples = [by_index[i] for i in keep]
    return [s.dataset.path / s.dataset.manifest["images"][s.name]["files"]["png"]["path"] for s in samples], samples


def circle_budget(out: Path, spec_name, terms: list[str], spp, keep: list[int], real: BoardInputs, real_run,
                  twin_run, methods: list[str], options: dict, channel: str, variant, progress: bool) -> list[str]:
    """The error budget (``twin.budget``) of a circle grid's twin: each term's scene rendered and studied as the
    twin is, the ellipse residual in straightness' place; returns the report's lines."""
    scenes = term_scenes(spec_name, out / "budget", names=terms or None, spp=spp, seeds=BUDGET_SEEDS)
    off, photos = {}, {"": len(real_run.setup.names), "all": len(twin_run.setup.names)}
    for name, path in scenes.items():
        pngs, _ = circle_pngs(load_spec(path), path.parent / "renders", keep, variant, False)
        try:
            run = compute_circle_study(replace(real, photos=pngs, set_name=f"{real.set_name} {name}"), methods,
                                       options, channel, progress)
        except InputError as exc:  # too few grids found with the term off: say so, keep the others
            console.say(f"budget: {name}: {exc}")
            continue
        off[name] = circle_figures(run.summaries)
        photos[name] = len(run.setup.names)
    real_s, twin_s = circle_figures(real_run.summaries), circle_figures(twin_run.summaries)
    return write_budget(out, budget_rows(real_s, twin_s, off, methods), per_method_rows(real_s, twin_s, off, methods),
                        len(methods), photos, first="ellipse residual")


def run_circle_twin_study(real_all: BoardInputs, spec, spec_name, out, methods=None, keep=None, thresholds=None,
                          channel: str = "luma", variant: str | None = None, progress: bool = True,
                          budget: list[str] | None = None, spp: int | None = None) -> Path:
    """Steps 1-4 (module docstring) for the photos ``real_all`` (a circle grid's ``BoardInputs``, paired with the
    twin ``spec``'s images, ``keep`` their indices); ``budget``: also the error budget (``circle_budget``: [] every
    term the twin renders, or those named), ``spp`` the samples its scenes take; returns report.md."""
    t0 = time.perf_counter()
    methods = mo.ordered(camera_free() if methods is None else methods)
    for m in methods:
        locate.get_method(mo.resolve(m)[0])
    options = mo.study_options(thresholds)
    check_variant_name(variant)
    set_name = real_all.set_name or spec.name
    settings = {"set": set_name, "methods": methods, "images": [i + 1 for i in keep], "spp": spec.render.spp,
                "spec_identity": spec.identity_sha256, "channel": channel, "board": "circles"}
    if budget is not None:  # only then: an earlier run without a budget keeps its settings
        settings["budget"] = sorted(budget) or "all"
    out = check_same_settings(Path(out), KIND, settings, "a twin study")
    out = prepare_run_dir(out, KIND, settings)
    t_r = time.perf_counter()
    pngs, samples = circle_pngs(spec, out / "renders", keep, variant, progress)
    render_s = time.perf_counter() - t_r
    real = replace(real_all, photos=[real_all.photos[i] for i in keep])
    twin = replace(real, photos=pngs, set_name=f"{set_name} twin")
    t_s = time.perf_counter()
    real_run = compute_circle_study(real, methods, options, channel, progress)
    twin_run = compute_circle_study(twin, methods, options, channel, progress)
    study_s = time.perf_counter() - t_s
    # the twin's images by the name the study gives them, with their truth; the photos' found alike
    truth_by_name = dict(zip(twin.names, [s.truth for s in samples]))
    lost = [(r, t) for r, t in zip(real.names, twin.names) if (r in real_run.setup.names) != (t in twin_run.setup.names)]
    if lost:
        console.say("study twin: the grid was found on only one of " + ", ".join(f"{r} / {t}" for r, t in lost)
                    + " (photo / twin image): each study keeps the photos it found the grid on")
    errors = {r.label: centre_errors(r, twin_run.setup.names, truth_by_name) for r in twin_run.rows}
    lines = comparison_rows(real_run, twin_run, errors)
    agree = agreement(lines)
    for sub, run, title in (("real", real_run, f"Board study (circle grid) — {set_name} (real photos)"),
                            ("twin", twin_run, f"Board study (circle grid) — {set_name} twin (renders)")):
        (out / sub).mkdir(exist_ok=True)
        write_circle_run(run, out / sub, channel, methods, options, thresholds, title=title)
    timings = {"render_s": render_s, "studies_s": study_s}
    budget_lines = None
    if budget is not None:
        t_b = time.perf_counter()
        budget_lines = circle_budget(out, spec_name, budget, spp, keep, real, real_run, twin_run, methods, options,
                                     channel, variant, progress)
        timings["budget_s"] = time.perf_counter() - t_b
    timings["total_s"] = time.perf_counter() - t0
    r = agree["ratio"]
    console.say(f"study twin: twin ÷ real (median over {len(methods)} methods): ellipse residual "
                f"{r['ellipse_rms_px']:.2f}, calibration RMS {r['calib_rms_px']:.2f}; ρ "
                + ", ".join(f"{a['rho']:.2f}" for a in agree["rank"][:2]) + " (ellipse, calibration)")
    return write_report(out, set_name, spec_name, lines, agree, real.names, timings, budget_lines)
