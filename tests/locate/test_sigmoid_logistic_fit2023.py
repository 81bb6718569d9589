"""Specification of SigmoidLogisticFit2023 (locate/methods/sigmoid_logistic_fit2023.py).

Setting shared by the accuracy tests: exact pixel-integrated edges
(render.synthetic.render_edge_image), dark level 40, contrast 120, Gaussian
blur 1.0 px, 48x48 images, shared Canny candidates (sigma 1 px); the error of
a point is truth.signed_distance(x, y); only candidates whose pixel centre
lies within 1.5 px of the true edge are scored.
"""
import numpy as np
from scipy.optimize import least_squares

import locate
from locate.profiles import profile_offsets, sample_profiles
from render.edge_truth import CircleEdge, StraightEdge
from render.synthetic import render_edge_image

METHOD = "sigmoid_logistic_fit2023"
SHAPE = (48, 48)
A, B, BLUR = 40.0, 120.0, 1.0


def straight(seed):
    r = np.random.default_rng(1000 + seed)
    return StraightEdge(SHAPE[1] / 2 - 0.5 + r.uniform(-1, 1), SHAPE[0] / 2 - 0.5 + r.uniform(-1, 1),
                        r.uniform(-np.pi, np.pi))


def circle(seed):
    r = np.random.default_rng(2000 + seed)
    return CircleEdge(SHAPE[1] / 2 - 0.5 + r.uniform(-1, 1), SHAPE[0] / 2 - 0.5 + r.uniform(-1, 1),
                      r.uniform(12, 16), bool(seed % 2))


def scored(edge, noise_rel=0.0, seed=0, **options):
    """(image, near candidates, EdgePoints) for one rendered edge."""
    img = render_edge_image(SHAPE, edge, A, B, BLUR, noise_sigma=noise_rel * B, rng=np.random.default_rng(seed))
    cand = locate.candidates(img)
    cand = cand.subset(np.abs(edge.signed_distance(cand.x, cand.y)) <= 1.5)
    return img, cand, locate.refine(img, cand, METHOD, **options)


def errors(edge, **kw):
    _, _, pts = scored(edge, **kw)
    assert pts.converged.all()
    return edge.signed_distance(pts.x, pts.y)


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


def _rmse_at(noise_rel):
    e = np.concatenate([errors(straight(s), noise_rel=noise_rel, seed=10 * s + rep + 1)
                        for s in range(4) for rep in range(3)])
    return np.sqrt(np.mean(e ** 2))


def test_error_grows_linearly_with_noise():
    """Least-squares error is linear in sigma_n/B.  Measured RMSE 0.0029, 0.0220, 0.0435 px at sigma_n/B = 0, 0.01, 0.02."""
    r0, r1, r2 = _rmse_at(0.0), _rmse_at(0.01), _rmse_at(0.02)
    assert r2 > 5 * r0
    # the noise-induced part (model-mismatch error removed in quadrature) doubles with sigma_n
    assert 1.6 < np.sqrt(r2 ** 2 - r0 ** 2) / np.sqrt(r1 ** 2 - r0 ** 2) < 2.4


def test_fit_agrees_with_scipy_least_squares():
    """The batched LM kernel lands on scipy's LM minimum to 1e-6 px on real noisy profiles."""
    img, cand, pts = scored(straight(1), noise_rel=0.01, seed=3)
    prof = sample_profiles(img, cand)
    t = profile_offsets()
    for i in range(0, len(cand), max(1, len(cand) // 6)):
        y = prof[i]

        def res(p):
            return p[0] + p[1] / (1.0 + np.exp(-(t - p[2]) / p[3])) - y

        x0 = [y.min(), y.max() - y.min(), 0.0, 0.6]
        ref = least_squares(res, x0, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=10000)
        assert abs(pts.offset[i] - ref.x[2]) < 1e-6
        assert abs(pts.width[i] - abs(ref.x[3])) < 1e-5


def test_flat_image_region_is_not_converged():
    """A profile without contrast cannot be fitted: converged=False, candidate pixel kept."""
    img, cand, _ = scored(straight(0))
    pts = locate.refine(np.full_like(img, 50.0), cand, METHOD)
    assert not pts.converged.any()
    np.testing.assert_array_equal(pts.x, cand.x)
    np.testing.assert_array_equal(pts.y, cand.y)
