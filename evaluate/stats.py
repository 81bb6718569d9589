"""The study's statistics (BRIEF §5): one definition, used by every table.

Error summaries are of |e| (e = signed error): MAE = mean |e|, RMSE =
sqrt(mean e^2), SD = standard deviation of |e|, median, IQR (75th - 25th
percentile) and max of |e|.  Paired comparisons: Wilcoxon signed-rank
(two-sided, scipy) on per-image MAE.
"""
from __future__ import annotations

import functools
import itertools

import numpy as np
from scipy import stats as _st

SUMMARY_KEYS = ("n", "mae", "rmse", "sd", "median", "iqr", "max")


def summary(errors) -> dict:
    """The error statistics every table prints, over the finite errors.

    Parameters
    ----------
    errors : array_like
        Signed errors (px, cm, ...); NaN and inf are left out.

    Returns
    -------
    dict
        ``n``, and of abs(e): ``mae``, ``sd`` (ddof 1), ``median``, ``iqr``, ``max``; ``rmse`` of e; in the
        errors' unit (NaN when there are none).
    """
    e = np.asarray(errors, float)
    e = e[np.isfinite(e)]
    if e.size == 0:
        return {k: (0 if k == "n" else float("nan")) for k in SUMMARY_KEYS}
    a = np.abs(e)
    q1, q3 = np.percentile(a, [25, 75])
    return {"n": int(a.size), "mae": float(a.mean()), "rmse": float(np.sqrt(np.mean(e * e))),
            "sd": float(a.std(ddof=1)) if a.size > 1 else 0.0, "median": float(np.median(a)),
            "iqr": float(q3 - q1), "max": float(a.max())}


def relative_errors_pct(estimate, truth) -> np.ndarray:
    truth = np.asarray(truth, float)
    return 100.0 * np.abs(np.asarray(estimate, float) - truth) / np.abs(truth)


def wilcoxon_paired(a, b, alpha: float = 0.05) -> dict:
    """Two-sided Wilcoxon signed-rank test of paired samples (e.g. two methods' per-image MAE).

    Parameters
    ----------
    a, b : array_like
        Paired samples; pairs with a non-finite member are left out.
    alpha : float, optional
        The significance level (default 0.05).

    Returns
    -------
    dict
        ``n_pairs``, ``median_difference`` (median of a - b), ``statistic``, ``p_value``, ``significant``.
    """
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    ok = np.isfinite(a) & np.isfinite(b)
    a, b = a[ok], b[ok]
    d = a - b
    out = {"n_pairs": int(a.size), "median_difference": float(np.median(d)) if d.size else float("nan")}
    if d.size < 2 or np.all(d == 0):
        out.update(statistic=float("nan"), p_value=1.0, significant=False)
        return out
    res = _st.wilcoxon(a, b, zero_method="wilcox", alternative="two-sided")
    out.update(statistic=float(res.statistic), p_value=float(res.pvalue), significant=bool(res.pvalue < alpha))
    return out


#: up to this many pairs Spearman's p is exact (every permutation: 9! = 362,880); beyond, scipy's t approximation
SPEARMAN_EXACT_N = 9


def spearman(a, b) -> dict:
    """Spearman's ρ, its two-sided p and n over the pairs where both are finite; ρ and p NaN with fewer than 3
    pairs or a constant side.  For n <= ``SPEARMAN_EXACT_N`` p is the exact permutation p (the share of the n!
    pairings with |ρ| at least the observed; ties kept as midranks): scipy's t approximation gives p = 0 for
    three points in order, where the exact p is 1/3."""
    a, b = np.asarray(a, float).ravel(), np.asarray(b, float).ravel()
    ok = np.isfinite(a) & np.isfinite(b)
    a, b, n = a[ok], b[ok], int(ok.sum())
    if n < 3 or np.ptp(a) == 0 or np.ptp(b) == 0:
        return {"rho": float("nan"), "p": float("nan"), "n": n}
    res = _st.spearmanr(a, b)
    rho = float(res.statistic)
    if n > SPEARMAN_EXACT_N:
        return {"rho": rho, "p": float(res.pvalue), "n": n}
    ra, rb = _st.rankdata(a), _st.rankdata(b)
    ra, rb = ra - ra.mean(), rb - rb.mean()
    perms = np.array(list(itertools.permutations(range(n))), dtype=np.int8)
    r = (rb[perms] @ ra) / np.sqrt((ra @ ra) * (rb @ rb))
    p = float(np.mean(np.abs(r) >= abs(rho) - 1e-12))
    return {"rho": rho, "p": p, "n": n}


# ---- coverage and the common subset (shared by the synthetic and ranging reports) ----
#
# A method that declines a candidate answers with the candidate pixel (converged=False).  Three
# figures keep accuracy and coverage apart: *coverage*, the share of candidates a method refines;
# accuracy on the points it *refines*; accuracy on the *common subset*, the candidates every compared
# method refines (the like-with-like comparison); and the whole set with failures scored as the
# pixel centre (what a user of the method gets if they keep every point).

