"""Paired comparisons between the rows of the board study, on the same sides and corners.

Four families, each on the units every compared row has (its common subset):

- ``straightness``: per side (photo x square x side), the RMS of its points about its line
  (methods only);
- ``reprojection``: per corner, the length of its residual under the row's own calibration;
- ``loo``: per corner, its held-out residual (calibrated without its photo);
- ``side_length``: per side, |length in the board plane - model length| (board units).

Per family: Friedman over all rows (Kendall's W as its effect size), then every row against the
baseline row (the proposed method ``dynamic_erf_4p`` when it runs, else the first method):
two-sided Wilcoxon signed-rank, Holm-adjusted within the family, the matched-pairs rank-biserial
correlation (> 0: the row's values tend to be larger than the baseline's), the median
difference and a percentile bootstrap CI (resampling units) of the mean difference.

The units are not independent: they come from a few photos, and what a photo does to an edge (its blur, tone,
palette, JPEG) it does to all of its sides and corners.  So every test also reads **by photo** (``by_photo``): the
mean difference's 95 % CI resampling photos (a cluster bootstrap: each resample draws photos and takes all their
units), how many photos' own mean differences share the overall mean's sign, and a Wilcoxon signed-rank over the
photos' mean differences (Holm-adjusted within the family; with 5 photos no two-sided p falls below 0.0625).  Where
the units' test is significant and the photos' is not, the difference is real on these photos but the photos are
too few to say it holds for others.
"""
from __future__ import annotations

import numpy as np

from edgetruth.evaluate import stats
from edgetruth.evaluate.board.measure.rows import Row
from edgetruth.evaluate.board.measure.summary import N_BOOT, SEED, bootstrap_indices, photo_resamples

FAMILIES = ("straightness", "reprojection", "loo", "side_length")
FAMILY_LABELS = {"straightness": "straightness per side (px)",
                 "ellipse_residual": "ellipse residual per circle (px)",
                 "reprojection": "|reprojection residual| per corner (px)",
                 "loo": "|leave-one-image-out residual| per corner (px)",
                 "side_length": "|side length error| per side (board units)"}


def _per_photo(row: Row, family: str) -> list[np.ndarray] | None:
    """The row's values of ``family``, one array per photo, None when it has none."""
    if family == "straightness":
        return [f.rms_px for f in row.sides] if row.is_method else None
    if row.cal is None:
        return None
    if family == "reprojection":
        return list(row.cal.residual_px)
    if family == "loo":
        return list(row.loo["residual_px"])
    if family == "side_length":
        return [np.abs(e) for e in row.lengths["error"]]
    raise ValueError(family)


def family_values(row: Row, family: str, per_photo=None) -> np.ndarray | None:
    """The row's value on every unit of ``family`` (flat, NaN where missing), None when it has none.  ``per_photo``:
    (row, family) -> the row's values per photo, or None (default: a board of squares' rows, ``_per_photo``)."""
    per = (per_photo or _per_photo)(row, family)
    return None if per is None else np.concatenate([np.asarray(v, float).ravel() for v in per])


def family_photos(row: Row, family: str, per_photo=None) -> np.ndarray | None:
    """Which photo (from 0) each of ``family_values``'s units comes from."""
    per = (per_photo or _per_photo)(row, family)
    return None if per is None else np.concatenate([np.full(np.size(v), k) for k, v in enumerate(per)])


