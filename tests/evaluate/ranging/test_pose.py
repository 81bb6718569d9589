"""Pose-based ranging recovers the distance of tilted, off-axis targets exactly from exact outlines,
where Z = fx S / l does not (its model floor)."""
from __future__ import annotations

import numpy as np
import pytest

from edgetruth.evaluate.ranging.pose import circle_conic, circle_pose_distance, sampson_distance, square_pose_distance
from edgetruth.render.optics.camera import Camera
from edgetruth.render.scene.pose import Pose

CAM = Camera(distortion=(0.0,) * 5)
POSES = [Pose(0.6, 0.05, -0.03, 3.0, -2.0, 10.0), Pose(1.7, -0.2, 0.1, -3.0, 3.0, 0.0),
         Pose(2.9, 0.3, 0.25, 2.0, 1.0, -30.0)]


def _square_corners(pose: Pose, side_m: float) -> np.ndarray:
    h = side_m / 2
    local = np.array([[-h, -h, 0], [h, -h, 0], [h, h, 0], [-h, h, 0]])  # TL, TR, BR, BL (board y down)
    return CAM.project(pose.to_camera(local), distorted=False)


@pytest.mark.parametrize("pose", POSES)
def test_square_pose_distance_is_exact_on_exact_corners(pose):
    z = square_pose_distance(_square_corners(pose, 0.13), CAM.K, 0.13)
    assert z == pytest.approx(pose.distance_m, rel=1e-9)


@pytest.mark.parametrize("pose", POSES)
def test_circle_pose_distance_is_exact_on_exact_outline(pose):
    t = np.linspace(0, 2 * np.pi, 360, endpoint=False)
    local = np.c_[0.065 * np.cos(t), 0.065 * np.sin(t), np.zeros_like(t)]
    px = CAM.project(pose.to_camera(local), distorted=False)
    z = circle_pose_distance(px[:, 0], px[:, 1], CAM.K, 0.13)
    assert z == pytest.approx(pose.distance_m, rel=1e-7)


def test_the_pinhole_size_model_is_biased_where_the_pose_is_not():
    """The reason for the pose estimate: 3 degrees of tilt and an off-axis position bias Z = fx S / l."""
    pose = POSES[2]
    c = _square_corners(pose, 0.13)
    l_px = np.mean([np.linalg.norm(c[1] - c[0]), np.linalg.norm(c[2] - c[3])])
    z_pinhole = CAM.fx_px * 0.13 / l_px
    assert abs(z_pinhole - pose.distance_m) > 1e-3
    assert abs(square_pose_distance(c, CAM.K, 0.13) - pose.distance_m) < 1e-9


def test_sampson_distance_is_the_geometric_distance_near_the_conic():
    pose = POSES[0]
    C = circle_conic([pose.lateral_x_m, pose.lateral_y_m, pose.distance_m, 0.0, 0.0], CAM.K, 0.065)
    cx = CAM.K[0, 2] + CAM.fx_px * pose.lateral_x_m / pose.distance_m
    cy = CAM.K[1, 2] + CAM.fx_px * pose.lateral_y_m / pose.distance_m
    r = CAM.fx_px * 0.065 / pose.distance_m
    ang = np.linspace(0, 2 * np.pi, 7)
    for off in (-0.3, 0.2):
        d = sampson_distance(C, cx + (r + off) * np.cos(ang), cy + (r + off) * np.sin(ang))
        np.testing.assert_allclose(d, off, atol=1e-3)


