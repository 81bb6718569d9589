"""Motion blur: rays spread over the exposure; a moving camera smears an edge into a ramp of
length speed x exposure, centred on the outline at mid-exposure (the ground truth).

A camera translating at v parallel to a fronto-parallel plane at Z moves its image by
fx v T / Z during the exposure T; rotating at ω about its y axis, by fx (1 + x²) ω T at
normalised position x.  The rendered edge (emissive square, pinhole, perfect lens) is fitted
with the exact profile step ⊗ pixel box ⊗ motion box of length L.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.optimize import least_squares

from edgetruth.render.optics.camera import load_camera
from edgetruth.render.scene.pose import Pose

Z_M, HALF_M, EXPOSURE_S = 1.5, 0.065, 0.01


@pytest.fixture(scope="module", autouse=True)
def variant(fast_variant):
    return fast_variant


def _ramp(x, x0, length):
    """step at x0 (dark left) convolved with a unit box and a box of ``length`` (both px)."""
    def r2(u):
        return 0.5 * np.maximum(u, 0.0) ** 2
    a, b = 1.0, max(length, 1e-6)
    u = x - x0
    return (r2(u + a / 2 + b / 2) - r2(u + a / 2 - b / 2) - r2(u - a / 2 + b / 2) + r2(u - a / 2 - b / 2)) / (a * b)


def _fit_left_edge(cam, spp=1024):
    from edgetruth.render.scene.emissive import render_emissive
    from edgetruth.render.scene.ground_truth import target_ground_truth

    pose = Pose(Z_M, 0.0, 0.0)
    gt = target_ground_truth(cam, pose, "T1", 2 * HALF_M, exposure_s=EXPOSURE_S)
    xe = float(np.asarray(gt["outline"]["distorted_px"])[0, 0])  # top-left corner: the left side's x
    crop = (int(xe) - 24, int(cam.principal_point_px[1]) - 16, 48, 32)
    img = render_emissive(cam, [("square", HALF_M, pose)], spp=spp, seed=5, crop=crop, exposure_s=EXPOSURE_S)
    row = img.mean(axis=0)
    x = crop[0] + np.arange(len(row), dtype=float)
    fit = least_squares(lambda p: p[2] * _ramp(x, p[0], p[1]) - row, [xe, 3.0, 1.0])
    return fit.x[0], abs(fit.x[1]), xe, gt


@pytest.mark.parametrize("speed_m_s", [0.3, 0.6])
def test_translation_blur_width_is_speed_times_exposure(speed_m_s):
    cam = replace(load_camera().ideal_optics(), f_number=0.0, distortion=(0.0,) * 5, velocity_m_s=(speed_m_s, 0, 0))
    x0, length, x_mid, gt = _fit_left_edge(cam)
    expected = cam.fx_px * speed_m_s * EXPOSURE_S / Z_M
    start = np.asarray(gt["motion"]["outline_start_distorted_px"])
    end = np.asarray(gt["motion"]["outline_end_distorted_px"])
    print(f"v = {speed_m_s} m/s: blur {length:.4f} px (v T fx / Z = {expected:.4f}), edge at {x0:.4f} "
          f"(mid-exposure outline {x_mid:.4f})")
    assert length == pytest.approx(expected, rel=0.01)
    assert abs(x0 - x_mid) < 0.01  # the truth is the outline at mid-exposure
    np.testing.assert_allclose(np.abs(end - start)[:, 0], expected, rtol=1e-4)  # the recorded motion (Z = 1.5 m - 10 um)


def test_rotation_blur_width_is_angular_speed_times_exposure():
    omega_deg_s = 15.0
    cam = replace(load_camera().ideal_optics(), f_number=0.0, distortion=(0.0,) * 5,
                  angular_velocity_deg_s=(0, omega_deg_s, 0))
    x0, length, x_mid, gt = _fit_left_edge(cam)
    xn = (x_mid - cam.principal_point_px[0]) / cam.fx_px
    expected = cam.fx_px * (1 + xn ** 2) * np.radians(omega_deg_s) * EXPOSURE_S
    print(f"omega = {omega_deg_s} deg/s: blur {length:.4f} px (expected {expected:.4f}), edge {x0:.4f} vs {x_mid:.4f}")
    assert length == pytest.approx(expected, rel=0.01)
    assert abs(x0 - x_mid) < 0.01
