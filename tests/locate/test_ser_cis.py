"""Specification of SER-CIS (locate/methods/ser_cis.py).

Setting shared by the accuracy tests: exact pixel-integrated edges
(render.synthetic.render_edge_image), dark level 40, contrast 120, Gaussian
blur 1.0 px, 48x48 images, shared Canny candidates (sigma 1 px); the error of
a point is truth.signed_distance(x, y); only candidates whose pixel centre
lies within 1.5 px of the true edge are scored.
"""
from functools import partial

import numpy as np
from scipy.special import ndtr

from edgetruth import locate
from edgetruth.locate.methods.ser_cis import cis_one, image_noise_sigma
from edgetruth.render.edge_truth import StraightEdge
from edgetruth.render.synthetic.scenarios import render_edge_image
from tests.support import edge_scenes
from tests.support.edge_scenes import (A_LEVEL as A, B_CONTRAST as B, BLUR, SHAPE_48 as SHAPE, circle,
                                       refine_near_edge, straight)

METHOD = "ser_cis"
errors = partial(edge_scenes.errors, METHOD)  # signed errors of the points, all of which must converge


def test_registered_as_baseline():
    m = locate.METHODS[METHOD]
    assert (m.label, m.family) == ("SER-CIS", "baseline")


T = np.arange(-5.0, 6.0)


def _cis(prof, h_min=4, tol_abs=0.0, flat_rel=0.01):
    out = np.empty(6)
    cis_one(np.asarray(prof, float), h_min, 2, tol_abs, flat_rel, out)
    return out  # mu, g_b, g_a, c, n, status


def _pixel_mean_step(mu, s):
    """Exact mean of Phi((t - mu)/s) over each unit pixel [t - 1/2, t + 1/2]."""
    def g1(u):
        return u * ndtr(u) + np.exp(-0.5 * u * u) / np.sqrt(2 * np.pi)
    return s * (g1((T + 0.5 - mu) / s) - g1((T - 0.5 - mu) / s))


def test_offset_convention_is_exact_on_an_ideal_pixel_integrated_step():
    """Derivation (module docstring): with pixel-mean samples of a step at mu,
    sum I = n g_b + (g_a - g_b)(t_e + 1/2 - mu), so c = t_e - mu and the edge
    is mu = t_e - c, measured back from the bright-end sample.  A sharp step
    must come out exact (1e-12 px) at every subpixel position, and the same
    from the 9- and the 11-sample region."""
    for mu in np.linspace(-0.95, 0.95, 39):
        prof = 40.0 + 120.0 * np.clip(T + 0.5 - mu, 0.0, 1.0)
        for h_min in (4, 5):
            out = _cis(prof, h_min=h_min)
            assert out[5] == 0 and out[4] == 2 * h_min + 1
            assert abs(out[0] - mu) < 1e-12
            assert abs(out[3] - (h_min - mu)) < 1e-12
            assert out[1] == 40.0 and out[2] == 160.0


def test_blur_only_moves_intensity_inside_the_region():
    """A Gaussian blur redistributes intensity within the run without changing
    its sum, so CIS stays exact while both ends are on their plateaus.  Blur
    0.7 px, |mu| <= 0.6, 11-sample region: the nearer end segment's pixels
    start >= 4.1 sigma from the edge, so the plateau error is < 3e-5 of the
    contrast and mu is exact to < 1e-5 px (measured worst 6.4e-6 px)."""
    for mu in np.linspace(-0.6, 0.6, 13):
        prof = 40.0 + 120.0 * _pixel_mean_step(mu, 0.7)
        out = _cis(prof, h_min=5, flat_rel=1e-3)
        assert out[5] == 0
        assert abs(out[0] - mu) < 1e-5


def test_axis_aligned_edges_in_images():
    """Along an axis the profile samples are exact pixel means, so only the
    plateau error of the 9-sample region remains (ends 2.5-4.5 px from the
    edge at blur 0.8: < 0.1 % of the contrast).  Measured max |error| 0.0032 px."""
    for angle in (0.0, np.pi / 2, np.pi, -np.pi / 2):
        for x0 in (23.3, 23.5, 23.81):
            edge = StraightEdge(x0, x0 - 0.4, angle)
            img = render_edge_image(SHAPE, edge, A, B, 0.8)
            _, pts = refine_near_edge(img, edge, METHOD)
            assert pts.converged.all()
            assert np.abs(edge.signed_distance(pts.x, pts.y)).max() < 0.005


