"""Rendered geometry against projected ground truth (pinhole, no distortion, emissive on black)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from edgetruth.render.variants import choose_variant


@pytest.fixture(scope="module", autouse=True)
def variant():
    return choose_variant(announce=lambda s: None)


@pytest.mark.parametrize("distance_m", [0.5, 1.5, 3.0])
def test_square_width_and_centroid(distance_m):
    from edgetruth.render.optics.camera import load_camera
    from edgetruth.render.scene.emissive import centroid, render_emissive
    from edgetruth.render.scene.pose import Pose

    # default optics at 1/4 resolution (320x256, same field of view), pinhole
    cam = load_camera().ideal_optics().scaled(4)  # geometry: no PSF, no falloff
    cam = replace(cam, f_number=0.0, distortion=(0.0,) * 5)
    size_m = 0.13
    pose = Pose(distance_m, lateral_x_m=0.013 * distance_m, lateral_y_m=-0.007 * distance_m)
    img = render_emissive(cam, [("square", size_m / 2, pose)], spp=256, seed=3)
    expected_width = cam.fx_px * size_m / distance_m
    width = np.sqrt(img.sum())  # fronto-parallel square: area = width²
    cx, cy = centroid(img)
    ex, ey = cam.project(pose.translation_m[None], distorted=False)[0]
    assert abs(width - expected_width) < 0.01, (width, expected_width)
    assert abs(cx - ex) < 0.01 and abs(cy - ey) < 0.01, ((cx, cy), (ex, ey))


def test_crop_window_matches_full_frame():
    """A cropped render is the same window of the full film (the sensor honours crop offsets)."""
    from edgetruth.render.optics.camera import load_camera
    from edgetruth.render.scene.emissive import centroid, render_emissive
    from edgetruth.render.scene.pose import Pose

    cam = load_camera().ideal_optics().scaled(4)  # geometry: no PSF, no falloff
    pose = Pose(1.0, 0.05, 0.03)
    crop = (150, 120, 60, 50)
    img = render_emissive(cam, [("disk", 0.02, pose)], spp=256, seed=1, crop=crop)
    cx, cy = centroid(img, crop[0], crop[1])
    ex, ey = cam.project(pose.translation_m[None])[0]
    # a small disk under mild distortion: centroid ≈ projected centre (bias ≪ 0.01 px)
    assert abs(cx - ex) < 0.02 and abs(cy - ey) < 0.02, ((cx, cy), (ex, ey))