def photo_sums(values: np.ndarray, photo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(sums, counts) of ``values`` per photo, over the photos that have units, in photo order."""
    _, inv = np.unique(np.asarray(photo), return_inverse=True)
    return np.bincount(inv, weights=np.asarray(values, float)), np.bincount(inv).astype(float)


def by_photo(d: np.ndarray, photo: np.ndarray, n_boot: int = N_BOOT, seed: int = SEED) -> dict:
    """The paired differences ``d`` (units) read by photo (module docstring): ``photo_means`` (per photo with units,
    in photo order), ``n_photos``, ``same_sign`` (photos whose mean has the sign of the overall mean; 0 when that is
    0), and ``mean_difference_ci_photos``, the 95 % percentile CI of the mean over units when photos are resampled
    (each resample's mean is Σ its photos' sums / Σ their counts)."""
    s, n = photo_sums(d, photo)
    means = s / n
    overall = float(s.sum() / n.sum()) if n.sum() else float("nan")
    out = {"photo_means": means.tolist(), "n_photos": int(s.size),
           "same_sign": int(np.sum(np.sign(means) == np.sign(overall))) if overall != 0 else 0,
           "mean_difference_ci_photos": (float("nan"), float("nan"))}
    boot = photo_resamples(s, n, n_boot, seed)
    if boot is not None:
        lo, hi = np.percentile(boot, [2.5, 97.5])
        out["mean_difference_ci_photos"] = (float(lo), float(hi))
    return out


def mean_difference_ci(a: np.ndarray, b: np.ndarray, alpha: float = 0.05) -> tuple[float, float]:
    d = np.asarray(a, float) - np.asarray(b, float)
    if d.size < 2:
        return float("nan"), float("nan")
    i = bootstrap_indices(d.size)
    lo, hi = np.percentile(d[i].mean(axis=1), [100 * alpha / 2, 100 * (1 - alpha / 2)])
    return float(lo), float(hi)


def baseline_of(labels: list[str]) -> str:
    return "dynamic_erf_4p" if "dynamic_erf_4p" in labels else labels[0]


def compare_family(rows: list[Row], family: str, baseline: str, alpha: float = 0.05, per_photo=None) -> dict:
    """{'family', 'rows', 'n_units', 'friedman', 'tests': [...]} for the rows that have the family's values
    (``per_photo`` as ``family_values``)."""
    vals = {r.label: v for r in rows if (v := family_values(r, family, per_photo)) is not None}
    labels = list(vals)
    out = {"family": family, "label": FAMILY_LABELS[family], "rows": labels, "baseline": baseline, "tests": []}
    if not labels or baseline not in vals:
        out.update(n_units=0, friedman=stats.friedman(np.zeros((0, 0))))
        return out
    m = np.stack([vals[k] for k in labels], axis=1)
    common = np.all(np.isfinite(m), axis=1)
    m = m[common]
    photo = family_photos(next(r for r in rows if r.label == baseline), family, per_photo)[common]
    out["n_units"] = int(m.shape[0])
    out["friedman"] = stats.friedman(m)
    b = m[:, labels.index(baseline)]
    tests = []
    for j, lab in enumerate(labels):
        if lab == baseline:
            continue
        w = stats.wilcoxon_paired(m[:, j], b, alpha)
        bp = by_photo(m[:, j] - b, photo)
        (s_row, n_ph), (s_base, _) = photo_sums(m[:, j], photo), photo_sums(b, photo)
        tests.append({"row": lab, "n_pairs": w["n_pairs"], "mean_row": float(m[:, j].mean()) if m.size else np.nan,
                      "mean_baseline": float(b.mean()) if m.size else np.nan,
                      "median_difference": w["median_difference"],
                      "mean_difference_ci": mean_difference_ci(m[:, j], b), "p_value": w["p_value"],
                      "rank_biserial": stats.rank_biserial(m[:, j], b),
                      "n_photos": bp["n_photos"], "photos_same_sign": bp["same_sign"],
                      "mean_difference_ci_photos": bp["mean_difference_ci_photos"],
                      "p_value_photos": stats.wilcoxon_paired(s_row / n_ph, s_base / n_ph, alpha)["p_value"]})
    for t, p in zip(tests, stats.holm([t["p_value"] for t in tests]) if tests else []):
        t["p_holm"] = float(p)
        t["significant"] = bool(p < alpha)
    for t, p in zip(tests, stats.holm([t["p_value_photos"] for t in tests]) if tests else []):
        t["p_holm_photos"] = float(p)
        t["significant_photos"] = bool(p < alpha)
    out["tests"] = tests
    return out


def compare_all(rows: list, alpha: float = 0.05, families=FAMILIES, per_photo=None) -> list[dict]:
    """Every family of ``families`` compared across ``rows`` (``compare_family``; ``per_photo`` as
    ``family_values``: a circle grid's rows give their own), against ``baseline_of`` the method rows."""
    methods = [r.label for r in rows if r.is_method]
    if not methods:
        return []
    base = baseline_of(methods)
    return [compare_family(rows, f, base, alpha, per_photo) for f in families]