@pytest.mark.parametrize("target", ["T1", "T2"])
def test_calibrated_pose_floor_is_the_calibrations_share(target):
    """The true outline seen through the calibrated camera (``pose_cal_floor_cm``): with the true model it
    is the true pose distance; with focal lengths (1 + eps) too long, a fronto-parallel target (off axis,
    rolled) reads exactly (1 + eps) too far, since scaling every normalised image point by 1/(1 + eps) is
    the image of the same target at (1 + eps) Z."""
    from edgetruth.evaluate.ranging.images import calibrated_pose_distance, true_pose_distance
    from edgetruth.evaluate.ranging.undistort import Undistorter
    from edgetruth.render.optics.camera import load_camera
    from edgetruth.render.scene.ground_truth import target_ground_truth

    cam = load_camera()  # the study camera, with its distortion
    size = (cam.width_px, cam.height_px)
    gt = target_ground_truth(cam, Pose(1.7, 0.12, -0.06, 0.0, 0.0, 10.0), target, 0.13)
    gt["camera"] = cam.ground_truth()
    dist = np.asarray(gt["camera"]["dist_coeffs_opencv"], float)
    K = np.asarray(gt["camera"]["K"], float)
    z_true = true_pose_distance(gt)
    assert z_true == pytest.approx(1.7, rel=1e-5)
    assert calibrated_pose_distance(gt, Undistorter(K, dist, size), K) == pytest.approx(z_true, rel=1e-9)
    eps = 1e-3
    K_long = K.copy()
    K_long[0, 0] *= 1 + eps
    K_long[1, 1] *= 1 + eps
    z = calibrated_pose_distance(gt, Undistorter(K_long, dist, size), K_long)
    # the distortion model is applied to the normalised coordinates of K_long: the outline's distorted
    # image is undistorted slightly wrong, so exact only to the distortion's change over eps of the field
    assert z / z_true - 1 == pytest.approx(eps, rel=5e-3)
    flat = Undistorter(K_long, np.zeros(5), size)
    gt_flat = target_ground_truth(load_camera().ideal_optics(), Pose(1.7, 0.12, -0.06, 0.0, 0.0, 10.0), target, 0.13)
    gt_flat["camera"] = cam.ground_truth()
    gt_flat["outline"]["distorted_px"] = gt_flat["outline"]["undistorted_px"]
    z_flat = calibrated_pose_distance(gt_flat, flat, K_long)
    assert z_flat / true_pose_distance(gt_flat) - 1 == pytest.approx(eps, rel=1e-6)


def test_optics_share_reads_the_optical_edge_through_the_true_camera():
    """``optics_pose_distance``: with no displacement it is the true distance; with a uniform outward
    displacement d (px) on a fronto-parallel square of side l px the target reads larger, Z (1 - 2 d / l)
    to first order; without an optical edge in the truth it is NaN."""
    from edgetruth.evaluate.ranging.images import optics_pose_distance, true_pose_distance
    from edgetruth.render.optics.camera import load_camera
    from edgetruth.render.scene.ground_truth import target_ground_truth

    cam = load_camera()
    gt = target_ground_truth(cam, Pose(1.2, 0.05, 0.03, 0.0, 0.0, 4.0), "T1", 0.13)
    gt["camera"] = cam.ground_truth()
    n = len(gt["outline"]["polyline_distorted_px"])
    gt["outline"]["optical_edge"] = {"offset_px": [0.0] * n, "offset_50_px": [0.0] * n}
    z_true = true_pose_distance(gt)  # the target's face: 10 um in front of the board
    assert optics_pose_distance(gt) == pytest.approx(z_true, rel=1e-8)
    d = 0.05
    gt["outline"]["optical_edge"] = {"offset_px": [d] * n, "offset_50_px": [d] * n}
    l_px = cam.K[0, 0] * 0.13 / 1.2
    assert optics_pose_distance(gt) / z_true - 1 == pytest.approx(-2 * d / l_px, rel=0.03)
    del gt["outline"]["optical_edge"]
    assert np.isnan(optics_pose_distance(gt))


def test_raw_pose_of_exact_points_is_the_calibrated_floor():
    """``raw_pose_distance`` on points exactly on the raw image's outline, with their outward normals, is
    the pose of the true outline through that camera (the calibration floor), through the size fits."""
    from edgetruth.evaluate.ranging.images import calibrated_pose_distance, raw_pose_distance
    from edgetruth.evaluate.ranging.undistort import Undistorter
    from edgetruth.render.optics.camera import load_camera
    from edgetruth.render.optics.optical_edge import outward_normals
    from edgetruth.render.scene.ground_truth import target_ground_truth

    cam = load_camera()
    gt = target_ground_truth(cam, Pose(2.1, -0.1, 0.04, 2.0, -1.0, 7.0), "T1", 0.13)
    gt["camera"] = cam.ground_truth()
    K = np.asarray(gt["camera"]["K"], float)
    K_cal = K * [[1.0004, 1, 1], [1, 1.0004, 1], [1, 1, 1]]
    und = Undistorter(K_cal, np.asarray(gt["camera"]["dist_coeffs_opencv"], float), (cam.width_px, cam.height_px))
    p = np.asarray(gt["outline"]["polyline_distorted_px"], float)
    nrm = outward_normals(p, np.roll(p, -1, axis=0) - np.roll(p, 1, axis=0))
    z_raw = raw_pose_distance("square", 0.13, p[:, 0], p[:, 1], nrm[:, 0], nrm[:, 1], und, K_cal)
    assert z_raw == pytest.approx(calibrated_pose_distance(gt, und, K_cal), rel=1e-6)
