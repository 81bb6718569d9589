"""Per-row figures of the board study (one dict per method, plus the reference row) and the per-side table.

- straightness: pooled RMS = sqrt(sum of squared residuals / number of points) over every covered
  side of every photo, with a percentile bootstrap CI resampling sides; also the median side RMS;
- calibration RMS (OpenCV's) and the LOO RMS, each with a bootstrap CI resampling corners (the
  calibration held fixed: the spread of the corners' residuals, not of a re-calibration);
- each of those three CIs also resampling photos (``_ci_photos``: a cluster bootstrap, a resample draws photos
  and pools all their sides or corners), since a photo's sides and corners are not independent of each other;
- intrinsics and their differences from the set's published calibration;
- side lengths in the board plane: bias (mean error) and RMSE, in board units and in px;
- coverage: sides with at least ``sides.MIN_POINTS`` points, and the share of the candidates the
  method refined (``converged``; the candidates within ``sides.CANDIDATE_MARGIN_PX`` of a detected
  square's side, all photos);
- per photo: straightness, calibration RMS and LOO RMS;
- corners vs the set's own corners (mean distance, px) where the set has them.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from edgetruth.evaluate import method_order as mo
from edgetruth.evaluate.board.detect.chessboard import junction_split, junctions
from edgetruth.evaluate.board.measure.rows import REFERENCE_ROWS, Row
from edgetruth.evaluate.board.model import BoardModel


N_BOOT = 2000
SEED = 0
INTRINSICS = ("fx", "fy", "cx", "cy", "k1", "k2")


@lru_cache(maxsize=4)
def bootstrap_indices(n: int, n_boot: int = N_BOOT, seed: int = SEED) -> np.ndarray:
    """The bootstrap's resamples of n units (cached: every row with n units gets the same resamples, so the
    rows' intervals are paired like their values)."""
    idx = np.random.Generator(np.random.PCG64(seed)).integers(0, n, size=(n_boot, n)).astype(np.int32)
    idx.flags.writeable = False
    return idx


@lru_cache(maxsize=4)
def photo_draws(n_photos: int, n_boot: int = N_BOOT, seed: int = SEED) -> np.ndarray:
    """(n_boot, n_photos): how often each photo is drawn in each resample of the photos (cached and shared, so
    that the rows' intervals by photo are paired like their values)."""
    draws = np.random.Generator(np.random.PCG64(seed)).integers(0, n_photos, size=(n_boot, n_photos))
    counts = np.zeros((n_boot, n_photos))
    np.add.at(counts, (np.arange(n_boot)[:, None], draws), 1.0)
    counts.flags.writeable = False
    return counts


def photo_resamples(sums, counts, n_boot: int = N_BOOT, seed: int = SEED) -> np.ndarray | None:
    """Σ sums / Σ counts over the photos drawn, one per resample of the photos (``photo_draws``), from each photo's
    sum and count (photos with no count left out); None with fewer than 2 photos."""
    s, n = np.asarray(sums, float), np.asarray(counts, float)
    s, n = s[n > 0], n[n > 0]
    if n.size < 2:
        return None
    c = photo_draws(n.size, n_boot, seed)
    return (c @ s) / (c @ n)


def rms_ci_by_photo(sq_sums, counts, alpha: float = 0.05) -> tuple[float, float]:
    """The percentile CI of sqrt(Σ squares / Σ count) resampling photos (``photo_resamples``); NaN with fewer than 2
    photos."""
    boot = photo_resamples(sq_sums, counts)
    if boot is None:
        return float("nan"), float("nan")
    lo, hi = np.percentile(np.sqrt(boot), [100 * alpha / 2, 100 * (1 - alpha / 2)])
    return float(lo), float(hi)


def photo_squares(arrs) -> tuple[np.ndarray, np.ndarray]:
    """Each photo's sum of squared finite values and their count."""
    a = [np.asarray(x, float).ravel() for x in arrs]
    return (np.array([np.sum(v[np.isfinite(v)] ** 2) for v in a]),
            np.array([np.count_nonzero(np.isfinite(v)) for v in a], float))


def pooled_rms(rms: np.ndarray, n: np.ndarray) -> float:
    """sqrt(sum of squared residuals / points) of sides with per-side RMS ``rms`` over ``n`` points."""
    ok = np.isfinite(rms) & (n > 0)
    return float(np.sqrt(np.sum(rms[ok] ** 2 * n[ok]) / n[ok].sum())) if ok.any() else float("nan")


