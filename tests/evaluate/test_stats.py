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
