"""Camera spec: intrinsics in OpenCV convention, aperture, field of view, spec loading."""
from __future__ import annotations

import math

import pytest

from edgetruth.errors import InputError
from edgetruth.render.optics.camera import camera_from_dict, load_camera


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


def test_default_camera_is_a_real_one():
    """The shipped lens: in focus MTF50 0.30 cy/px at the centre (0.27-0.33), lower at the corner;
    falloff towards the corners; every parameter in the ground truth."""
    from edgetruth.render.optics.prediction import predicted_mtf50

    cam = load_camera()
    gt = cam.ground_truth()["optics"]
    assert 0.29 < predicted_mtf50(cam) == gt["mtf50_centre_cy_px"] < 0.31
    assert gt["mtf50_corner_cy_px"] < gt["mtf50_centre_cy_px"] - 0.05
    assert gt["relative_illumination"]["corner"] < 0.7
    assert gt["psf"]["aberration_sigma_um"] == cam.aberration_sigma_um == 2.13


def test_optics_keys_parse_and_scale_with_binning():
    cam = camera_from_dict({"aberration_sigma_um": 2.0, "olpf_split_um": 3.0, "velocity_m_s": [0.1, 0, 0],
                            "angular_velocity_deg_s": [0, 5, 0], "natural_vignetting": False, "shading_a2": -0.1})
    assert cam.velocity_m_s == (0.1, 0.0, 0.0) and cam.moving and not cam.natural_vignetting
    from edgetruth.render.optics.psf import psf_params

    p1, p2 = psf_params(cam), psf_params(cam.scaled(2))
    assert p2.sigma_px == pytest.approx(p1.sigma_px / 2) and p2.olpf_px == pytest.approx(p1.olpf_px / 2)
    assert p2.cutoff_cy_px == pytest.approx(2 * p1.cutoff_cy_px)  # p / (λN): in cycles per (bigger) pixel
    with pytest.raises(InputError, match="velocity_m_s"):
        camera_from_dict({"velocity_m_s": [1, 2]})
    with pytest.raises(InputError, match="olpf_split_um"):  # an OLPF alone has no band limit to tabulate
        camera_from_dict({"olpf_split_um": 3.0, "diffraction_wavelength_nm": 0.0})
