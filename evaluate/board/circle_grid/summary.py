"""Per-row figures of the circle-grid study, its paired-test families and its per-circle table.

- **ellipse residual** (the circle analogue of straightness; method rows): each circle's edge points, undistorted
  with the row's own calibration, against the ellipse fitted to them (``circles.CircleEdges.ellipse_residuals``):
  the first-order geometric distance, RMS pooled over every fitted point of every circle of every photo, with
  percentile bootstrap CIs resampling circles and resampling photos; also the median circle's RMS and the share of
  the points the fit kept (those within ``circles.OUTLIER_PX`` of the first fit);
- calibration RMS (OpenCV's) and the leave-one-image-out RMS, each with CIs resampling circles and photos (the
  calibration held fixed), as the board study's (``measure.summary``);
- intrinsics (OpenCV's 5-term lens) and each row's centres against OpenCV's blob centroids (mean distance, px).
"""
from __future__ import annotations

import numpy as np

from edgetruth.evaluate.board.circle_grid.rows import REFERENCE_LABEL, REFERENCE_ROW, CircleRow
from edgetruth.evaluate.board.measure.summary import photo_squares, pooled_rms_ci, rms_ci, rms_ci_by_photo
from edgetruth.evaluate import method_order as mo

#: the families of paired tests (``measure.compare``) a circle grid's rows have
FAMILIES = ("ellipse_residual", "reprojection", "loo")
#: the families' names in the report (a circle grid's units are circles)
FAMILY_LABELS = {"ellipse_residual": "ellipse residual per circle: RMS distance of its points from their own ellipse "
                                     "(px)",
                 "reprojection": "|reprojection residual| per circle (px)",
                 "loo": "|leave-one-image-out residual| per circle (px)"}
LENS = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")
NAN2 = (float("nan"), float("nan"))


def per_photo(row: CircleRow, family: str) -> list | None:
    """The row's values of ``family`` (``FAMILIES``), one array per photo (per circle), None when it has none."""
    if family == "ellipse_residual":
        return [e["rms_px"] for e in row.ellipse] if row.ellipse is not None else None
    if row.cal is None:
        return None
    if family == "reprojection":
        return list(row.cal["residual_px"])
    if family == "loo":
        return list(row.loo["residual_px"])
    raise ValueError(family)


def label_of(row: str) -> str:
    """The row's label in tables: the method's, or the reference's."""
    return REFERENCE_LABEL if row == REFERENCE_ROW else mo.label(row)


def _flat(arrs) -> np.ndarray:
    return np.concatenate([np.asarray(a, float).ravel() for a in arrs]) if arrs else np.zeros(0)


