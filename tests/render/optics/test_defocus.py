"""Thin-lens defocus: the blur of a small emissive dot is a uniform disk of radius fx·R·|1/z_f − 1/z|."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from edgetruth.render.optics.camera import load_camera
from edgetruth.render.variants import choose_variant


@pytest.mark.parametrize("distance_m", [0.5, 0.8, 3.0])
def test_blur_radius(distance_m):
    from edgetruth.render.scene.emissive import render_emissive, second_moments
    from edgetruth.render.scene.pose import Pose

    choose_variant(announce=lambda s: None)
    # default geometry with a perfect lens opened to f/1.4 for blur of several pixels; no distortion and no
    # PSF (isolates defocus)
    cam = replace(load_camera().ideal_optics(), f_number=1.4, distortion=(0.0,) * 5)
    expected_r = cam.defocus_radius_px(distance_m)
    dot_r_m = 1e-3 * distance_m  # 1.7 px: big enough that most samples hit it (low MC noise)
    dot_r_px = cam.fx_px * dot_r_m / distance_m
    half = int(expected_r + dot_r_px + 4)
    c = int(cam.width_px / 2)
    crop = (c - half, int(cam.height_px / 2) - half, 2 * half, 2 * half)
    img = render_emissive(cam, [("disk", dot_r_m, Pose(distance_m))], spp=4096, seed=2, crop=crop)
    vx, vy = second_moments(img)
    # image = dot ⊛ blur disk ⊛ pixel box; a uniform disk of radius ρ has per-axis variance ρ²/4
    var_blur = 0.5 * (vx + vy) - dot_r_px ** 2 / 4 - 1.0 / 12.0
    measured_r = 2.0 * np.sqrt(var_blur)
    assert expected_r > 1.0
    assert abs(measured_r / expected_r - 1.0) < 0.05, (measured_r, expected_r)
