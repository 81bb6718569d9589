"""Relative illumination: the thin lens's natural falloff and the lens-shading polynomial.

A uniform emissive wall (radiance 1) fills the view, so every pixel shows the relative
illumination at its sensor position.  The analytic side is computed here by quadrature: the
irradiance from a disk aperture of radius R = f/(2N) at distance f, seen from a sensor point
at distance b off axis, is ∝ ∫_disk cos⁴θ dA, cos θ = f / √(f² + |a − b|²), relative to the
centre.  Mitsuba's own ``thinlens`` (and the plugin with the falloff off) gives a flat image.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from edgetruth.render.optics.camera import load_camera


@pytest.fixture(scope="module", autouse=True)
def variant(fast_variant):
    return fast_variant


def _wall(cam, spp=256, sensor=None):
    import mitsuba as mi

    from edgetruth.render.optics.lens_sensor import sensor_dict

    scene = mi.load_dict({
        "type": "scene", "integrator": {"type": "direct"},
        "sensor": sensor or sensor_dict(cam, {"type": "multijitter", "sample_count": spp}),
        "wall": {"type": "rectangle", "to_world": mi.ScalarTransform4f([[20, 0, 0, 0], [0, -20, 0, 0],
                                                                       [0, 0, -1, 2.0], [0, 0, 0, 1]]),
                 "emitter": {"type": "area", "radiance": {"type": "uniform", "value": 1.0}}}})
    return np.asarray(mi.render(scene, spp=spp), np.float64)[..., 1]


def _relative_illumination(cam, b):
    """∫_disk cos⁴θ dA / (same at b = 0), by Gauss-Legendre in polar coordinates (f = 1)."""
    r = cam.aperture_radius_m / cam.focal_length_m
    b = np.atleast_1d(b)
    if r == 0:
        return 1.0 / (1.0 + b * b) ** 2
    gr, wr = np.polynomial.legendre.leggauss(64)
    gp, wp = np.polynomial.legendre.leggauss(128)
    rho, wrho = 0.5 * r * (gr + 1), 0.5 * r * wr
    phi, wphi = np.pi * (gp + 1), np.pi * wp
    ax = (rho[:, None] * np.cos(phi[None, :])).ravel()
    ay = (rho[:, None] * np.sin(phi[None, :])).ravel()
    w = (wrho[:, None] * rho[:, None] * wphi[None, :]).ravel()

    def omega(bb):
        return np.sum(w / (1.0 + (ax - bb) ** 2 + ay ** 2) ** 2)
    return np.array([omega(v) for v in b]) / omega(0.0)


@pytest.mark.parametrize("f_number", [1.4, 4.0, 0.0])
def test_natural_falloff_matches_the_thin_lens_integral(f_number):
    cam = replace(load_camera().ideal_optics(), natural_vignetting=True, f_number=f_number).scaled(8)
    img = _wall(cam, spp=1024)  # the ray weights vary over the aperture: their Monte-Carlo noise ~1e-3
    cx, cy = cam.principal_point_px
    ys, xs = np.mgrid[0:cam.height_px, 0:cam.width_px]
    b = np.hypot(xs - cx, ys - cy) / cam.fx_px  # sensor offset in units of f (the pixel centre)
    # the pixel's mean of a smooth falloff differs from its centre value by ~(1/24) ∇² RI: < 1e-5 here
    ri = np.interp(b, np.linspace(0, b.max(), 200), _relative_illumination(cam, np.linspace(0, b.max(), 200)))
    err = img - ri
    print(f"f/{f_number}: corner {img[0, 0]:.4f} (analytic {ri[0, 0]:.4f}, cos^4 {1 / (1 + b[0, 0] ** 2) ** 2:.4f}), "
          f"max |error| {np.abs(err).max():.2e}, mean {err.mean():+.1e}")
    assert np.abs(err).max() < 2e-3 and abs(err.mean()) < 2e-4
    assert ri[0, 0] < 0.72  # the falloff is real: 30 % or more at the corner of the default lens


def test_shading_polynomial_multiplies_the_falloff():
    from edgetruth.render.optics.prediction import relative_illumination

    base = replace(load_camera().ideal_optics(), natural_vignetting=True).scaled(8)
    cam = replace(base, shading_a2=-0.2, shading_a4=0.05)
    img, ref = _wall(cam), _wall(base)
    ys, xs = np.mgrid[0:cam.height_px, 0:cam.width_px]
    cx, cy = cam.principal_point_px
    h2 = (np.hypot(xs - cx, ys - cy) / np.hypot(cam.width_px / 2, cam.height_px / 2)) ** 2
    np.testing.assert_allclose(img, ref * (1 - 0.2 * h2 + 0.05 * h2 ** 2), atol=2e-3)
    np.testing.assert_allclose(img, relative_illumination(cam, xs, ys), atol=2e-3)  # the JSON's closed form


def test_without_falloff_the_image_is_flat_as_in_mitsubas_thinlens():
    import mitsuba as mi

    cam = load_camera().ideal_optics().scaled(8)
    flat = _wall(cam)
    assert np.abs(flat - 1.0).max() < 1e-6
    fov = np.degrees(2 * np.arctan(cam.width_px * cam.pitch_m / (2 * cam.focal_length_m)))
    thinlens = {"type": "thinlens", "fov": fov, "fov_axis": "x", "aperture_radius": cam.aperture_radius_m,
                "focus_distance": cam.focus_distance_m,
                "film": {"type": "hdrfilm", "width": cam.width_px, "height": cam.height_px, "rfilter": {"type": "box"}},
                "sampler": {"type": "multijitter", "sample_count": 64}}
    assert np.abs(_wall(cam, 64, sensor=thinlens) - 1.0).max() < 1e-5
    assert mi.variant()
