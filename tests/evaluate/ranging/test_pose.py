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
