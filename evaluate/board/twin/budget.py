"""The twin's error budget: what each rendered term gives the twin's straightness and calibration RMS (issue 47).

``edgetruth study twin SET -o DIR --budget`` renders, beside the twin, one copy of its scene per term that the
twin renders, with that term switched off and nothing else changed (the same spec name, so the same seeds, poses
and Monte-Carlo samples: only the term differs), and runs the same board study on each.  The terms (``TERMS``,
registered by name) are the physics the twin's scene carries, each measured on the photos by ``edgetruth twin``
(``twin.derive``, docs/board.md) and never by the figures judged here:

- ``noise``: the sensor's temporal noise (shot noise, read noise, the video chain's output noise);
- ``fpn``: fixed-pattern noise (DSNU, PRNU, hot and dead pixels);
- ``jpeg``: the JPEG coding (the same 8-bit tone curve, stored losslessly);
- ``sharpening``: the camera's unsharp mask;
- ``clip``: the white's clip below 255 (saturated photos);
- ``bend``: the boards' curl (``board_bend_mm``);
- ``lens_shading``: the lens's relative illumination beyond the thin lens's own falloff.

For a figure F (a method's straightness or calibration RMS, or their median over the methods), F_all the twin's
with every term on and F_off the twin's without one term, the term's share is ``sign · √|F_all² − F_off²|`` (px):
independent error sources add in quadrature, so the shares of independent terms add up to the twin's F² less what
remains with none of them (its floor: the edge method's own error on a clean image, the lens's bow of a side).  A
term that interacts with another (JPEG on noise) has a share that is not additive; the table says what is
measured.  The *unexplained* line is ``sign · √|F_real² − F_all²|``: what the photos show beyond the twin.
"""
from __future__ import annotations

import copy
import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import cv2
import numpy as np

from edgetruth.evaluate.report_format import num, table
from edgetruth.evaluate.residual_field import board_point_transfer, image_field_transfer
from edgetruth.fileio import atomic_write_text, read_toml, write_json
from edgetruth.render.dataset.spec import resolve_spec_path
from edgetruth.render.optics.camera import resolve_camera_path

#: the scene with every term off at once (the twin's floor), beside one scene per term
ALL_OFF = "all_off"
#: the twin under other seeds: ``seed2``, ``seed3``, ... (the interval of its figures)
SEED_PREFIX = "seed"
#: the twin's renders the budget has in all (its own and seed copies)
BUDGET_SEEDS = 3
#: the board-study figures the budget splits
FIGURES = {"straightness_px": "straightness", "calib_rms_px": "calibration RMS"}

_NOISE_KEYS = ("dark_noise_e", "output_noise_dn")
_FPN_KEYS = ("dsnu_e", "prnu_pct", "hot_pixel_fraction", "dead_pixel_fraction")


def _sensors(spec: dict) -> list[dict]:
    """The spec's [sensor] table and every group's ``sensor = {...}`` override (made where missing only for
    [sensor]): the tables a term edits."""
    spec.setdefault("sensor", {})
    return [spec["sensor"]] + [g["sensor"] for g in spec.get("group", []) if isinstance(g.get("sensor"), dict)]


def _any(spec: dict, key: str, test) -> bool:
    return any(key in t and test(t[key]) for t in _sensors(spec))


@dataclass(frozen=True)
class Term:
    """A rendered term of the twin: whether a scene renders it, and the same scene with it off (in place)."""

    name: str
    what: str
    present: Callable[[dict, dict], bool]  # (spec TOML, camera TOML) -> the scene renders the term
    switch_off: Callable[[dict, dict], None]  # edits (spec TOML, camera TOML) in place


def _noise_present(spec, cam) -> bool:
    base = spec.get("sensor", {})
    on = bool(base.get("shot_noise", True)) or base.get("dark_noise_e", 10.0) > 0  # 10 e-: the sensor's default
    return on or _any(spec, "dark_noise_e", lambda v: v > 0) or _any(spec, "output_noise_dn", lambda v: v > 0)


def _noise_off(spec, cam) -> None:
    for t in _sensors(spec):
        for k in _NOISE_KEYS:
            t.pop(k, None)
    spec["sensor"].update({"shot_noise": False, "dark_noise_e": 0.0, "output_noise_dn": 0.0})


def _jpeg_off(spec, cam) -> None:
    for t in _sensors(spec):
        if t.get("output") == "jpeg":
            t["output"] = "srgb8"
            t.pop("jpeg_quality", None)


def _drop(spec, keys) -> None:
    for t in _sensors(spec):
        for k in keys:
            t.pop(k, None)


def _bend_off(spec, cam) -> None:
    for g in spec.get("group", []):
        g.pop("board_bend_mm", None)


