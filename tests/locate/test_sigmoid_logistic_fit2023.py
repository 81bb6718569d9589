"""Specification of SigmoidLogisticFit2023 (locate/methods/sigmoid_logistic_fit2023.py).

Setting shared by the accuracy tests: exact pixel-integrated edges
(render.synthetic.render_edge_image), dark level 40, contrast 120, Gaussian
blur 1.0 px, 48x48 images, shared Canny candidates (sigma 1 px); the error of
a point is truth.signed_distance(x, y); only candidates whose pixel centre
lies within 1.5 px of the true edge are scored.
"""
from functools import partial

import numpy as np

from edgetruth import locate
from tests.support import edge_scenes
from tests.support.edge_scenes import assert_flat_region_not_converged, circle, lm_reference_fits, straight

METHOD = "sigmoid_logistic_fit2023"
errors = partial(edge_scenes.errors, METHOD)  # signed errors of the points, all of which must converge


def test_registered_as_baseline():
    m = locate.METHODS[METHOD]
    assert (m.label, m.family) == ("SigmoidLogisticFit2023", "baseline")


def test_ideal_straight_edges_are_unbiased():
    """The logistic is point-symmetric about its centre, the blurred step about the edge: no bias; and a logistic (w ~ 0.6 sigma) is close to a Gaussian-blurred step, so the phase-dependent mismatch error is small.  Measured over 4 random edges (168 points): mean +6e-5 px, RMSE 0.0029 px, max 0.009 px."""
    e = np.concatenate([errors(straight(s)) for s in range(4)])
    assert e.size > 100
    assert abs(e.mean()) < 0.002
    assert np.sqrt(np.mean(e ** 2)) < 0.005


def test_ideal_circles_only_curvature_bias():
    """Curvature makes the normal profile asymmetric: a bias of order blur^2/(2R) (~0.035 px) toward the bright side bounds it.  Measured per circle (R = 12-15 px): |mean| 0.005-0.006 px, sign of the bright side; RMSE 0.012 px."""
    es = []
    for s in range(4):
        e = errors(circle(s))
        assert abs(e.mean()) < 0.012
        es.append(e)
    e = np.concatenate(es)
    assert np.sqrt(np.mean(e ** 2)) < 0.016


_rmse_at = partial(edge_scenes.rmse_at, METHOD)  # RMSE over straight edges 0-3, 3 noise draws each


def test_error_grows_linearly_with_noise():
    """Least-squares error is linear in sigma_n/B.  Measured RMSE 0.0029, 0.0220, 0.0435 px at sigma_n/B = 0, 0.01, 0.02."""
    r0, r1, r2 = _rmse_at(0.0), _rmse_at(0.01), _rmse_at(0.02)
    assert r2 > 5 * r0
    # the noise-induced part (model-mismatch error removed in quadrature) doubles with sigma_n
    assert 1.6 < np.sqrt(r2 ** 2 - r0 ** 2) / np.sqrt(r1 ** 2 - r0 ** 2) < 2.4


def test_fit_agrees_with_scipy_least_squares():
    """The batched LM kernel lands on scipy's LM minimum to 1e-6 px on real noisy profiles."""
    pts, refs = lm_reference_fits(METHOD, lambda t, p: p[0] + p[1] / (1.0 + np.exp(-(t - p[2]) / p[3])),
                                  lambda t, y: [y.min(), y.max() - y.min(), 0.0, 0.6])
    for i, ref_x in refs:
        assert abs(pts.offset[i] - ref_x[2]) < 1e-6
        assert abs(pts.width[i] - abs(ref_x[3])) < 1e-5


def test_flat_image_region_is_not_converged():
    """A profile without contrast cannot be fitted: converged=False, candidate pixel kept."""
    assert_flat_region_not_converged(METHOD)
