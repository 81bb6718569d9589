"""Camera spec: intrinsics in OpenCV convention, aperture, field of view, spec loading."""
from __future__ import annotations

import math

import pytest

from edgetruth.errors import InputError
from edgetruth.render.camera import camera_from_dict, load_camera


def test_default_camera_intrinsics():
    cam = load_camera()
    assert (cam.width_px, cam.height_px, cam.pitch_um, cam.focal_length_mm, cam.f_number) == (1280, 1024, 4.8, 8.0, 4.0)
    assert cam.focus_distance_m == 1.5
    assert cam.fx_px == pytest.approx(8e-3 / 4.8e-6)
    assert cam.principal_point_px == (639.5, 511.5)
    assert cam.aperture_radius_m == pytest.approx(1e-3)  # R = f / (2N)
    assert cam.fov_x_deg == pytest.approx(math.degrees(2 * math.atan(1280 * 4.8e-6 / 16e-3)))
    k1, k2, p1, p2, k3 = cam.distortion
    assert k1 < 0  # barrel
    # mild: the image corner moves by a few to ~20 px
    corner = cam.project([[639.5 / cam.fx_px, 511.5 / cam.fx_px, 1.0]])[0]
    assert 3 < math.hypot(corner[0] - 1279, corner[1] - 1023) < 25


def test_defocus_formula():
    cam = load_camera()
    assert cam.defocus_radius_px(1.5) == 0
    assert cam.defocus_radius_px(0.5) == pytest.approx(cam.fx_px * 1e-3 * (2 - 1 / 1.5))


def test_scaled_keeps_field_of_view():
    cam = load_camera()
    half = cam.scaled(2)
    assert (half.width_px, half.height_px) == (640, 512) and half.fov_x_deg == pytest.approx(cam.fov_x_deg)
    assert half.principal_point_px == (319.5, 255.5)


def test_bad_camera_specs_are_input_errors(tmp_path):
    with pytest.raises(InputError, match="unknown key"):
        camera_from_dict({"focal_mm": 8})
    with pytest.raises(InputError, match="not found"):
        load_camera(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[camera\n")
    with pytest.raises(InputError, match="invalid TOML"):
        load_camera(bad)
