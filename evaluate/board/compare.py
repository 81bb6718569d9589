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
"""
from __future__ import annotations

import numpy as np

from edgetruth.evaluate import stats
from edgetruth.evaluate.board.measure import Row
from edgetruth.evaluate.board.summary import bootstrap_indices

FAMILIES = ("straightness", "reprojection", "loo", "side_length")
FAMILY_LABELS = {"straightness": "straightness per side (px)",
                 "reprojection": "|reprojection residual| per corner (px)",
                 "loo": "|leave-one-image-out residual| per corner (px)",
                 "side_length": "|side length error| per side (board units)"}


def family_values(row: Row, family: str) -> np.ndarray | None:
    """The row's value on every unit of ``family`` (flat, NaN where missing), None when it has none."""
    if family == "straightness":
        return np.concatenate([f.rms_px.ravel() for f in row.sides]) if row.is_method else None
    if row.cal is None:
        return None
    if family == "reprojection":
        return np.concatenate([r.ravel() for r in row.cal.residual_px])
    if family == "loo":
        return np.concatenate([r.ravel() for r in row.loo["residual_px"]])
    if family == "side_length":
        return np.abs(np.concatenate([e.ravel() for e in row.lengths["error"]]))
    raise ValueError(family)


def mean_difference_ci(a: np.ndarray, b: np.ndarray, alpha: float = 0.05) -> tuple[float, float]:
    d = np.asarray(a, float) - np.asarray(b, float)
    if d.size < 2:
        return float("nan"), float("nan")
    i = bootstrap_indices(d.size)
    lo, hi = np.percentile(d[i].mean(axis=1), [100 * alpha / 2, 100 * (1 - alpha / 2)])
    return float(lo), float(hi)


def baseline_of(labels: list[str]) -> str:
    return "dynamic_erf_4p" if "dynamic_erf_4p" in labels else labels[0]


def compare_family(rows: list[Row], family: str, baseline: str, alpha: float = 0.05) -> dict:
    """{'family', 'rows', 'n_units', 'friedman', 'tests': [...]} for the rows that have the family's values."""
    vals = {r.label: v for r in rows if (v := family_values(r, family)) is not None}
    labels = list(vals)
    out = {"family": family, "label": FAMILY_LABELS[family], "rows": labels, "baseline": baseline, "tests": []}
    if not labels or baseline not in vals:
        out.update(n_units=0, friedman=stats.friedman(np.zeros((0, 0))))
        return out
    m = np.stack([vals[k] for k in labels], axis=1)
    common = np.all(np.isfinite(m), axis=1)
    m = m[common]
    out["n_units"] = int(m.shape[0])
    out["friedman"] = stats.friedman(m)
    b = m[:, labels.index(baseline)]
    tests = []
    for j, lab in enumerate(labels):
        if lab == baseline:
            continue
        w = stats.wilcoxon_paired(m[:, j], b, alpha)
        tests.append({"row": lab, "n_pairs": w["n_pairs"], "mean_row": float(m[:, j].mean()) if m.size else np.nan,
                      "mean_baseline": float(b.mean()) if m.size else np.nan,
                      "median_difference": w["median_difference"],
                      "mean_difference_ci": mean_difference_ci(m[:, j], b), "p_value": w["p_value"],
                      "rank_biserial": stats.rank_biserial(m[:, j], b)})
    for t, p in zip(tests, stats.holm([t["p_value"] for t in tests]) if tests else []):
        t["p_holm"] = float(p)
        t["significant"] = bool(p < alpha)
    out["tests"] = tests
    return out


def compare_all(rows: list[Row], alpha: float = 0.05) -> list[dict]:
    methods = [r.label for r in rows if r.is_method]
    if not methods:
        return []
    base = baseline_of(methods)
    return [compare_family(rows, f, base, alpha) for f in FAMILIES]
