"""Calibrate the dynamic window's entropy thresholds tau1 <= tau2 <= tau3 (BRIEF §2).

Data: the ``calibration`` split of the synthetic scenarios (seeds disjoint
from every test split by construction, see ``edgetruth.render.synthetic.scenarios``),
or rendered target images of a camera (``calibrate_renders``: the per-point
truth of ``edgetruth.evaluate.points.scores`` on the raw images; the file
records every image's seeds, and ``check_disjoint`` refuses to evaluate
those thresholds on any image rendered from the same seeds).
For every on-edge candidate we fit all four fixed windows once and record
the normalised entropy H of its 11-sample profile; a threshold triple then
only selects, per point, which of the four stored errors counts.  With the
points sorted by H, the sum of squared errors of any triple is four
prefix-sum look-ups, so the full grid (step 0.01, ~177k triples) is exact
and takes milliseconds.

Objective: RMSE (px) of the selected refined positions over all on-edge
candidates of all scenarios (non-converged fits count with their fallback
position).  Ties go to the triple closest to the grid's centre of mass of
the optimal set (stable under tiny perturbations).
"""
from __future__ import annotations

import datetime as _dt
import json
from dataclasses import dataclass

import numpy as np

from edgetruth import __version__, locate
from edgetruth.errors import InputError
from edgetruth.evaluate.matching import MATCH_RADIUS_PX, on_edge
from edgetruth.evaluate.points.scores import CORNER_EXCLUSION_PX, scored_candidates
from edgetruth.fileio import write_json
from edgetruth.locate.methods.erf import WINDOWS
from edgetruth.render.dataset.reader import open_dataset
from edgetruth.render.synthetic.scenarios import DEFAULT_SHAPE, SCENARIOS, synthetic_image
from edgetruth.resources import source_commit


@dataclass
class WindowErrors:
    entropy: np.ndarray  # (N,)
    errors: dict  # model -> (4, N) signed errors for windows 5, 7, 9, 11
    scenario: np.ndarray  # (N,) scenario index
    images: int


def collect(split: str = "calibration", images_per_scenario: int = 100, shape=DEFAULT_SHAPE,
            scenarios=SCENARIOS, progress=None) -> WindowErrors:
    ent, sc = [], []
    errs = {"2p": [], "4p": []}
    total = 0
    for si, scenario in enumerate(scenarios):
        for i in range(images_per_scenario):
            s = synthetic_image(scenario, i, split=split, shape=shape)
            cand = locate.candidates(s.image)
            cand = cand.subset(on_edge(s.truth, cand))
            total += 1
            if progress is not None:
                progress()
            if not len(cand):
                continue
            for model in ("2p", "4p"):
                rows = []
                for w in WINDOWS:
                    pts = locate.refine(s.image, cand, f"erf{model}_fixed{w}")
                    rows.append(s.errors(pts.x, pts.y))
                errs[model].append(np.array(rows))
            ent.append(pts.entropy)
            sc.append(np.full(len(cand), si))
    if not ent:
        raise InputError("calibration set produced no on-edge candidates; use more images")
    return WindowErrors(np.concatenate(ent), {m: np.concatenate(v, axis=1) for m, v in errs.items()},
                        np.concatenate(sc), total)


def collect_renders(dataset_dirs, progress=None, names=None) -> tuple[WindowErrors, list[dict]]:
    """Per-point window errors on the target images of rendered datasets (raw images, exact outline,
    the scoring rule of ``edgetruth.evaluate.points.scores``); also each image's seeds and spec."""
    ent, sc, used = [], [], []
    errs = {"2p": [], "4p": []}
    total = 0
    for di, d in enumerate(dataset_dirs):
        for s in open_dataset(d).targets():
            if names is not None and s.name not in names:
                continue
            gt = s.truth
            truth = s.outline  # every visible edge: one outline, or a scene's several
            total += 1
            try:
                tc, cand, _ = scored_candidates(s.image, truth)
            except InputError:
                tc = None
            if progress is not None:
                progress()
            if tc is None or not len(cand):
                continue
            x0, y0 = tc.offset
            for model in ("2p", "4p"):
                rows = []
                for w in WINDOWS:
                    pts = locate.refine(tc.crop, cand, f"erf{model}_fixed{w}")
                    rows.append(truth.signed_distance(pts.x + x0, pts.y + y0))
                errs[model].append(np.array(rows))
            ent.append(pts.entropy)
            sc.append(np.full(len(cand), di))
            used.append({"dataset": str(d), "spec": gt.get("spec", ""), "image": s.name, "seed": gt.get("seed"),
                         "seeds": gt.get("seeds", {}), "points": int(len(cand))})
    if not ent:
        raise InputError(f"datasets {', '.join(map(str, dataset_dirs))}: no target image with scored edge points; "
                         "render target images (e.g. `edgetruth render thresholds`)")
    return (WindowErrors(np.concatenate(ent), {m: np.concatenate(v, axis=1) for m, v in errs.items()},
                         np.concatenate(sc), total), used)