def pooled_rms_ci(rms: np.ndarray, n: np.ndarray, alpha: float = 0.05) -> tuple[float, tuple[float, float]]:
    """Pooled RMS of sides (per-side RMS ``rms`` over ``n`` points) and its bootstrap CI over sides."""
    ok = np.isfinite(rms) & (n > 0)
    ss, nn = (rms[ok] ** 2) * n[ok], n[ok].astype(float)
    if nn.size == 0:
        return float("nan"), (float("nan"), float("nan"))
    value = float(np.sqrt(ss.sum() / nn.sum()))
    if nn.size < 2:
        return value, (float("nan"), float("nan"))
    i = bootstrap_indices(nn.size)
    boots = np.sqrt(ss[i].sum(axis=1) / nn[i].sum(axis=1))
    lo, hi = np.percentile(boots, [100 * alpha / 2, 100 * (1 - alpha / 2)])
    return value, (float(lo), float(hi))


def rms_ci(residuals: np.ndarray, alpha: float = 0.05) -> tuple[float, tuple[float, float]]:
    """RMS of residual lengths (the finite ones) and its bootstrap CI over them."""
    r = np.asarray(residuals, float)
    r = r[np.isfinite(r)]
    if r.size < 2:
        return (float(np.sqrt(np.mean(r * r))) if r.size else float("nan")), (float("nan"), float("nan"))
    sq = r * r
    boots = np.sqrt(sq[bootstrap_indices(r.size)].mean(axis=1))
    lo, hi = np.percentile(boots, [100 * alpha / 2, 100 * (1 - alpha / 2)])
    return float(np.sqrt(sq.mean())), (float(lo), float(hi))


def _flat(arrs) -> np.ndarray:
    return np.concatenate([np.asarray(a, float).ravel() for a in arrs]) if arrs else np.zeros(0)


def row_summary(row: Row, model: BoardModel, reference: dict | None, reference_corners=None) -> dict:
    """The figures of one row (module docstring); NaN where they do not apply."""
    label = REFERENCE_ROWS[row.label] if row.label in REFERENCE_ROWS else _label(row.label)
    out: dict = {"row": row.label, "label": label}
    if row.is_method:
        rms = _flat([f.rms_px for f in row.sides])
        n = _flat([f.n_points for f in row.sides])
        s, ci = pooled_rms_ci(rms, n)
        covered = np.isfinite(rms)
        out["per_photo_straightness_px"] = [pooled_rms(f.rms_px.ravel(), f.n_points.ravel()) for f in row.sides]
        ok = [np.isfinite(f.rms_px) & (f.n_points > 0) for f in row.sides]
        ci_photos = rms_ci_by_photo([np.sum(f.rms_px[k] ** 2 * f.n_points[k]) for f, k in zip(row.sides, ok)],
                                    [np.sum(f.n_points[k]) for f, k in zip(row.sides, ok)])
        out.update(straightness_px=s, straightness_ci=ci, straightness_ci_photos=ci_photos,
                   straightness_median_px=float(np.nanmedian(rms))
                   if covered.any() else float("nan"), sides_covered=int(covered.sum()), sides_total=int(rms.size),
                   side_coverage=float(covered.mean()) if rms.size else float("nan"),
                   converged_fraction=row.converged / row.candidates if row.candidates else float("nan"),
                   points_per_side=float(np.mean(n[covered])) if covered.any() else float("nan"),
                   refine_s=row.refine_s)
        if model.pattern is not None:  # a chessboard: how far apart the two dark squares put a junction

            jn = junctions(model)
            split = _flat([junction_split(jn, f.corners) for f in row.sides])
            out["junction_split_px"] = float(np.nanmean(split)) if np.isfinite(split).any() else float("nan")
            out["own_corner_outward_px"] = _outward_offset(row, jn)
    else:
        out.update(straightness_px=float("nan"), straightness_ci=(float("nan"),) * 2,
                   straightness_ci_photos=(float("nan"),) * 2,
                   straightness_median_px=float("nan"), sides_covered=0, sides_total=0, side_coverage=float("nan"),
                   converged_fraction=float("nan"), points_per_side=float("nan"), refine_s=float("nan"))
    corners = _flat([np.all(np.isfinite(c), axis=2) for c in row.corners])
    out["corners_used"] = int(corners.sum())
    out["corners_total"] = int(corners.size)
    if reference_corners is not None:
        d = _flat([np.linalg.norm(c - r, axis=2) for c, r in zip(row.corners, reference_corners)])
        out["corner_vs_reference_px"] = float(np.nanmean(d)) if np.isfinite(d).any() else float("nan")
    out["failure"] = row.failure
    if row.cal is None:
        return out
    _, calib_ci = rms_ci(_flat(row.cal.residual_px))
    loo, loo_ci = rms_ci(_flat(row.loo["residual_px"]))
    out.update(calib_rms_px=row.cal.rms_px, calib_rms_ci=calib_ci,
               calib_rms_ci_photos=rms_ci_by_photo(*photo_squares(row.cal.residual_px)),
               loo_rms_px=loo, loo_rms_ci=loo_ci,
               loo_rms_ci_photos=rms_ci_by_photo(*photo_squares(row.loo["residual_px"])),
               loo_per_photo_px=list(row.loo["per_view_rms_px"]),
               calib_per_photo_px=[float(np.sqrt(np.nanmean(r ** 2))) for r in row.cal.residual_px])
    out.update(row.cal.intrinsics())
    if reference:
        for k in INTRINSICS:
            out[f"d_{k}"] = out[k] - reference[k]
    err = _flat(row.lengths["error"])
    err_px = _flat(row.lengths["error_px"])
    ok = np.isfinite(err)
    out.update(length_bias_model=float(err[ok].mean()) if ok.any() else float("nan"),
               length_rmse_model=float(np.sqrt(np.mean(err[ok] ** 2))) if ok.any() else float("nan"),
               length_bias_px=float(err_px[ok].mean()) if ok.any() else float("nan"),
               length_rmse_px=float(np.sqrt(np.mean(err_px[ok] ** 2))) if ok.any() else float("nan"),
               length_sides=int(ok.sum()))
    return out


