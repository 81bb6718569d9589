"""Calibration, leave-one-image-out and board-plane side lengths on corners of a known camera."""
import cv2
import numpy as np
import pytest

from edgetruth.errors import InputError
from edgetruth.evaluate.board.calibrate.zhang import board_points, calibrate, leave_one_out, side_lengths
from tests.evaluate.board.board_images import grid_model

K = np.array([[800.0, 0, 322.5], [0, 800.0, 241.0], [0, 0, 1]])
DIST = np.array([-0.2, 0.15, 0, 0, 0])
POSES = [((0.2, -0.3, 0.05), (-4.0, -3.5, 14.0)), ((-0.25, 0.1, -0.1), (-3.5, -4.0, 15.0)),
         ((0.1, 0.35, 0.2), (-4.5, -3.0, 13.0)), ((-0.3, -0.2, 0.0), (-3.8, -3.6, 16.0))]


def _views(noise_px=0.0, seed=0):
    model = grid_model(6, 6, side=1.0, pitch=1.5)
    obj = np.c_[model.reshape(-1, 2), np.zeros(model.size // 2)]
    rng = np.random.Generator(np.random.PCG64(seed))
    views = []
    for r, t in POSES:
        p, _ = cv2.projectPoints(obj, np.array(r), np.array(t), K, DIST)
        views.append(p[:, 0].reshape(model.shape) + rng.normal(0, noise_px, model.shape))
    return model, views


def test_exact_corners_give_the_camera_back():
    model, views = _views()
    cal = calibrate(model, views, (640, 480))
    # OpenCV calibrates float32 points: ~1e-5 px of rounding is all that is left
    assert cal.rms_px < 1e-4
    np.testing.assert_allclose(cal.K, K, atol=1e-3)
    assert cal.k1 == pytest.approx(-0.2, abs=1e-5) and cal.k2 == pytest.approx(0.15, abs=1e-4)
    loo = leave_one_out(model, views, (640, 480))
    assert loo["rms_px"] < 1e-4 and len(loo["per_view_rms_px"]) == 4
    lengths = side_lengths(cal, model, views)
    assert np.nanmax(np.abs(np.concatenate([e.ravel() for e in lengths["error"]]))) < 1e-5
    # back-projection is the inverse of the projection
    np.testing.assert_allclose(board_points(cal, 2, views[2]), model, atol=1e-5)


def test_noisy_corners_loo_exceeds_the_fit_and_missing_corners_are_skipped():
    model, views = _views(noise_px=0.2)
    views[1][3] = np.nan  # a square not found
    cal = calibrate(model, views, (640, 480))
    assert 0.1 < cal.rms_px < 0.3
    assert np.isnan(cal.residual_px[1][3]).all() and np.isfinite(cal.residual_px[1][4]).all()
    loo = leave_one_out(model, views, (640, 480))
    assert loo["rms_px"] > cal.rms_px
    lengths = side_lengths(cal, model, views)
    assert np.isnan(lengths["error"][1][3]).all()
    assert abs(np.nanmean(lengths["error"][0])) < 0.01


def test_too_few_views_or_corners():
    model, views = _views()
    with pytest.raises(InputError, match="at least 3 views"):
        leave_one_out(model, views[:2], (640, 480))
    views[0][:] = np.nan
    with pytest.raises(InputError, match="corners each"):
        calibrate(model, views, (640, 480))
