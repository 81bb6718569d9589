"""Specification of HagaraAEF2011 (locate/methods/hagara_aef2011.py).

Setting shared by the accuracy tests: exact pixel-integrated edges
(render.synthetic.render_edge_image), dark level 40, contrast 120, Gaussian
blur 1.0 px, 48x48 images, shared Canny candidates (sigma 1 px); the error of
a point is truth.signed_distance(x, y); only candidates whose pixel centre
lies within 1.5 px of the true edge are scored.
"""
from functools import partial

import numpy as np
from scipy.special import erf

from edgetruth import locate
from tests.support import edge_scenes
from tests.support.edge_scenes import assert_flat_region_not_converged, circle, lm_reference_fits, straight

METHOD = "hagara_aef2011"
errors = partial(edge_scenes.errors, METHOD)  # signed errors of the points, all of which must converge


def test_registered_as_baseline():
    m = locate.METHODS[METHOD]
    assert (m.label, m.family) == ("HagaraAEF2011", "baseline")


def test_ideal_straight_edges_are_unbiased():
    """The erf model is the Gaussian-blurred step itself, so on noise-free
    straight edges only the small mismatch from pixel-area integration and
    bilinear resampling along an oblique normal remains; both are symmetric
    about the edge, so no bias.  Measured over 4 random edges (168 points):
    mean -2e-5 px, RMSE 0.0022 px, max 0.007 px."""
    e = np.concatenate([errors(straight(s)) for s in range(4)])
    assert e.size > 100
    assert abs(e.mean()) < 0.002
    assert np.sqrt(np.mean(e ** 2)) < 0.004


def test_ideal_circles_only_curvature_bias():
    """On a circle of radius R the normal profile is not symmetric: a bias of
    order blur^2 / (2R) (~0.035 px here) toward the bright side is the most
    a profile method can show; the fit shows less.  Measured per circle
    (R = 12-15 px): |mean| 0.005-0.007 px with the sign of the bright side,
    RMSE over the 4 circles 0.011 px."""
    es = []
    for s in range(4):
        c = circle(s)
        e = errors(c)
        assert abs(e.mean()) < 0.012
        es.append(e)
    e = np.concatenate(es)
    assert np.sqrt(np.mean(e ** 2)) < 0.015


_rmse_at = partial(edge_scenes.rmse_at, METHOD)  # RMSE over straight edges 0-3, 3 noise draws each


def test_error_grows_linearly_with_noise():
    """A least-squares fit's position error is linear in sigma_n/B; the erf
    fit reaches the Cramer-Rao bound (BRIEF §6: 2.36 sigma_n/B for blur 1,
    11 px), slightly below it here because bilinear resampling along oblique
    normals averages neighbouring pixels.  Measured: RMSE 0.0022, 0.0217,
    0.0430 px at sigma_n/B = 0, 0.01, 0.02 (0.91 x the bound)."""
    r0, r1, r2 = _rmse_at(0.0), _rmse_at(0.01), _rmse_at(0.02)
    assert r2 > 5 * r0
    assert 1.6 < r2 / r1 < 2.4
    crb = 2.36 * 0.02
    assert 0.6 * crb < r2 < 1.3 * crb


def test_fit_agrees_with_scipy_least_squares():
    """The batched kernel lands on scipy's LM minimum of the paper's model
    a + b erf((t - mu) / (sqrt(2) sigma)) to 1e-6 px on real noisy profiles."""
    pts, refs = lm_reference_fits(METHOD, lambda t, p: p[0] + p[1] * erf((t - p[2]) / (np.sqrt(2) * p[3])),
                                  lambda t, y: [y.mean(), 0.5 * (y.max() - y.min()), 0.0, 1.0])
    for i, ref_x in refs:
        assert abs(pts.offset[i] - ref_x[2]) < 1e-6
        assert abs(pts.width[i] - abs(ref_x[3])) < 1e-5
        assert abs(pts.a[i] - ref_x[0]) < 1e-4 and abs(pts.b[i] - ref_x[1]) < 1e-4


def test_flat_image_region_is_not_converged():
    """A profile without contrast cannot be fitted: converged=False, candidate pixel kept."""
    assert_flat_region_not_converged(METHOD)