def image_seed_keys(gt_or_record: dict) -> set:
    """The seeds that make an image: the pose's, the Monte-Carlo render's and the sensor noise's."""
    s = gt_or_record.get("seeds") or {}
    keys = set()
    for k in ("pose_rng", "sensor_rng"):
        if s.get(k) is not None:
            keys.add((k, tuple(s[k]) if isinstance(s[k], (list, tuple)) else s[k]))
    if s.get("mitsuba") is not None:
        keys.add(("mitsuba", s["mitsuba"]))
    return keys


def check_disjoint(thresholds_path, samples) -> None:
    """Refuse to evaluate render-calibrated thresholds on an image rendered from the seeds they
    were calibrated on (calibration data must be disjoint from test data)."""
    if thresholds_path is None:
        return
    try:
        data = json.loads(open(thresholds_path).read())
    except (OSError, ValueError):
        return  # thresholds.load reports an unreadable file
    images = (data.get("provenance", {}).get("data", {}) or {}).get("images") or []
    cal = set()
    for r in images:
        cal |= image_seed_keys(r)
    if not cal:
        return
    for name, gt in samples:
        if image_seed_keys(gt) & cal:
            raise InputError(f"thresholds file {thresholds_path}: image {name} was rendered from seeds its thresholds "
                             "were calibrated on; calibrate on images of another spec (calibration and test data "
                             "must be disjoint)")


def grid_search(entropy: np.ndarray, errors: np.ndarray, step: float = 0.01):
    """Best (tau1, tau2, tau3) on a grid; errors (4, N) for windows 5, 7, 9, 11.

    Returns (tau, rmse, table) where table holds the RMSE of every triple."""
    if not (0 < step <= 0.25):
        raise InputError(f"step={step}: must be in (0, 0.25]")
    h = np.where(np.isfinite(entropy), entropy, 1.0)
    order = np.argsort(h, kind="stable")
    hs = h[order]
    e2 = errors[:, order] ** 2
    cum = np.concatenate([np.zeros((4, 1)), np.cumsum(e2, axis=1)], axis=1)  # cum[:, i] = sum of first i
    grid = np.round(np.arange(0.0, 1.0 + step / 2, step), 10)
    idx = np.searchsorted(hs, grid, side="left")  # points with H < tau
    i1, i2, i3 = np.meshgrid(np.arange(grid.size), np.arange(grid.size), np.arange(grid.size), indexing="ij")
    valid = (i1 <= i2) & (i2 <= i3)
    a, b, c = idx[i1[valid]], idx[i2[valid]], idx[i3[valid]]
    n = hs.size
    sse = cum[0, a] + (cum[1, b] - cum[1, a]) + (cum[2, c] - cum[2, b]) + (cum[3, n] - cum[3, c])
    rmse = np.sqrt(sse / n)
    best = rmse.min()
    ties = np.flatnonzero(rmse <= best * (1 + 1e-12))
    t_all = np.stack([grid[i1[valid]], grid[i2[valid]], grid[i3[valid]]], axis=1)
    centre = t_all[ties].mean(axis=0)
    pick = ties[np.argmin(np.sum((t_all[ties] - centre) ** 2, axis=1))]
    return tuple(float(v) for v in t_all[pick]), float(rmse[pick]), (t_all, rmse)