def _shading_off(spec, cam) -> None:
    table = cam.get("camera", cam)
    table.pop("shading_a2", None)
    table.pop("shading_a4", None)


def _cam_table(cam: dict) -> dict:
    return cam.get("camera", cam)


#: the terms, by name (the order of the budget table)
TERMS: dict[str, Term] = {t.name: t for t in (
    Term("noise", "temporal noise (shot, read, output)", _noise_present, _noise_off),
    Term("fpn", "fixed-pattern noise (DSNU, PRNU, hot and dead pixels)",
         lambda s, c: any(_any(s, k, lambda v: v > 0) for k in _FPN_KEYS), lambda s, c: _drop(s, _FPN_KEYS)),
    Term("jpeg", "JPEG coding", lambda s, c: _any(s, "output", lambda v: v == "jpeg"), _jpeg_off),
    Term("sharpening", "the camera's sharpening", lambda s, c: _any(s, "sharpen_amount", lambda v: v > 0),
         lambda s, c: _drop(s, ("sharpen_amount",))),
    Term("clip", "the white's clip below 255", lambda s, c: _any(s, "output_clip_dn", lambda v: v < 255),
         lambda s, c: _drop(s, ("output_clip_dn",))),
    Term("bend", "the boards' curl", lambda s, c: any("board_bend_mm" in g for g in s.get("group", [])), _bend_off),
    Term("lens_shading", "lens shading (relative illumination)",
         lambda s, c: any(_cam_table(c).get(k, 0.0) != 0.0 for k in ("shading_a2", "shading_a4")), _shading_off),
)}


def _absolute_refs(spec: dict, folder: Path) -> None:
    """Paths the scene names relative to its own folder (a square board's model file), made absolute: the
    budget's copies live elsewhere."""
    sq = spec.get("spec", {}).get("squares")
    if isinstance(sq, dict) and isinstance(sq.get("model"), str):
        ref = sq["model"]
        if "/" in ref or "\\" in ref or Path(ref).suffix:
            sq["model"] = str((folder / ref).resolve())


def term_scenes(spec_ref: str | Path, out_dir: Path, names=None, spp: int | None = None,
                seeds: int = 1) -> dict[str, Path]:
    """Write, for each term the scene ``spec_ref`` renders (or each of ``names``), its copy with that term off:
    ``out_dir/<term>/twin.toml`` and its ``camera.toml``; returns {term: spec path}.  The copies keep the spec's
    name (its seeds) and every other key; ``spp``: the twin's samples per pixel when the study overrides them.
    ``seeds`` > 1: also the twin itself under ``seeds - 1`` other names (``seed2``, ...: other seeds for the
    Monte-Carlo samples and the sensor's noise, the same poses), for the interval of its figures."""
    import tomli_w  # lazy: only the budget writes TOML

    path = resolve_spec_path(spec_ref)
    spec = read_toml(path)
    cam_path = resolve_camera_path(str(spec["spec"].get("camera", "default")), path.parent)
    cam = read_toml(cam_path)
    _absolute_refs(spec, path.parent)
    terms = [t for name, t in TERMS.items() if (names is None or name in names) and t.present(spec, cam)]
    cases = [(t.name, [t]) for t in terms] + ([(ALL_OFF, terms)] if len(terms) > 1 else [])
    cases += [(f"{SEED_PREFIX}{k}", []) for k in range(2, seeds + 1)]
    out = {}
    for name, off in cases:
        s, c = copy.deepcopy(spec), copy.deepcopy(cam)
        for term in off:
            term.switch_off(s, c)
        if not off:  # a seed copy: the name seeds every image (its poses are the scene's own)
            s["spec"]["name"] = f"{s['spec'].get('name') or path.stem}_{name}"
        if spp is not None:
            s["spec"]["spp"] = int(spp)
        folder = out_dir / name
        folder.mkdir(parents=True, exist_ok=True)
        atomic_write_text(folder / "camera.toml", tomli_w.dumps(c))
        s["spec"]["camera"] = str((folder / "camera.toml").resolve())
        what = f"with {'; '.join(t.what for t in off)} off" if off else f"under other seeds ({name})"
        atomic_write_text(folder / "twin.toml", f"# {spec_ref} {what} (edgetruth study twin --budget)\n"
                          + tomli_w.dumps(s))
        out[name] = folder / "twin.toml"
    return out


def signed_root(d: float) -> float:
    """``sign(d) · √|d|``: a difference of squares back in px."""
    return math.copysign(math.sqrt(abs(d)), d) if np.isfinite(d) else float("nan")


def share_px(all_px: float, off_px: float) -> float:
    """A term's share of a figure, ``sign(all² − off²) · √|all² − off²|`` (px)."""
    return signed_root(all_px * all_px - off_px * off_px)