SUBSETS = ("refined", "common", "all")
SUBSET_LABELS = {"refined": "refined points", "common": "common subset",
                 "all": "all candidates (failures as pixel centre)"}


def coverage(converged) -> float:
    """Share of candidates a method refines."""
    c = np.asarray(converged, bool)
    return float(c.mean()) if c.size else float("nan")


def common_subset(converged: dict, methods=None) -> np.ndarray:
    """Candidates that every method in ``methods`` (default: all keys) refines."""
    methods = list(converged) if methods is None else list(methods)
    if not methods:
        raise ValueError("common_subset: no methods")
    out = np.ones(np.asarray(converged[methods[0]]).shape, bool)
    for m in methods:
        out &= np.asarray(converged[m], bool)
    return out


def subset_masks(converged, common) -> dict:
    """{'refined': converged, 'common': common, 'all': every point} for one method."""
    c = np.asarray(converged, bool)
    return {"refined": c, "common": np.asarray(common, bool), "all": np.ones(c.shape, bool)}


def subset_summaries(errors, converged, common) -> dict:
    """``summary`` of a method's errors on each of SUBSETS."""
    e = np.asarray(errors, float)
    return {k: summary(e[m]) for k, m in subset_masks(converged, common).items()}


def per_image_mae(errors, image, n_images: int, mask=None) -> np.ndarray:
    """Mean |e| per image over the points in ``mask`` (NaN for an image without such points)."""
    a = np.abs(np.asarray(errors, float))
    image = np.asarray(image, np.int64)
    if mask is not None:
        m = np.asarray(mask, bool)
        a, image = a[m], image[m]
    s = np.bincount(image, weights=a, minlength=n_images)
    c = np.bincount(image, minlength=n_images)
    with np.errstate(invalid="ignore", divide="ignore"):
        return s / c


# --- paired designs: effect sizes, multiple comparisons, bootstrap intervals -------------------------
def rank_biserial(a, b) -> float:
    """Matched-pairs rank-biserial correlation of a - b, in [-1, 1]: (W+ - W-) / (W+ + W-) over the
    non-zero differences (the Wilcoxon signed-rank test's effect size; > 0: a tends to be larger)."""
    d = np.asarray(a, float) - np.asarray(b, float)
    d = d[np.isfinite(d) & (d != 0)]
    if d.size == 0:
        return 0.0
    r = _st.rankdata(np.abs(d))
    wp, wm = r[d > 0].sum(), r[d < 0].sum()
    return float((wp - wm) / (wp + wm))


def holm(p_values) -> np.ndarray:
    """Holm–Bonferroni adjusted p-values (same order as given; family-wise error control)."""
    p = np.asarray(p_values, float)
    order = np.argsort(p)
    m = p.size
    adj = np.empty(m)
    running = 0.0
    for rank, i in enumerate(order):
        running = max(running, min(1.0, (m - rank) * p[i]))
        adj[i] = running
    return adj


def bootstrap_ci(statistic, *samples, n_boot: int = 2000, alpha: float = 0.05, seed: int = 0) -> tuple[float, float]:
    """Percentile bootstrap CI of ``statistic(*samples)``; paired samples are resampled together.

    The same indices serve every sample, so pairs stay pairs; the draws are
    ``Generator(PCG64(seed)).integers(0, n, (n_boot, n))``, the same for every report.

    Parameters
    ----------
    statistic : callable
        ``statistic(*resampled) -> float``.
    *samples : array_like
        Samples of equal length n >= 2.
    n_boot : int, optional
        Resamples (default 2000).
    alpha : float, optional
        1 - the CI's level (default 0.05: a 95 % interval).
    seed : int, optional
        The generator's seed (default 0).

    Returns
    -------
    tuple of float
        (low, high); NaN for fewer than 2 or unequal samples.
    """
    arrs = [np.asarray(s, float) for s in samples]
    n = arrs[0].size
    if n < 2 or any(a.size != n for a in arrs):
        return float("nan"), float("nan")
    idx = bootstrap_indices(n, n_boot, seed)
    vals = np.array([statistic(*(a[i] for a in arrs)) for i in idx])
    vals = vals[np.isfinite(vals)]
    if vals.size == 0:
        return float("nan"), float("nan")
    lo, hi = np.percentile(vals, [100 * alpha / 2, 100 * (1 - alpha / 2)])
    return float(lo), float(hi)


def rmse(e) -> float:
    """Root mean square of the finite values of ``e``.

    Parameters
    ----------
    e : array_like
        Signed errors.

    Returns
    -------
    float
        In the errors' unit; NaN when none is finite.
    """
    e = np.asarray(e, float)
    e = e[np.isfinite(e)]
    return float(np.sqrt(np.mean(e * e))) if e.size else float("nan")


