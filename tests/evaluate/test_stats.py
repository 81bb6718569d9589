"""Statistics are the textbook definitions."""
import numpy as np
import pytest

from edgetruth.evaluate.stats import relative_errors_pct, summary, wilcoxon_paired


def test_summary_of_known_errors():
    e = np.array([-3.0, 1.0, 2.0, -2.0, 0.0])
    s = summary(e)
    assert s["n"] == 5
    assert s["mae"] == pytest.approx(8 / 5)
    assert s["rmse"] == pytest.approx(np.sqrt(18 / 5))
    assert s["median"] == pytest.approx(2.0)
    assert s["iqr"] == pytest.approx(2.0 - 1.0)
    assert s["max"] == pytest.approx(3.0)
    assert s["sd"] == pytest.approx(np.std([3, 1, 2, 2, 0], ddof=1))


def test_summary_ignores_non_finite_and_handles_empty():
    assert summary([np.nan, 1.0])["n"] == 1
    assert np.isnan(summary([])["rmse"])


def test_relative_error():
    assert relative_errors_pct([101.0, 99.0], [100.0, 100.0]) == pytest.approx([1.0, 1.0])


def test_wilcoxon_detects_a_consistent_shift_and_not_noise():
    rng = np.random.default_rng(0)
    a = rng.uniform(0.1, 0.2, 60)
    assert wilcoxon_paired(a, a + 0.01)["significant"]
    b = a + rng.normal(0, 1e-3, 60)
    c = a + rng.normal(0, 1e-3, 60)
    assert wilcoxon_paired(b, c)["p_value"] > 0.01
    assert wilcoxon_paired(a, a)["p_value"] == 1.0


def test_holm_matches_its_definition():
    from edgetruth.evaluate.stats import holm

    p = [0.01, 0.04, 0.03, 0.005]
    # sorted: 0.005*4, 0.01*3, 0.03*2, 0.04*1 -> 0.02, 0.03, 0.06, 0.06 (monotone)
    np.testing.assert_allclose(holm(p), [0.03, 0.06, 0.06, 0.02])
    assert holm([0.9, 0.8]).max() <= 1.0


def test_rank_biserial_extremes_and_symmetry():
    from edgetruth.evaluate.stats import rank_biserial

    a = np.arange(10.0)
    assert rank_biserial(a + 1, a) == 1.0 and rank_biserial(a, a + 1) == -1.0
    rng = np.random.default_rng(0)
    x, y = rng.normal(size=50), rng.normal(size=50)
    assert rank_biserial(x, y) == pytest.approx(-rank_biserial(y, x))


def test_bootstrap_ci_covers_the_true_rmse():
    """Coverage of the 95 % percentile interval of the RMSE of N(0, 1) samples: near 95 %."""
    from edgetruth.evaluate.stats import rmse_ci

    rng = np.random.default_rng(1)
    hits = sum(lo <= 1.0 <= hi for lo, hi in (rmse_ci(rng.normal(size=200), n_boot=400, seed=k)
                                             for k in range(120)))
    assert 0.88 <= hits / 120 <= 0.99


def test_paired_difference_ci_keeps_pairs():
    """A shared per-image nuisance cancels in a paired difference: the CI is much narrower than the
    CI of either RMSE alone."""
    from edgetruth.evaluate.stats import rmse_ci, rmse_difference_ci

    rng = np.random.default_rng(2)
    common = rng.normal(0, 1.0, 300)
    a, b = common + rng.normal(0, 0.05, 300), common + rng.normal(0, 0.05, 300) + 0.02
    lo, hi = rmse_difference_ci(a, b)
    la, ha = rmse_ci(a)
    assert (hi - lo) < 0.3 * (ha - la)


def test_friedman_detects_a_monotone_effect_and_not_noise():
    from edgetruth.evaluate.stats import friedman, paired_comparisons

    rng = np.random.default_rng(3)
    base = rng.uniform(0, 1, (40, 1))
    grows = base + np.array([0.0, 0.1, 0.2, 0.3]) + rng.normal(0, 0.02, (40, 4))
    f = friedman(grows)
    assert f["p_value"] < 1e-6 and f["kendall_w"] > 0.5 and f["n_blocks"] == 40
    rows = paired_comparisons(grows, ["G1", "G2", "G3", "G4"])
    assert all(r["significant"] and r["median_difference"] > 0 and r["rank_biserial"] > 0.8 for r in rows)
    flat = base + rng.normal(0, 0.02, (40, 4))
    assert friedman(flat)["p_value"] > 0.01


def test_bootstrap_indices_are_the_generators_draws_kept_read_only():
    from edgetruth.evaluate.stats import bootstrap_indices

    for k, n_boot, seed in [(3, 2000, 0), (140, 2000, 0), (57, 500, 4), (1200, 2000, 1)]:  # the last: not kept
        want = np.random.Generator(np.random.PCG64(seed)).integers(0, k, size=(n_boot, k))
        got = bootstrap_indices(k, n_boot, seed)
        assert np.array_equal(got, want)
        again = bootstrap_indices(k, n_boot, seed)
        if k * n_boot <= 2_000_000:
            assert again is got and not got.flags.writeable  # kept, and nobody can change it for the next caller
        else:
            assert again is not got


def test_spearman_p_is_exact_for_few_pairs_and_scipys_beyond():
    """Three points in order: ρ = 1, and 2 of the 3! pairings reach |ρ| = 1, so p = 1/3 (scipy's t approximation
    says 0: a report printed 'n=3, rho=1.00, p=0.000').  Four in order: 2/24.  n <= 9 against scipy's exact
    permutation test (ties as midranks); n > 9 is scipy's own p."""
    from scipy import stats as sst

    from edgetruth.evaluate.stats import SPEARMAN_EXACT_N, spearman

    assert spearman([1, 2, 3], [5, 6, 7]) == {"rho": 1.0, "p": pytest.approx(1 / 3), "n": 3}
    assert spearman([1, 2, 3, 4], [4, 3, 2, 1])["p"] == pytest.approx(2 / 24)
    rng = np.random.default_rng(3)
    for n in (5, 7, SPEARMAN_EXACT_N):
        x, y = rng.normal(size=n), np.round(rng.normal(size=n), 0)  # y has ties
        ry = sst.rankdata(y) - sst.rankdata(y).mean()

        def rho(a, axis):  # Pearson's r of the midranks, vectorised over the pairings (n! = 362,880 at n = 9)
            ra = sst.rankdata(a, axis=axis)
            ra = ra - ra.mean(axis=axis, keepdims=True)
            return (ra @ ry) / np.sqrt((ra * ra).sum(axis=axis) * (ry @ ry))

        assert rho(x, -1) == pytest.approx(sst.spearmanr(x, y).statistic, abs=1e-12)
        want = sst.permutation_test((x,), rho, permutation_type="pairings", n_resamples=np.inf,
                                    vectorized=True).pvalue
        assert spearman(x, y)["p"] == pytest.approx(want, abs=1e-12)
    x, y = rng.normal(size=30), rng.normal(size=30)
    assert spearman(x, y)["p"] == sst.spearmanr(x, y).pvalue
    nan = spearman([1, 2, np.nan, 4], [1, 1, 5, 1])  # a constant side after the NaN pair is dropped
    assert nan["n"] == 3 and np.isnan(nan["rho"]) and np.isnan(nan["p"])
