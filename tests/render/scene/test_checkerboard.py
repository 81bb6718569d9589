"""The checkerboard's black squares are black matte print (reflectance 0.04) facing the camera.

(They used to be a mesh without a BSDF -- Mitsuba's default diffuse 0.5 -- wound away from the
camera, so a one-sided BSDF rendered them exactly 0.)"""
from __future__ import annotations

import numpy as np
import pytest

from edgetruth.render.optics.camera import load_camera
from edgetruth.render.scene.pose import Pose
from edgetruth.render.scene.targets import BOARD_REFLECTANCE, CHECKER_BLACK_REFLECTANCE, Checkerboard


@pytest.fixture(scope="module", autouse=True)
def variant(fast_variant):
    return fast_variant


def test_black_squares_reflect_their_albedo():
    from edgetruth.render.scene.mitsuba_scene import CheckerRig, RenderSettings

    cam = load_camera().ideal_optics().scaled(4)
    board = Checkerboard()
    pose = Pose(0.6)
    rig = CheckerRig(cam, RenderSettings(spp=64, edge_spp=0), board)
    rig.set_state(pose, 1.2)
    img = rig.render(1)
    ratios = []
    s = board.square_m
    for j in range(board.rows):
        for i in range(board.cols - 1):
            # centres of square (i, j) and its right neighbour, one black, one white
            loc = np.array([[(i + 0.5 - board.cols / 2) * s, (j + 0.5 - board.rows / 2) * s, 0.0],
                            [(i + 1.5 - board.cols / 2) * s, (j + 0.5 - board.rows / 2) * s, 0.0]])
            (xa, ya), (xb, yb) = cam.project(pose.to_camera(loc))
            a = img[int(round(ya)) - 2:int(round(ya)) + 3, int(round(xa)) - 2:int(round(xa)) + 3].mean()
            b = img[int(round(yb)) - 2:int(round(yb)) + 3, int(round(xb)) - 2:int(round(xb)) + 3].mean()
            black, white = (a, b) if (i + j) % 2 == 0 else (b, a)
            ratios.append(black / white)
    ratios = np.array(ratios)
    print(f"black/white radiance of neighbouring squares: {ratios.mean():.4f} +- {ratios.std():.4f} "
          f"(albedo ratio {CHECKER_BLACK_REFLECTANCE / BOARD_REFLECTANCE})")
    expected = CHECKER_BLACK_REFLECTANCE / BOARD_REFLECTANCE
    assert abs(ratios.mean() / expected - 1) < 0.01
    # neighbours differ in irradiance by their 3 cm offset (light falloff): each within 4 %
    np.testing.assert_allclose(ratios, expected, rtol=0.04)
