"""The robust line fit's numba kernels are, bit for bit, the numpy implementation they replaced (kept
here as the specification): numpy's pairwise summation, the same medians, the same operation order."""
from __future__ import annotations

import math

import numpy as np
import pytest

from edgetruth.evaluate.ranging import line_kernels as lk
from edgetruth.evaluate.ranging.size import IRLS_TOL_PX, SIGMA_FLOOR_PX, fit_line_robust


def _tls(x, y, w):
    sw = w.sum()
    mx, my = (w * x).sum() / sw, (w * y).sum() / sw
    dx, dy = x - mx, y - my
    sxx, sxy, syy = float((w * dx * dx).sum()), float((w * dx * dy).sum()), float((w * dy * dy).sum())
    theta = 0.5 * math.atan2(2.0 * sxy, sxx - syy)
    n = np.array([-math.sin(theta), math.cos(theta)])
    return n, float(n[0] * mx + n[1] * my)


def _mad_sigma(r):
    return max(1.4826 * float(np.median(np.abs(r - np.median(r)))), SIGMA_FLOOR_PX)


def reference_fit(x, y, ransac_threshold_px=1.0, iterations=200, seed=0, tukey_c=4.685):
    """The numpy implementation (stop 26)."""
    n_pts = x.size
    rng = np.random.Generator(np.random.PCG64(seed))
    best = None
    if n_pts > 3:
        i = rng.integers(0, n_pts, size=(iterations, 2))
        i = i[i[:, 0] != i[:, 1]]
        ex, ey = x[i[:, 1]] - x[i[:, 0]], y[i[:, 1]] - y[i[:, 0]]
        norm = np.hypot(ex, ey)
        ok = norm > 0
        i, ex, ey, norm = i[ok], ex[ok], ey[ok], norm[ok]
        nx, ny = -ey / norm, ex / norm
        d = nx * x[i[:, 0]] + ny * y[i[:, 0]]
        r = np.abs(nx[:, None] * x[None] + ny[:, None] * y[None] - d[:, None])
        counts = (r < ransac_threshold_px).sum(1)
        if counts.size:
            best = r[int(np.argmax(counts))] < ransac_threshold_px
    w = best.astype(np.float64) if best is not None and best.sum() >= 2 else np.ones(n_pts)
    n, d = _tls(x, y, w)
    for _ in range(30):
        r = n[0] * x + n[1] * y - d
        s = _mad_sigma(r[w > 0])
        u = r / (tukey_c * s)
        w_new = np.where(np.abs(u) < 1, (1 - u * u) ** 2, 0.0)
        if w_new.sum() < 2 or np.count_nonzero(w_new) < 2:
            break
        n_new, d_new = _tls(x, y, w_new)
        if n_new @ n < 0:
            n_new, d_new = -n_new, -d_new
        done = abs(d_new - d) < IRLS_TOL_PX and np.linalg.norm(n_new - n) < IRLS_TOL_PX * 1e-3
        n, d, w = n_new, d_new, w_new
        if done:
            break
    r = n[0] * x + n[1] * y - d
    inl = w > 0
    return n, d, inl, float(np.sqrt(np.mean(r[inl] ** 2))) if inl.any() else float("nan")


def test_pairwise_sum_is_numpys_sum():
    rng = np.random.default_rng(0)
    for n in list(range(0, 300)) + [1000, 4097]:
        a = rng.normal(size=n) * 10.0 ** rng.uniform(-3, 3, size=n)
        assert lk.pairwise_sum(a, 0, n) == a.sum() or (n == 0 and lk.pairwise_sum(a, 0, 0) == 0.0)


@pytest.mark.slow
@pytest.mark.parametrize("case", range(300))
def test_fit_equals_the_numpy_implementation(case):
    """Edge-like point sets: a line at any angle, 6-400 points, sub-pixel noise, gross outliers, a few
    exact duplicates; every output (normal, offset, inliers, RMS) identical."""
    rng = np.random.default_rng(case)
    n = int(rng.integers(6, 400))
    theta = rng.uniform(0, np.pi)
    t = np.sort(rng.uniform(-100, 100, n))
    x = 300 + t * math.cos(theta) + rng.normal(0, 0.03, n)
    y = 200 + t * math.sin(theta) + rng.normal(0, 0.03, n)
    out = rng.random(n) < rng.uniform(0, 0.2)
    x[out] += rng.normal(0, 3, out.sum())
    if case % 7 == 0:
        x[: n // 10] = x[0]
        y[: n // 10] = y[0]
    ln = fit_line_robust(x, y, seed=case % 4)
    n_ref, d_ref, inl_ref, rms_ref = reference_fit(x, y, seed=case % 4)
    assert ln.n[0] == n_ref[0] and ln.n[1] == n_ref[1] and ln.d == d_ref
    np.testing.assert_array_equal(ln.inliers, inl_ref)
    assert ln.rms_px == rms_ref


@pytest.mark.parametrize("n", [0, 1, 2, 3, 7, 8, 64, 129, 500])
def test_median_is_numpys_median(n):
    """The kernel's heap sort gives np.median's order statistics, NaN last (as np.sort orders them)."""
    rng = np.random.default_rng(n)
    for case in range(20):
        v = rng.normal(size=n) * 10.0 ** rng.uniform(-3, 3, size=n)
        if case % 3 == 1 and n > 2:
            v[rng.integers(0, n, n // 3 + 1)] = v[0]  # ties
        if case % 5 == 4 and n > 2:
            v[rng.integers(0, n, 1)] = np.nan
        ref = np.sort(v)
        want = np.nan if n == 0 else (ref[n // 2] if n % 2 else (ref[n // 2 - 1] + ref[n // 2]) / 2.0)
        got = lk._median(v.copy())
        assert (got == want) or (np.isnan(got) and np.isnan(want))
        s = v.copy()
        lk._heapsort(s)
        assert np.array_equal(s, ref, equal_nan=True)


def test_ransac_pairs_are_the_draws_kept_read_only():
    from edgetruth.evaluate.ranging.size import ransac_pairs

    for n in (2, 3, 4, 57, 400):
        got = ransac_pairs(1, n, 200)
        if n <= 3:
            assert got.shape == (0, 2)
        else:
            i = np.random.Generator(np.random.PCG64(1)).integers(0, n, size=(200, 2))
            assert np.array_equal(got, i[i[:, 0] != i[:, 1]])
        assert not got.flags.writeable and ransac_pairs(1, n, 200) is got