def window_shares(entropy, tau) -> dict:
    h = np.where(np.isfinite(entropy), entropy, 1.0)
    w = np.select([h < tau[0], h < tau[1], h < tau[2]], [5, 7, 9], 11)
    return {int(k): float(np.mean(w == k)) for k in WINDOWS}


def calibrate(images_per_scenario: int = 100, step: float = 0.01, shape=DEFAULT_SHAPE, progress=None) -> dict:
    """Run the calibration; returns the JSON-ready record (thresholds + provenance)."""
    if images_per_scenario < 1:
        raise InputError(f"images_per_scenario={images_per_scenario}: must be >= 1")
    data = collect("calibration", images_per_scenario, shape, progress=progress)
    return {
        "models": _fit(data, step),
        "provenance": {
            "data": {
                "split": "calibration",
                "scenarios": list(SCENARIOS),
                "images_per_scenario": images_per_scenario,
                "image_shape": list(shape),
                "seeds": "numpy SeedSequence([1, scenario_index, image_index]); test splits use [2, ...]",
                "on_edge_points": int(data.entropy.size),
                "generator": "edgetruth.render.synthetic.scenarios.synthetic_image (lines and circles alternate)",
            },
            "objective": "minimise RMSE (px) of the dynamic-window ERF positions over all on-edge candidates "
                         "(|candidate distance to the true edge| <= 1.5 px), all scenarios pooled",
            "search": f"exhaustive grid, step {step}, 0 <= tau1 <= tau2 <= tau3 <= 1; ties -> the centre of the optimal set",
            "code_version": {"edgetruth": __version__, "git_commit": source_commit()},
            "created_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
            "command": f"edgetruth calibrate-thresholds --images-per-scenario {images_per_scenario} --step {step}",
        },
    }


def _fit(data: WindowErrors, step: float) -> dict:
    models = {}
    for model, errs in data.errors.items():
        tau, rmse, _ = grid_search(data.entropy, errs, step)
        fixed = {int(w): float(np.sqrt(np.mean(errs[k] ** 2))) for k, w in enumerate(WINDOWS)}
        models[model] = {"tau": list(tau), "rmse_px": rmse, "fixed_window_rmse_px": fixed,
                         "window_shares": window_shares(data.entropy, tau)}
    return models


def calibrate_renders(dataset_dirs, step: float = 0.01, progress=None, names=None) -> dict:
    """Thresholds for the camera of rendered datasets, from their per-point truth (JSON-ready record);
    ``names``: only these images (default: every target image)."""
    data, used = collect_renders(dataset_dirs, progress, None if names is None else set(names))
    cams = {}
    for d in dataset_dirs:
        for s in open_dataset(d).targets():
            c = s.truth["camera"]
            cams[c.get("name", "")] = {k: c.get(k) for k in ("name", "width_px", "height_px", "pitch_um",
                                                             "focal_length_mm", "f_number", "focus_distance_m")}
            break
    return {
        "models": _fit(data, step),
        "provenance": {
            "data": {
                "kind": "renders",
                "datasets": [str(d) for d in dataset_dirs],
                "specs": sorted({u["spec"] for u in used}),
                "camera": list(cams.values()),
                "target_images": data.images,
                "images_with_points": len(used),
                "on_edge_points": int(data.entropy.size),
                "images": used,
                "seeds": "each image's own (pose, Monte-Carlo, sensor) seeds, listed under images; evaluating these "
                         "thresholds on an image with any of them is refused (check_disjoint)",
                "rule": f"raw-image Canny boundary candidates within {MATCH_RADIUS_PX} px of the exact distorted "
                        f"outline, squares' candidates farther than {CORNER_EXCLUSION_PX:g} px from a corner",
            },
            "objective": "minimise RMSE (px) of the dynamic-window ERF positions over the scored points, pooled",
            "search": f"exhaustive grid, step {step}, 0 <= tau1 <= tau2 <= tau3 <= 1; ties -> the centre of the optimal set",
            "code_version": {"edgetruth": __version__, "git_commit": source_commit()},
            "created_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
            "command": "edgetruth calibrate-thresholds --dataset " + " ".join(str(d) for d in dataset_dirs),
        },
    }


def write(record: dict, path) -> None:
    write_json(path, record, indent=2)
