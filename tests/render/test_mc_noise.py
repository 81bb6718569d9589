"""Monte-Carlo noise of the default render settings stays below a quarter of the sensor's dark noise.

Measured as the std of the difference of two renders with different seeds (/√2), in
electrons, at the brightest illumination used (G1, where MC noise in electrons is largest),
on the flat board and on the target interior (3 px away from edges).
"""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from edgetruth.render.camera import load_camera
from edgetruth.render.variants import choose_variant


@pytest.mark.parametrize("target,distance_m", [("T1", 1.2), ("T4", 0.55), ("T4", 1.2)])
def test_mc_noise_below_quarter_dark_noise(target, distance_m):
    from edgetruth.render.ground_truth import target_ground_truth
    from edgetruth.render.mitsuba_scene import RenderSettings, TargetRig
    from edgetruth.render.pose import Pose
    from edgetruth.render.sensor import SensorModel

    choose_variant(announce=lambda s: None)
    cam = load_camera()
    sensor = SensorModel()
    settings = RenderSettings()  # the defaults the specs use
    pose = Pose(distance_m, 0.02, -0.01, 2.0, -1.5)
    gt = target_ground_truth(cam, pose, target, 0.13)
    outline = np.array(gt["outline"]["distorted_px"])
    x0, y0 = (np.floor(outline.min(0)) - 30).astype(int)
    x1, y1 = (np.ceil(outline.max(0)) + 30).astype(int)
    crop = (int(x0), int(y0), int(x1 - x0), int(y1 - y0))
    rig = TargetRig(cam, settings, crop=crop)
    rig.set_state(target, pose, 1.75)
    a, b = rig.render(11), rig.render(12)
    e_per_rad = sensor.qe * sensor.photons_per_radiance(cam.f_number, cam.pitch_um)
    diff_e = (a.astype(np.float64) - b) / np.sqrt(2.0) * e_per_rad
    inside = np.zeros(a.shape, np.uint8)
    cv2.fillPoly(inside, [np.round((outline - [x0, y0]) * 16).astype(np.int32)], 1, shift=4)
    k = np.ones((7, 7), np.uint8)
    target_mask = cv2.erode(inside, k).astype(bool)
    board_mask = ~cv2.dilate(inside, k).astype(bool)
    limit = sensor.dark_noise_e / 4.0
    for name, mask in (("board", board_mask), ("target", target_mask)):
        sigma = diff_e[mask].std()
        print(f"{target} {distance_m} m {name}: MC noise {sigma:.3f} e- (mean {a[mask].mean() * e_per_rad:.0f} e-), limit {limit} e-")
        assert mask.sum() > 1000
        assert sigma < limit, (name, sigma)
