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


@pytest.mark.parametrize("t", [-0.03, 0.03, 0.1])
def test_bilinear_resampling_moves_level_fits_less_than_the_edge(t):
    """Why Table 13c has a resampling share.  Resampling at a fractional offset t (what the undistortion's
    remap does where its map offset is t) convolves the image with the 2-tap kernel (1 - t, t): the edge's
    centroid moves by t, its 50 % level by less.  A moment method (SER-CIS) follows the centroid; the ERF
    fits, which find the level, lag 12-16 % of t behind it (sigma 0.7 px), on the side the map samples from."""
    import cv2

    from edgetruth import locate
    from edgetruth.render.edge_truth import StraightEdge
    from edgetruth.render.synthetic.scenarios import render_edge_image

    edge = StraightEdge(48.3, 48.0, np.deg2rad(2.0))
    img = render_edge_image((96, 96), edge, 1000.0, 24000.0, 0.7).astype(np.float32)
    yy, xx = np.mgrid[0:96, 0:96].astype(np.float32)
    out = cv2.remap(img, xx + np.float32(t), yy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    moved = StraightEdge(edge.x0 - t, edge.y0, edge.angle_rad)  # where the image's content now is
    cand = locate.candidates(out.astype(np.float64))
    cand = cand.subset((np.abs(moved.signed_distance(cand.x, cand.y)) < 1.5) & (cand.y > 15) & (cand.y < 80))

    def lag(method):  # the points' mean error over t: 0 follows the edge, 1 stays behind
        p = locate.refine(out.astype(np.float64), cand, method)
        return float(np.mean(moved.signed_distance(p.x, p.y))) / t

    assert abs(lag("ser_cis")) < 0.03
    assert 0.08 < lag("erf4p_fixed11") < 0.20
    assert 0.06 < lag("erf2p_fixed9") < 0.16
