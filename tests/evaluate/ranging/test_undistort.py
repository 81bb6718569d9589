"""Undistortion with a known model: points and images agree with the projection model."""
from __future__ import annotations

import numpy as np
import pytest

from edgetruth.evaluate.ranging.undistort import Undistorter


def test_identity_model_leaves_the_image_unchanged():
    img = np.random.default_rng(0).uniform(0, 100, (40, 50))
    u = Undistorter(np.array([[500.0, 0, 24.5], [0, 500.0, 19.5], [0, 0, 1]]), np.zeros(5), (50, 40))
    assert np.allclose(u(img), img, atol=1e-4)
    assert u.valid_mask(0).all()


def test_points_roundtrip_with_the_renderer_model():
    from edgetruth.render.optics.camera import load_camera

    cam = load_camera()
    u = Undistorter(cam.K, cam.dist_coeffs, (cam.width_px, cam.height_px))
    rng = np.random.default_rng(2)
    pts_cam = np.stack([rng.uniform(-0.3, 0.3, 50), rng.uniform(-0.25, 0.25, 50), np.full(50, 1.0)], 1)
    dist = cam.project(pts_cam, distorted=True)
    ideal = cam.project(pts_cam, distorted=False)
    assert np.abs(u.undistort_points(dist) - ideal).max() < 1e-6


def test_undistorted_image_moves_a_blob_to_its_ideal_position():
    from edgetruth.render.optics.camera import load_camera
    cam = load_camera().scaled(4)
    u = Undistorter(cam.K, cam.dist_coeffs, (cam.width_px, cam.height_px))
    # a Gaussian blob drawn at its distorted position
    p = np.array([[0.35, -0.28, 1.0]])
    xd, yd = cam.project(p, distorted=True)[0]
    xi, yi = cam.project(p, distorted=False)[0]
    yy, xx = np.mgrid[0:cam.height_px, 0:cam.width_px]
    img = np.exp(-((xx - xd) ** 2 + (yy - yd) ** 2) / (2 * 2.0 ** 2))
    out = u(img)
    w = out / out.sum()
    assert (w * xx).sum() == pytest.approx(xi, abs=0.05)
    assert (w * yy).sum() == pytest.approx(yi, abs=0.05)
