"""Analytic edges: pixel values are exact pixel-area means of the blurred step."""
import numpy as np
import pytest

from edgetruth.conventions import pixel_centres
from edgetruth.render.synthetic.analytic import StepProfile, gauss_legendre_pixel_mean, step_image, texture_image
from edgetruth.render.edge_truth import CircleEdge, StraightEdge


def supersampled(shape, fn, n=64):
    """Midpoint-rule reference: n x n samples per pixel (error O(1/n^2) for smooth fn)."""
    x, y = pixel_centres(shape)
    g = (np.arange(n) + 0.5) / n - 0.5
    xs = x[..., None, None] + g[None, None, :, None]
    ys = y[..., None, None] + g[None, None, None, :]
    return fn(xs, ys).mean(axis=(-1, -2))


@pytest.mark.parametrize("angle", [0.0, 1e-6, 0.01, 0.4, np.pi / 4, 2.0, -2.7, np.pi / 2])
@pytest.mark.parametrize("blur", [(0.5, 0.5), (1.0, 1.0), (2.0, 2.0), (0.6, 1.8)])
def test_straight_edge_closed_form_matches_supersampling(angle, blur):
    # midpoint rule with n = 128 on a profile of scale >= 0.5 px: error < 4e-6
    # (the asymmetric profile's kink at d = 0 makes the reference the weaker side)
    prof = StepProfile(*blur)
    e = StraightEdge(6.3, 5.7, angle)
    img = step_image((12, 12), e, prof)
    ref = supersampled((12, 12), lambda x, y: prof.value(e.signed_distance(x, y)), n=128)
    assert np.abs(img - ref).max() < 4e-6


def test_unblurred_step_is_exact_area_fraction():
    # s = 0: the pixel value is the area of the pixel on the bright side.
    # Axis-aligned edge at x = 10.3: pixel 10 covers [9.5, 10.5] -> bright fraction 0.2
    e = StraightEdge(10.3, 0.0, 0.0)
    img = step_image((5, 20), e, StepProfile(0.0, 0.0))
    assert img[2, 10] == pytest.approx(0.2, abs=1e-9)
    assert img[2, 9] == pytest.approx(0.0, abs=1e-12) and img[2, 11] == pytest.approx(1.0, abs=1e-12)
    # 45 degrees through a pixel centre: exactly half of that pixel is bright
    e45 = StraightEdge(10.0, 10.0, np.pi / 4)
    img45 = step_image((21, 21), e45, StepProfile(0.0, 0.0))
    assert img45[10, 10] == pytest.approx(0.5, abs=1e-9)
    # a 45-degree line through (10.5, 10) cuts a right triangle of legs 1/2
    # (area 1/8) from the corner of pixel (row 10, col 11)
    cut = step_image((21, 21), StraightEdge(10.5, 10.0, np.pi / 4), StepProfile(0.0, 0.0))
    assert cut[10, 11] == pytest.approx(1 - 1 / 8, abs=1e-9)


def test_half_value_on_the_edge_and_symmetry():
    prof = StepProfile(1.3, 1.3)
    e = StraightEdge(10.0, 10.0, 0.3)
    img = step_image((21, 21), e, prof)
    # the pixel centred on the edge line: by symmetry exactly 1/2
    assert img[10, 10] == pytest.approx(0.5, abs=1e-12)
    # point symmetry about (10, 10): f(d) + f(-d) = 1
    assert np.abs(img + img[::-1, ::-1] - 1.0).max() < 1e-12


def test_gauss_legendre_quadrature_matches_closed_form():
    """Circles use the quadrature: its error on straight edges bounds its error on circles."""
    prof = StepProfile(0.5, 0.9)
    e = StraightEdge(9.6, 10.2, 0.8)
    x, y = pixel_centres((20, 20))
    fn = lambda xx, yy: prof.value(e.signed_distance(xx, yy))
    exact = step_image((20, 20), e, prof)
    # smooth symmetric profile: plain 10-node rule is at machine precision
    sym = StepProfile(0.5, 0.5)
    q_sym = gauss_legendre_pixel_mean(lambda xx, yy: sym.value(e.signed_distance(xx, yy)), x, y, 10)
    assert np.abs(q_sym - step_image((20, 20), e, sym)).max() < 1e-12
    # the kinked (asymmetric) profile: the composite rule used on edge pixels
    assert np.abs(gauss_legendre_pixel_mean(fn, x, y, 8, cells=8) - exact).max() < 2e-6


def test_circle_total_intensity_is_analytic():
    # profile Phi((R - r)/s) integrates to pi (R^2 + s^2) over the plane
    for r, s in [(8.3, 1.0), (15.0, 0.6), (11.1, 2.0)]:
        c = CircleEdge(24.4, 23.8, r)
        img = step_image((48, 48), c, StepProfile(s, s))
        assert img.sum() == pytest.approx(np.pi * (r * r + s * s), rel=1e-6)


def test_circle_bright_outside_is_complement():
    c_in = CircleEdge(15.2, 14.9, 7.0, True)
    c_out = CircleEdge(15.2, 14.9, 7.0, False)
    p = StepProfile(1.0, 1.0)
    assert np.abs(step_image((30, 30), c_in, p) + step_image((30, 30), c_out, p) - 1).max() < 1e-6


def test_texture_pixel_mean_is_exact():
    amp, kx, ky, ph = [1.0, 0.5], [0.9, -1.3], [0.4, 1.1], [0.3, 2.0]
    img = texture_image((10, 10), amp, kx, ky, ph)
    ref = supersampled((10, 10), lambda x, y: sum(a * np.cos(u * x + v * y + p) for a, u, v, p in zip(amp, kx, ky, ph)), n=128)
    assert np.abs(img - ref).max() < 1e-4