def test_ideal_straight_edges():
    """Oblique edges: the bilinear samples along the normal are no longer
    pixel-area means, so the sum is not exactly conserved, and the 1 %
    flatness tolerance leaves plateau errors up to ~0.5 % of the contrast;
    both vary with the edge's phase, so RMSE but little mean bias.  Measured
    over 4 random edges (168 points): mean -0.0015 px, RMSE 0.0083 px,
    max 0.016 px."""
    e = np.concatenate([errors(straight(s)) for s in range(4)])
    assert e.size > 100
    assert abs(e.mean()) < 0.004
    assert np.sqrt(np.mean(e ** 2)) < 0.012


def test_ideal_circles_only_curvature_bias():
    """Curvature makes the normal profile asymmetric: a bias of order
    blur^2/(2R) (~0.035 px) toward the bright side bounds it.  Measured per
    circle (R = 12-15 px): |mean| 0.006-0.009 px, sign of the bright side;
    RMSE 0.010 px."""
    es = []
    for s in range(4):
        e = errors(circle(s))
        assert abs(e.mean()) < 0.014
        es.append(e)
    e = np.concatenate(es)
    assert np.sqrt(np.mean(e ** 2)) < 0.015


_rmse_at = partial(edge_scenes.rmse_at, METHOD)  # RMSE over straight edges 0-3, 3 noise draws each


def test_error_grows_with_noise():
    """Given its region, c is linear in the samples, so the error is linear
    in sigma_n/B; the plateau means (2 samples each) enter c multiplied by
    the number of samples on their side, which makes CIS noisier than the
    fits (erf fit: 0.043 px at 0.02).  Measured RMSE 0.0083, 0.0313,
    0.0600 px at sigma_n/B = 0, 0.01, 0.02."""
    r0, r1, r2 = _rmse_at(0.0), _rmse_at(0.01), _rmse_at(0.02)
    assert r2 > 5 * r0
    assert 1.6 < np.sqrt(r2 ** 2 - r0 ** 2) / np.sqrt(r1 ** 2 - r0 ** 2) < 2.4


def test_no_stable_region_is_not_converged():
    """A 4-px blur still slopes by ~5 % of the contrast per px at t = +-5:
    no stable region within the 11 samples, so every point is flagged
    converged=False and keeps its candidate pixel.  So does a ramp."""
    edge = StraightEdge(23.3, 24.1, 0.7)
    img = render_edge_image(SHAPE, edge, A, B, 4.0)
    cand, pts = refine_near_edge(img, edge, METHOD)
    assert len(cand) > 20 and not pts.converged.any()
    np.testing.assert_array_equal(pts.x, cand.x)
    np.testing.assert_array_equal(pts.y, cand.y)
    assert _cis(40.0 + 10.0 * T)[5] != 0


def test_noise_estimate_ignores_the_edge():
    """Immerkaer's estimator over non-edge pixels recovers the noise to 10 %
    and stays near zero on a noise-free edge image (the edge is masked)."""
    edge = straight(2)
    noisy = render_edge_image(SHAPE, edge, A, B, BLUR, noise_sigma=2.4, rng=np.random.default_rng(5))
    assert abs(image_noise_sigma(noisy, locate.candidates(noisy)) / 2.4 - 1) < 0.1
    clean = render_edge_image(SHAPE, edge, A, B, BLUR)
    assert image_noise_sigma(clean, locate.candidates(clean)) < 0.01 * B


def test_noise_estimate_is_immerkaers_formula():
    """The one-pass kernel equals Immerkaer's estimator written with OpenCV (3x3 Laplacian-difference
    mask, mean |response| over the interior pixels whose gradient is below the Canny low threshold)."""
    import math

    import cv2
    import pytest

    from edgetruth.locate import candidates

    for seed in range(3):
        img, cand, _ = edge_scenes.scored("ser_cis", straight(seed), noise_rel=0.02, seed=seed)
        full = candidates(img)
        mask = np.array([[1.0, -2.0, 1.0], [-2.0, 4.0, -2.0], [1.0, -2.0, 1.0]])
        resp = np.abs(cv2.filter2D(img, cv2.CV_64F, mask, borderType=cv2.BORDER_REFLECT))[1:-1, 1:-1]
        mag = np.hypot(full.grad_x, full.grad_y)[1:-1, 1:-1]
        ref = math.sqrt(math.pi / 2) / 6 * resp[mag < full.thresholds[0]].mean()
        assert image_noise_sigma(img, full) == pytest.approx(ref, rel=1e-12)
        assert 0.5 * 0.02 * 120 < ref < 2 * 0.02 * 120