@functools.lru_cache(maxsize=64)
def _cached_indices(k: int, n_boot: int, seed: int) -> np.ndarray:
    idx = np.random.Generator(np.random.PCG64(seed)).integers(0, k, size=(n_boot, k))
    idx.flags.writeable = False
    return idx


def bootstrap_indices(k: int, n_boot: int, seed: int) -> np.ndarray:
    """The resamples (n_boot, k) of k units: ``Generator(PCG64(seed)).integers(0, k, (n_boot, k))``, kept
    (read-only) for the small sizes a report asks for again and again (one per method and subset)."""
    if k * n_boot <= 2_000_000:
        return _cached_indices(int(k), int(n_boot), int(seed))
    return np.random.Generator(np.random.PCG64(seed)).integers(0, k, size=(n_boot, k))


def _bootstrap_rmse(sq_a: np.ndarray, sq_b: np.ndarray | None, n_boot: int, alpha: float, seed: int,
                    chunk_values: int = 4_000_000) -> tuple[float, float]:
    """Percentile bootstrap CI of RMSE(a) (- RMSE(b)) from squared errors, vectorised: the same
    resamples as ``bootstrap_ci`` (same generator, same draws), in chunks of bounded memory."""
    n = sq_a.size
    if n < 2:
        return float("nan"), float("nan")
    idx = bootstrap_indices(n, n_boot, seed)
    step = max(1, chunk_values // n)
    vals = np.empty(n_boot)
    for k in range(0, n_boot, step):
        i = idx[k:k + step]
        vals[k:k + step] = np.sqrt(sq_a[i].mean(axis=1))
        if sq_b is not None:
            vals[k:k + step] -= np.sqrt(sq_b[i].mean(axis=1))
    lo, hi = np.percentile(vals, [100 * alpha / 2, 100 * (1 - alpha / 2)])
    return float(lo), float(hi)


def rmse_ci(errors, n_boot: int = 2000, alpha: float = 0.05, seed: int = 0) -> tuple[float, float]:
    """Percentile bootstrap CI of the RMSE of ``errors`` (the finite ones; the draws of ``bootstrap_ci``).

    Parameters
    ----------
    errors : array_like
        Signed errors.
    n_boot : int, optional
        Resamples (default 2000).
    alpha : float, optional
        1 - the CI's level (default 0.05).
    seed : int, optional
        The generator's seed (default 0).

    Returns
    -------
    tuple of float
        (low, high), in the errors' unit.
    """
    e = np.asarray(errors, float)
    e = e[np.isfinite(e)]
    return _bootstrap_rmse(e * e, None, n_boot, alpha, seed)


def rmse_difference_ci(a, b, n_boot: int = 2000, alpha: float = 0.05, seed: int = 0) -> tuple[float, float]:
    """Bootstrap CI of RMSE(a) - RMSE(b) for errors paired element by element."""
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    ok = np.isfinite(a) & np.isfinite(b)
    return _bootstrap_rmse(a[ok] ** 2, b[ok] ** 2, n_boot, alpha, seed)


def friedman(blocks) -> dict:
    """Friedman test over an (n_blocks, k_levels) array of paired measurements (e.g. |error| per
    pose slot and illumination level); rows with a missing value are dropped."""
    m = np.asarray(blocks, float)
    m = m[np.all(np.isfinite(m), axis=1)] if m.ndim == 2 else m
    out = {"n_blocks": int(m.shape[0]) if m.ndim == 2 else 0, "k": int(m.shape[1]) if m.ndim == 2 else 0}
    if m.ndim != 2 or m.shape[0] < 2 or m.shape[1] < 3:
        out.update(statistic=float("nan"), p_value=float("nan"), kendall_w=float("nan"))
        return out
    res = _st.friedmanchisquare(*m.T)
    n, k = m.shape
    out.update(statistic=float(res.statistic), p_value=float(res.pvalue),
               kendall_w=float(res.statistic / (n * (k - 1))))  # effect size: Kendall's W in [0, 1]
    return out


def paired_comparisons(blocks, labels, alpha: float = 0.05) -> list[dict]:
    """Wilcoxon signed-rank between consecutive levels of a paired (n_blocks, k) design, Holm-adjusted,
    with the rank-biserial effect size and the median difference (later level minus earlier)."""
    m = np.asarray(blocks, float)
    rows = []
    for j in range(m.shape[1] - 1):
        w = wilcoxon_paired(m[:, j + 1], m[:, j], alpha)
        rows.append({"from": labels[j], "to": labels[j + 1], "n_pairs": w["n_pairs"],
                     "median_difference": w["median_difference"], "p_value": w["p_value"],
                     "rank_biserial": rank_biserial(m[:, j + 1], m[:, j])})
    adj = holm([r["p_value"] for r in rows]) if rows else []
    for r, p in zip(rows, adj):
        r["p_holm"] = float(p)
        r["significant"] = bool(p < alpha)
    return rows
