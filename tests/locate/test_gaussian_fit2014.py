"""Specification of GaussianFit2014 (locate/methods/gaussian_fit2014.py).

Setting shared by the accuracy tests: exact pixel-integrated edges
(render.synthetic.render_edge_image), dark level 40, contrast 120, Gaussian
blur 1.0 px, 48x48 images, shared Canny candidates (sigma 1 px); the error of
a point is truth.signed_distance(x, y); only candidates whose pixel centre
lies within 1.5 px of the true edge are scored.
"""
from functools import partial

import numpy as np
import pytest

from edgetruth import locate
from tests.support import edge_scenes
from tests.support.edge_scenes import assert_flat_region_not_converged, circle, lm_reference_fits, straight

METHOD = "gaussian_fit2014"
scored = partial(edge_scenes.scored, METHOD)  # (image, near candidates, EdgePoints) for one rendered edge
errors = partial(edge_scenes.errors, METHOD)  # signed errors of the points, all of which must converge


def test_registered_as_baseline():
    m = locate.METHODS[METHOD]
    assert (m.label, m.family) == ("GaussianFit2014", "baseline")


def test_ideal_straight_edges_are_unbiased():
    """The differences of a pixel-integrated Gaussian-blurred step are a
    symmetric, nearly Gaussian bump (variance ~ blur^2 + 1/6) centred on the
    edge, so the Gaussian peak is unbiased; what remains is the small shape
    mismatch and the bilinear resampling.  Measured over 4 random edges
    (168 points): mean -2e-5 px, RMSE 0.0020 px, max 0.006 px."""
    e = np.concatenate([errors(straight(s)) for s in range(4)])
    assert e.size > 100
    assert abs(e.mean()) < 0.002
    assert np.sqrt(np.mean(e ** 2)) < 0.004


def test_ideal_circles_only_curvature_bias():
    """Curvature makes the normal profile asymmetric: a bias of order
    blur^2/(2R) (~0.035 px) toward the bright side bounds it.  Measured per
    circle (R = 12-15 px): |mean| 0.004-0.005 px, sign of the bright side;
    RMSE 0.012 px."""
    es = []
    for s in range(4):
        e = errors(circle(s))
        assert abs(e.mean()) < 0.010
        es.append(e)
    e = np.concatenate(es)
    assert np.sqrt(np.mean(e ** 2)) < 0.016


_rmse_at = partial(edge_scenes.rmse_at, METHOD)  # RMSE over straight edges 0-3, 3 noise draws each


def test_error_grows_linearly_with_noise():
    """Least-squares error is linear in sigma_n/B.  Differencing doubles the
    noise variance of each gradient sample and correlates neighbours, so the
    Gaussian fit is noisier than the step fits (erf: 0.043 px at 0.02).
    Measured RMSE 0.0020, 0.0287, 0.0571 px at sigma_n/B = 0, 0.01, 0.02."""
    r0, r1, r2 = _rmse_at(0.0), _rmse_at(0.01), _rmse_at(0.02)
    assert r2 > 5 * r0
    assert 1.6 < np.sqrt(r2 ** 2 - r0 ** 2) / np.sqrt(r1 ** 2 - r0 ** 2) < 2.4


def test_least_squares_fit_beats_three_point_log_parabola_under_noise():
    """The 3-point closed form uses 3 of the 10 differences; the full fit uses
    all of them.  Noise-free both are accurate (log3 RMSE 0.0040 px); at
    sigma_n/B = 0.02 the fit is ~2x better (measured 0.057 vs 0.107 px)."""
    assert _rmse_at(0.0, variant="log3") < 0.006
    assert _rmse_at(0.02) < 0.7 * _rmse_at(0.02, variant="log3")


def test_fit_agrees_with_scipy_least_squares():
    """The batched LM kernel lands on scipy's LM minimum of the constant-free
    Gaussian on the profile differences to 1e-6 px on real noisy profiles."""
    pts, refs = lm_reference_fits(METHOD, lambda tg, p: p[0] * np.exp(-0.5 * ((tg - p[1]) / p[2]) ** 2),
                                  lambda tg, y: [y.max(), tg[np.argmax(y)], 1.0], differences=True)
    for i, ref_x in refs:
        assert abs(pts.offset[i] - ref_x[1]) < 1e-6
        assert abs(pts.width[i] - abs(ref_x[2])) < 1e-5
        assert abs(pts.amplitude[i] - ref_x[0]) < 1e-4


def test_flat_image_region_is_not_converged():
    """No positive difference, no Gaussian: converged=False, candidate pixel kept (both variants)."""
    for variant in ("lsq", "log3"):
        assert_flat_region_not_converged(METHOD, variant=variant)


def test_unknown_variant_is_an_input_error():
    from edgetruth.errors import InputError
    img, cand, _ = scored(straight(0))
    with pytest.raises(InputError):
        locate.refine(img, cand, METHOD, variant="cubic")
