"""The block Levenberg-Marquardt (``block_lm``): exact on a linear problem with shared and per-view parameters, its
variances (shared and per view) the diagonal of (JᵀJ)⁻¹, and the same answer as the dense reference on a bent-board
calibration."""
from __future__ import annotations

import numpy as np
import pytest

from edgetruth.evaluate import block_lm


def _linear(n_views=7, rows=30, n_shared=3, n_block=4, seed=0):
    """r = A_s s + A_b(view) b_view - y: a linear problem, its dense design matrix and data."""
    rng = np.random.default_rng(seed)
    view = np.repeat(np.arange(n_views), rows)
    As = rng.normal(size=(len(view), n_shared))
    Ab = rng.normal(size=(len(view), n_block))
    y = rng.normal(size=len(view))

    def residual(s, b):
        return As @ s + np.einsum("nk,nk->n", Ab, b[view]) - y

    dense = np.zeros((len(view), n_shared + n_views * n_block))
    dense[:, :n_shared] = As
    for v in range(n_views):
        dense[view == v, n_shared + v * n_block: n_shared + (v + 1) * n_block] = Ab[view == v]
    return residual, view, dense, y


def test_linear_problem_is_solved_exactly():
    """On a linear problem the solution is least squares' (1e-8), and the variances are the diagonal of (JᵀJ)⁻¹
    of the whole design matrix (1e-8 relative), shared parameters' correlations with the blocks included."""
    residual, view, dense, y = _linear()
    fit = block_lm.solve(residual, np.zeros(3), np.zeros((7, 4)), view, np.ones(3, bool), np.ones(4, bool))
    x = np.linalg.lstsq(dense, y, rcond=None)[0]
    assert np.abs(fit.shared - x[:3]).max() < 1e-8 and np.abs(fit.blocks.ravel() - x[3:]).max() < 1e-8
    var = np.diag(np.linalg.inv(dense.T @ dense))
    assert np.allclose(fit.block_var, var[3:].reshape(7, 4), rtol=1e-8, atol=0)
    assert np.allclose(fit.shared_var, var[:3], rtol=1e-8, atol=0)
    ref = block_lm.solve_dense(residual, np.zeros(3), np.zeros((7, 4)), view, np.ones(3, bool), np.ones(4, bool))
    assert np.allclose(ref.shared_var, var[:3], rtol=1e-6, atol=0)


def test_held_parameters_stay_and_have_no_variance():
    residual, view, dense, y = _linear()
    b0 = np.full((7, 4), 0.5)
    fit = block_lm.solve(residual, np.zeros(3), b0, view, np.array([True, False, True]),
                         np.array([True, True, False, True]))
    assert fit.shared[1] == 0.0 and np.all(fit.blocks[:, 2] == 0.5) and np.all(np.isnan(fit.block_var[:, 2]))
    assert np.isnan(fit.shared_var[1]) and np.all(np.isfinite(fit.shared_var[[0, 2]]))
    keep = np.r_[0, 2, [3 + 4 * v + j for v in range(7) for j in (0, 1, 3)]]
    x = np.linalg.lstsq(dense[:, keep], y - dense[:, 3 + 2::4][:, :7] @ np.full(7, 0.5), rcond=None)[0]
    assert np.abs(fit.shared[[0, 2]] - x[:2]).max() < 1e-8


def test_rows_must_be_grouped_by_view():
    residual, view, _, _ = _linear()
    with pytest.raises(ValueError, match="grouped by view"):
        block_lm.solve(residual, np.zeros(3), np.zeros((7, 4)), view[::-1], np.ones(3, bool), np.ones(4, bool))


def test_same_answer_as_the_dense_reference():
    """A bent-board calibration of 13 analytic views: the block solver and scipy's dense MINPACK agree on RMS
    (1e-9 relative), depths (1e-5 mm), focal length (1e-4 px) and standard errors (1e-4 relative)."""
    from edgetruth.evaluate.board_bend import bend_check
    from tests.evaluate.bent_views import curled_views

    rng = np.random.default_rng(7)
    curl = np.c_[rng.uniform(-0.1, 0.1, 13), rng.uniform(-0.1, 0.1, 13), rng.uniform(0.2, 0.6, 13)]
    xy, img, K, dist, rv, tv, _, _ = curled_views(curl, 0.05)
    a = bend_check(xy, img, K, dist, rv, tv, solver=block_lm.solve)
    b = bend_check(xy, img, K, dist, rv, tv, solver=block_lm.solve_dense)
    for name in a:
        qa, qb = a[name], b[name]
        assert qa["rms_bent_px"] == pytest.approx(qb["rms_bent_px"], rel=1e-9)
        assert np.abs(np.subtract(qa["depth_mm"], qb["depth_mm"])).max() < 1e-5
        assert abs(qa["intrinsics_bent"]["fx_px"] - qb["intrinsics_bent"]["fx_px"]) < 1e-4
        assert np.allclose(qa["coefficients_se_mm"], qb["coefficients_se_mm"], rtol=1e-4)
