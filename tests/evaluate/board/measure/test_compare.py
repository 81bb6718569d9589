"""The board study's paired tests (``board.compare``): over units, and by photo, since a photo's sides and corners
are not independent of each other."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from edgetruth.evaluate.board.measure import compare as cmp


def test_by_photo_is_the_cluster_bootstrap_of_the_unit_mean():
    """Photo means, the count of photos on the overall mean's side, and a CI whose every resample is Σ sums / Σ
    counts of the photos drawn (checked draw by draw against the definition)."""
    d = np.array([1.0, 1.0, 1.0, 2.0, 2.0, -1.0])
    photo = np.array([0, 0, 0, 1, 1, 2])
    out = cmp.by_photo(d, photo, n_boot=500, seed=3)
    assert out["photo_means"] == [1.0, 2.0, -1.0] and out["n_photos"] == 3 and out["same_sign"] == 2
    draws = np.random.Generator(np.random.PCG64(3)).integers(0, 3, size=(500, 3))
    boot = [np.concatenate([d[photo == k] for k in row]).mean() for row in draws]
    assert np.allclose(out["mean_difference_ci_photos"], np.percentile(boot, [2.5, 97.5]), rtol=0, atol=1e-12)
    # photos that agree leave the resamples nothing to vary
    same = cmp.by_photo(np.array([0.5, 0.4, 0.6, 0.5]), np.array([0, 1, 1, 0]))
    assert np.allclose(same["mean_difference_ci_photos"], 0.5, rtol=0, atol=1e-12) and same["same_sign"] == 2


def _rows(base: np.ndarray, others: dict) -> list:
    """Method rows with straightness values (photos x sides) only, as ``compare_family`` reads them."""
    def row(label, values):
        return SimpleNamespace(label=label, is_method=True, cal=None,
                               sides=[SimpleNamespace(rms_px=v.reshape(-1, 4)) for v in values])
    return [row("base", base)] + [row(k, v) for k, v in others.items()]


def test_a_difference_on_one_photo_is_significant_over_units_not_by_photo():
    """5 photos x 40 sides: a row worse by 0.01 px on every photo is worse by photo too (5 of 5 photos, the photos'
    CI above 0; their Wilcoxon cannot go below p = 0.0625 with 5); a row better by 0.05 px on one photo only is
    significant over the 200 units and not by photo (1 of 5, the photos' CI holding 0)."""
    rng = np.random.default_rng(0)
    base = 0.1 + 0.02 * rng.random((5, 40))
    worse = base + 0.01 + 1e-4 * rng.standard_normal(base.shape)
    one = base.copy()
    one[0] -= 0.05
    out = cmp.compare_family(_rows(base, {"worse": worse, "one": one}), "straightness", "base")
    t = {x["row"]: x for x in out["tests"]}
    assert out["n_units"] == 200 and t["worse"]["n_photos"] == 5
    assert t["worse"]["significant"] and t["worse"]["photos_same_sign"] == 5
    assert t["worse"]["mean_difference_ci_photos"][0] > 0.009 and t["worse"]["p_value_photos"] == 0.0625
    assert t["one"]["significant"] and t["one"]["photos_same_sign"] == 1 and not t["one"]["significant_photos"]
    lo, hi = t["one"]["mean_difference_ci_photos"]
    assert lo < 0 and hi == 0.0  # a resample without that photo has no difference at all