def medians(summaries: dict, methods: list[str]) -> dict:
    """The median over ``methods`` of each budget figure of a run's summaries {row: summary}."""
    return {k: float(np.nanmedian([summaries[m].get(k, np.nan) for m in methods if m in summaries] or [np.nan]))
            for k in FIGURES}


def budget_rows(real: dict, twin: dict, off: dict[str, dict], methods: list[str]) -> list[dict]:
    """The budget's rows: per figure and row (the real photos, the twin with every term on, the twin without each
    term, the unexplained rest) the median over the methods and the twin ÷ real ratio; per method the same
    figures for ``budget.csv``.  ``real``, ``twin`` and each ``off[term]`` are summaries by row."""
    rm, tm = medians(real, methods), medians(twin, methods)
    rows = [{"row": "real photos", "term": "", **{f"{k}": rm[k] for k in FIGURES}},
            {"row": "twin, every term on", "term": "all", **{k: tm[k] for k in FIGURES}}]
    seeds = [medians(s, methods) for name, s in off.items() if name.startswith(SEED_PREFIX)]
    if seeds:  # the twin's figure under its own seeds and the copies': its spread from noise and samples alone
        vals = {k: [tm[k]] + [m[k] for m in seeds] for k in FIGURES}
        rows.append({"row": f"twin, every term on: range over {len(seeds) + 1} seeds", "term": "seeds",
                     **{f"range_{k}": [float(np.min(v)), float(np.max(v))] for k, v in vals.items()},
                     **{f"real_inside_{k}": bool(np.min(v) <= rm[k] <= np.max(v)) for k, v in vals.items()}})
    shares = {k: [] for k in FIGURES}
    for name, s in off.items():
        if name == ALL_OFF or name.startswith(SEED_PREFIX):
            continue
        om = medians(s, methods)
        rows.append({"row": f"twin without {TERMS[name].what}", "term": name, **{k: om[k] for k in FIGURES},
                     **{f"share_{k}": share_px(tm[k], om[k]) for k in FIGURES}})
        for k in FIGURES:
            shares[k].append(rows[-1][f"share_{k}"])
    if ALL_OFF in off:  # the floor, and what the terms' shares leave of the twin's figure (their interaction)
        fm = medians(off[ALL_OFF], methods)
        rows.append({"row": "twin, every term off (its floor)", "term": ALL_OFF, **{k: fm[k] for k in FIGURES},
                     **{f"share_{k}": share_px(tm[k], fm[k]) for k in FIGURES}})
        # what the shares leave of the twin above its floor: 0 where the terms add in quadrature
        rows.append({"row": "the twin above its floor, less the shares in quadrature (the terms' interaction)",
                     "term": "interaction", **{f"share_{k}": signed_root(
                         tm[k] ** 2 - fm[k] ** 2 - sum(math.copysign(v * v, v) for v in shares[k] if np.isfinite(v)))
                         for k in FIGURES}})
    rows.append({"row": "unexplained (real beyond the twin)", "term": "unexplained",
                 **{f"share_{k}": share_px(rm[k], tm[k]) for k in FIGURES}})
    for r in rows:
        for k in FIGURES:
            r[f"ratio_{k}"] = r[k] / rm[k] if k in r and rm[k] else float("nan")
    return rows


def per_method_rows(real: dict, twin: dict, off: dict[str, dict], methods: list[str]) -> list[dict]:
    """One row per (method, term): the figures with the term off and its share (``budget.csv``; a seed copy's
    "share" is its difference in quadrature from the twin's own seed)."""
    out = []
    for m in methods:
        base = {"method": m, **{f"real_{k}": real.get(m, {}).get(k, np.nan) for k in FIGURES},
                **{f"twin_{k}": twin.get(m, {}).get(k, np.nan) for k in FIGURES}}
        for name, s in off.items():
            row = dict(base, term=name)  # all_off: the floor, its "share" the twin above it
            for k in FIGURES:
                v = s.get(m, {}).get(k, np.nan)
                row[f"off_{k}"] = v
                row[f"share_{k}"] = share_px(base[f"twin_{k}"], v)
            out.append(row)
    return out