def circle_summary(row: CircleRow, blobs: list) -> dict:
    """The figures of one row (module docstring); ``blobs``: per photo OpenCV's centroids (n, 2).  NaN where a figure
    does not apply."""
    out: dict = {"row": row.label, "label": label_of(row.label), "failure": row.failure,
                 "ellipse_rms_px": float("nan"), "ellipse_ci": NAN2, "ellipse_ci_photos": NAN2,
                 "ellipse_median_px": float("nan"), "circles_fitted": 0, "circles_total": 0,
                 "points_per_circle": float("nan"), "fit_kept_fraction": float("nan"),
                 "converged_fraction": float("nan"), "refine_s": float("nan"), "rounds": row.rounds,
                 "moved_px": row.moved_px}
    if row.is_method:
        out.update(converged_fraction=row.converged / row.candidates if row.candidates else float("nan"),
                   refine_s=row.refine_s, circles_total=int(sum(len(b) for b in blobs)))
    if row.ellipse is not None:
        rms, n = _flat([e["rms_px"] for e in row.ellipse]), _flat([e["n_fit"] for e in row.ellipse])
        value, ci = pooled_rms_ci(rms, n)
        ok = [np.isfinite(e["rms_px"]) & (e["n_fit"] > 0) for e in row.ellipse]
        ci_photos = rms_ci_by_photo([np.sum(e["rms_px"][k] ** 2 * e["n_fit"][k]) for e, k in zip(row.ellipse, ok)],
                                    [np.sum(e["n_fit"][k]) for e, k in zip(row.ellipse, ok)])
        fitted = np.isfinite(rms) & (n > 0)
        n_all = _flat([e["n_points"] for e in row.ellipse])
        out.update(ellipse_rms_px=value, ellipse_ci=ci, ellipse_ci_photos=ci_photos,
                   ellipse_median_px=float(np.median(rms[fitted])) if fitted.any() else float("nan"),
                   circles_fitted=int(fitted.sum()), points_per_circle=float(n[fitted].mean()) if fitted.any()
                   else float("nan"), fit_kept_fraction=float(n.sum() / n_all.sum()) if n_all.sum() else float("nan"),
                   per_photo_ellipse_px=[_pooled(e) for e in row.ellipse])
    pts = _flat([np.all(np.isfinite(p), axis=1) for p in row.points])
    out["centres_used"], out["centres_total"] = int(pts.sum()), int(pts.size)
    d = _flat([np.linalg.norm(p - b, axis=1) for p, b in zip(row.points, blobs)])
    out["centre_vs_blobs_px"] = float(np.nanmean(d)) if np.isfinite(d).any() else float("nan")
    if row.cal is None:
        return out
    _, calib_ci = rms_ci(_flat(row.cal["residual_px"]))
    loo, loo_ci = rms_ci(_flat(row.loo["residual_px"]))
    out.update(calib_rms_px=row.cal["rms_px"], calib_rms_ci=calib_ci,
               calib_rms_ci_photos=rms_ci_by_photo(*photo_squares(row.cal["residual_px"])),
               loo_rms_px=loo, loo_rms_ci=loo_ci, loo_rms_ci_photos=rms_ci_by_photo(*photo_squares(row.loo["residual_px"])),
               loo_per_photo_px=list(row.loo["per_view_rms_px"]), calib_per_photo_px=list(row.cal["per_view_rms_px"]))
    d = np.asarray(row.cal["dist"], float).ravel()
    K = row.cal["K"]
    out.update(fx=float(K[0, 0]), fy=float(K[1, 1]), cx=float(K[0, 2]), cy=float(K[1, 2]),
               **{k: float(v) for k, v in zip(LENS[4:], d[:5])})
    return out


def _pooled(e: dict) -> float:
    ok = np.isfinite(e["rms_px"]) & (e["n_fit"] > 0)
    return float(np.sqrt(np.sum(e["rms_px"][ok] ** 2 * e["n_fit"][ok]) / e["n_fit"][ok].sum())) if ok.any() \
        else float("nan")


def per_circle_rows(rows: list[CircleRow], names: list[str]) -> list[dict]:
    """per_circle.csv: one line per (photo, circle, row): the circle's image point, its residuals under the row's
    calibration and held out, and (method rows) its points and ellipse residual.  Circles in OpenCV's order, from 0."""
    out = []
    for row in rows:
        for i, name in enumerate(names):
            p = row.points[i]
            cal = row.cal["residual_px"][i] if row.cal else np.full(len(p), np.nan)
            loo = row.loo["residual_px"][i] if row.loo else np.full(len(p), np.nan)
            e = row.ellipse[i] if row.ellipse is not None else None
            for k in range(len(p)):
                out.append({"image": name, "circle": k, "row": row.label, "x_px": _cell(p[k, 0]),
                            "y_px": _cell(p[k, 1]), "residual_px": _cell(cal[k]), "loo_residual_px": _cell(loo[k]),
                            "n_points": int(e["n_points"][k]) if e is not None else "",
                            "n_fit": int(e["n_fit"][k]) if e is not None else "",
                            "ellipse_rms_px": _cell(e["rms_px"][k]) if e is not None else ""})
    return out


def _cell(v) -> str:
    return "" if not np.isfinite(v) else repr(float(v))