def _outward_offset(row: Row, jn) -> float:
    """Mean signed distance (px) of each square's own corner from the junction's corner, along the direction from
    the square's centre to that corner: > 0 when its side lines put the square larger than the junctions do."""
    v = _flat(outward_offsets(row, jn))
    return float(np.nanmean(v)) if np.isfinite(v).any() else float("nan")


def outward_offsets(row: Row, jn) -> list[np.ndarray]:
    """Per photo, (J * 2,) the signed distance (px) of each square's own corner (from its own side lines) from the
    junction's corner (``row.corners``), outward from the square's centre; NaN where either is missing."""
    vals = []
    for f, c in zip(row.sides, row.corners):
        own = f.corners.reshape(-1, 2)
        with np.errstate(invalid="ignore"):
            centre = np.repeat(np.asarray(c).mean(axis=1), 4, axis=0)  # (S*4, 2) the square's centre per slot
        slot = jn.slots.ravel()
        junction = np.asarray(c).reshape(-1, 2)[slot]
        u = junction - centre[slot]
        with np.errstate(invalid="ignore", divide="ignore"):
            u /= np.linalg.norm(u, axis=1, keepdims=True)
        vals.append(((own[slot] - junction) * u).sum(axis=1))
    return vals


def _label(method_label: str) -> str:
    return mo.label(method_label)


def per_side_rows(rows: list[Row], model: BoardModel, photo_names: list[str]) -> list[dict]:
    """per_side.csv: one line per (photo, square, side, row): n_points, rms_px (methods only), the side's
    length in the board plane and its error (board units and px).  Squares/sides are numbered from 0."""
    out = []
    s_idx, k_idx = np.meshgrid(np.arange(len(model)), np.arange(4), indexing="ij")
    model_len = model.side_lengths
    for row in rows:
        for i, name in enumerate(photo_names):
            n = row.sides[i].n_points if row.is_method else np.full(model_len.shape, -1)
            rms = row.sides[i].rms_px if row.is_method else np.full(model_len.shape, np.nan)
            length = row.lengths["length"][i] if row.lengths else np.full(model_len.shape, np.nan)
            err = row.lengths["error"][i] if row.lengths else np.full(model_len.shape, np.nan)
            err_px = row.lengths["error_px"][i] if row.lengths else np.full(model_len.shape, np.nan)
            for s, k in zip(s_idx.ravel(), k_idx.ravel()):
                out.append({"image": name, "square": int(s), "side": int(k), "method": row.label,
                            "n_points": int(n[s, k]) if row.is_method else "",
                            "rms_px": _cell(rms[s, k]), "length_model": _cell(model_len[s, k]),
                            "length_measured": _cell(length[s, k]), "length_err": _cell(err[s, k]),
                            "length_err_px": _cell(err_px[s, k])})
    return out


def _cell(v) -> str:
    return "" if not np.isfinite(v) else repr(float(v))
