"""Whole-chain sanity: noise-free, in-focus, distortion-free renders -> target finding -> dynamic_erf_4p
-> size -> Z = fx S / l must be within 0.1 % of the true distance at every distance (T1 square, T2 circle).

Renders go through the renderer's scene objects (``edgetruth.render.dataset.image.get_rig`` + ``edgetruth.render.scene.ground_truth``)
with a pinhole-like camera (f/10000: defocus < 0.01 px) and a perfect lens (no PSF, no falloff), zero distortion, full resolution, the
radiance image (no sensor noise) and a crop around the target (board margin > target size so the
board-level estimate of ``target_finding`` sees the board).  The pose is fronto-parallel with a 3°
roll (slanted edges sample every subpixel phase); the true model is used (the chain, not the
calibration, is under test).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest


DISTANCES_M = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0)


@pytest.fixture(scope="module", autouse=True)
def variant(fast_variant):
    return fast_variant


class _Identity:
    def __call__(self, image):
        return np.asarray(image, np.float64)

    def valid_mask(self):
        return None

    def undistort_points(self, pts_px):
        return np.asarray(pts_px, np.float64)


def render_clean(target: str, distance_m: float, spp: int = 64, roll_deg: float = 3.0):
    """Radiance crop (float), its (x0, y0) offset and the ground truth of a fronto-parallel target."""
    from edgetruth.render.optics.camera import load_camera
    from edgetruth.render.dataset.image import get_rig
    from edgetruth.render.scene.ground_truth import target_ground_truth
    from edgetruth.render.scene.mitsuba_scene import RenderSettings
    from edgetruth.render.scene.pose import Pose

    cam = replace(load_camera().ideal_optics(), f_number=10000.0, distortion=(0.0,) * 5)
    pose = Pose(distance_m, roll_deg=roll_deg)
    gt = target_ground_truth(cam, pose, target, 0.13)
    gt["camera"] = cam.ground_truth()
    pts = np.asarray(gt["outline"]["distorted_px"])
    side = float(np.ptp(pts[:, 0]))
    m = int(0.6 * side + 16)
    x0 = max(0, int(pts[:, 0].min()) - m)
    y0 = max(0, int(pts[:, 1].min()) - m)
    x1 = min(cam.width_px, int(pts[:, 0].max()) + m + 1)
    y1 = min(cam.height_px, int(pts[:, 1].max()) + m + 1)
    crop = (x0, y0, x1 - x0, y1 - y0)
    rig = get_rig("target", cam, RenderSettings(spp=spp, sampler="multijitter"), 0.13, crop)
    rig.set_state(target, pose, 1.2)
    img = rig.render(seed=7)
    return img.astype(np.float64), (x0, y0), gt, cam


@pytest.mark.slow
@pytest.mark.parametrize("target", ["T1", "T2"])
def test_dynamic_erf_4p_ranges_clean_renders_within_0p1_percent(target):
    from edgetruth.evaluate.calibration import Calibration
    from edgetruth.evaluate.ranging.images import process_image

    errs, pose_errs = [], []
    for d in DISTANCES_M:
        img, (x0, y0), gt, cam = render_clean(target, d)
        K = cam.K - np.array([[0, 0, x0], [0, 0, y0], [0, 0, 0]])  # the crop's own camera matrix
        cal = Calibration(K=K, dist=np.zeros(5), image_size=(cam.width_px, cam.height_px), rms_px=0.0, n_views=0)
        # the truth in crop coordinates (the model floors use it)
        for k in ("distorted_px", "undistorted_px"):
            gt["outline"][k] = (np.asarray(gt["outline"][k]) - [x0, y0]).tolist()
        gt["camera"]["K"] = K.tolist()
        gt.update(spec="sanity", group=target)
        r = process_image(img, gt, cal, _Identity(), ["dynamic_erf_4p"], name=f"{target}_{d}")
        row = r.rows[0]
        assert row["status"] == "ok", row["status"]
        errs.append(row["rel_error_pct"])
        pose_errs.append(100 * abs(row["error_pose_cm"]) / (100 * d))
        assert abs(row["model_floor_cm"]) < 1e-6  # fronto-parallel: the model itself is exact
        assert abs(row["pose_floor_cm"]) < 1e-3  # the pose fit on the true outline (10 um stand-off aside)
        assert abs(row["pose_cal_floor_cm"] - row["pose_floor_cm"]) < 1e-9  # the calibration here is the truth
    print(target, dict(zip(DISTANCES_M, np.round(errs, 4))), dict(zip(DISTANCES_M, np.round(pose_errs, 4))))
    assert max(errs) <= 0.1, dict(zip(DISTANCES_M, errs))
    assert max(pose_errs) <= 0.1, dict(zip(DISTANCES_M, pose_errs))


def test_undistorting_the_points_equals_undistorting_the_image_when_the_model_is_identity():
    """``--undistort points`` refines the raw image and undistorts the points; with an identity model the
    raw image is the undistorted one, so every row is the same as ``--undistort image`` (the plumbing),
    and a mode that is neither is one InputError."""
    from edgetruth.errors import InputError
    from edgetruth.evaluate.calibration import Calibration
    from edgetruth.evaluate.ranging.images import process_image

    img, (x0, y0), gt, cam = render_clean("T1", 1.5)
    K = cam.K - np.array([[0, 0, x0], [0, 0, y0], [0, 0, 0]])
    cal = Calibration(K=K, dist=np.zeros(5), image_size=(cam.width_px, cam.height_px), rms_px=0.0, n_views=0)
    for k in ("distorted_px", "undistorted_px"):
        gt["outline"][k] = (np.asarray(gt["outline"][k]) - [x0, y0]).tolist()
    gt["camera"]["K"] = K.tolist()
    methods = ["dynamic_erf_4p", "ser_cis", "canny_devernay"]
    by_image = process_image(img, gt, cal, _Identity(), methods, undistort="image").rows
    by_points = process_image(img, gt, cal, _Identity(), methods, undistort="points").rows
    keys = ("status", "z_hat_m", "size_px", "z_pose_m", "n_used")
    assert [[r[k] for k in keys] for r in by_points] == [[r[k] for k in keys] for r in by_image]
    assert all(r["status"] == "ok" and abs(r["rel_error_pct"]) < 0.1 for r in by_points)
    with pytest.raises(InputError, match="--undistort 'both'"):
        process_image(img, gt, cal, _Identity(), methods, undistort="both")