def budget_section(rows: list[dict], n_methods: int, photos: dict[str, int],
                   first: str = "straightness") -> list[str]:
    """Markdown lines of the budget table (``write_budget``); ``first``: what the first figure is (a circle grid's:
    the ellipse residual, ``circle_figures``)."""
    body = []
    for r in rows:
        cells = [r["row"]]
        for k in FIGURES:
            lo_hi = r.get(f"range_{k}")
            value = f"{lo_hi[0]:.3f}–{lo_hi[1]:.3f}" if lo_hi else num(r.get(k), 3)
            inside = {True: "real inside", False: "real outside"}.get(r.get(f"real_inside_{k}"))
            cells += [value, inside or num(r.get(f"ratio_{k}"), 2), num(r.get(f"share_{k}"), 3)]
        cells.append(str(photos.get(r["term"], "")))
        body.append(cells)
    head = ["", f"{first} (px)", "÷ real", "share (px)", "calib RMS (px)", "÷ real", "share (px)", "photos"]
    return ["## Error budget", "",
            f"Median over the {n_methods} ranked methods of each figure; the twin rendered again with one term off at "
            "a time (the same seeds, poses and samples: only the term differs; `budget/<term>/twin.toml`).  A term's "
            "share is sign · √|F_all² − F_off²|, the unexplained line sign · √|F_real² − F_all²| "
            "(docs/board.md, 'Error budget'); per method: `budget.csv`.", "",
            table(head, body), ""]


def measured_terms(run, method: str) -> dict | None:
    """Where the photos' calibration residual lives, for ``method``'s row of the board study ``run``
    (``residual_field``: the print, each board point's own offset, and a lens field fixed in the image, each
    photo held out), with what each is in pixels (√share · RMS); None without that row's calibration."""
    row = next((r for r in run.rows if r.label == method and r.cal is not None), None)
    if row is None:
        return None
    cal, obj = row.cal, np.asarray(run.inp.model.corners, float)
    board, image, res = [], [], []
    for corners, rv, tv in zip(row.corners, cal.rvecs, cal.tvecs):
        c = np.asarray(corners, float)
        ok = np.all(np.isfinite(c), axis=2)
        xy, uv = obj[ok], c[ok]
        proj, _ = cv2.projectPoints(np.c_[xy, np.zeros(len(xy))], rv, tv, cal.K, cal.dist)
        board.append(xy)
        image.append(uv)
        res.append(uv - proj.reshape(-1, 2))
    e = np.concatenate(res)
    rms = float(np.sqrt(np.mean(np.sum(e * e, axis=1))))
    out = {"method": method, "calib_rms_px": rms, **board_point_transfer(board, res, cal.K, cal.dist, cal.rvecs,
                                                                          cal.tvecs),
           **image_field_transfer(image, res, run.size)}
    for key in ("print", "image_field"):
        if f"{key}_share" in out:
            out[f"{key}_px"] = math.sqrt(max(out[f"{key}_share"], 0.0)) * rms
    return out


def measured_lines(m: dict | None) -> list[str]:
    """The report's lines for ``measured_terms``."""
    if not m or "print_share" not in m:
        return []
    return ["Measured on the photos, not rendered (docs/board.md, 'Where the calibration residual lives'; "
            f"{m['method']}'s calibration, RMS {m['calib_rms_px']:.3f} px, each photo held out): **the print** (each "
            f"board point's own offset, the same in every photo) predicts {100 * m['print_share']:.0f} % of the "
            f"residual energy (shuffled: {100 * m['print_null_median']:.0f} %, p {m['print_p_value']:.3f}; "
            f"≈ {m['print_px']:.3f} px), **a lens field** fixed in the image "
            f"{100 * m.get('image_field_share', float('nan')):.0f} % (shuffled: "
            f"{100 * m.get('image_field_null_median', float('nan')):.0f} %; ≈ {m.get('image_field_px', float('nan')):.3f}"
            " px).", ""]


def circle_figures(summaries: list[dict]) -> dict:
    """A circle-grid study's summaries as the budget's figures {row: {figure: value}}: the ellipse residual (the
    circle grid's straightness) in the first figure's place, the calibration RMS as it is."""
    return {s["row"]: {"straightness_px": s.get("ellipse_rms_px", np.nan), "calib_rms_px": s.get("calib_rms_px",
                                                                                                  np.nan)}
            for s in summaries}


def write_budget(out: Path, rows: list[dict], method_rows: list[dict], n_methods: int,
                 photos: dict[str, int], measured: dict | None = None, first: str = "straightness") -> list[str]:
    """Write ``budget.json`` and ``budget.csv`` into ``out``; return the report's lines (with ``measured_terms``'
    when given; ``first``: the first figure's name)."""
    write_json(out / "budget.json", {"rows": rows, "per_method": method_rows, "photos": photos,
                                     "measured_on_photos": measured})
    buf = io.StringIO()
    if method_rows:
        w = csv.DictWriter(buf, fieldnames=list(method_rows[0]))
        w.writeheader()
        w.writerows(method_rows)
    atomic_write_text(out / "budget.csv", buf.getvalue())
    return budget_section(rows, n_methods, photos, first) + measured_lines(measured)
