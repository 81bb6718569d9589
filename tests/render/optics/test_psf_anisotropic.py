"""An anisotropic (elliptical) Gaussian aberration: ``aberration_sigma_y_um`` against its analytic MTF.

The PSF table is built from the 2-D OTF sinc(nx) sinc(ny) D(|nu|) exp(-2 pi^2 (sx^2 nx^2 + sy^2 ny^2)); its
interpolated marginals along x and along y (what the renderer samples) must follow the analytic MTF along
each axis, and rendered edges must show it: the e-SFR of a near-vertical edge (normal ~ x) and of a
near-horizontal one (normal ~ y) of the same emissive square, each within 3 % in MTF50 and 0.03 up to
Nyquist of the analytic MTF along its normal (the analytic side written here from textbook forms, as in
test_optics_mtf.py).  Measured (1024 spp): MTF50 within 1 % on both edges.

Off (no ``aberration_sigma_y_um``) nothing changes: the same table to the bit, nothing new in a camera's
identity or JSON.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from edgetruth.errors import InputError
from edgetruth.render.optics.camera import camera_from_dict, load_camera
from edgetruth.render.scene.pose import Pose
from edgetruth.render.optics.psf import PsfParams, psf_params, psf_table, table_otf_x, table_otf_y

NU = np.linspace(0.0, 0.5, 101)
HALF_M = 0.065


def _diffraction(nu, wavelength_nm, f_number, pitch_um):
    if wavelength_nm == 0 or f_number == 0:
        return np.ones_like(nu)
    q = np.clip(nu * wavelength_nm * 1e-3 * f_number / pitch_um, 0, 1)
    return 2 / np.pi * (np.arccos(q) - q * np.sqrt(1 - q * q))


def analytic_mtf(cam, nu, theta):
    """|pixel x diffraction x elliptical Gaussian| along the normal angle theta, in focus, at the centre."""
    nx, ny = nu * np.cos(theta), nu * np.sin(theta)
    sx, sy = cam.aberration_sigma_um / cam.pitch_um, cam.aberration_sigma_y_um / cam.pitch_um
    return np.abs(np.sinc(nx) * np.sinc(ny) * _diffraction(nu, cam.diffraction_wavelength_nm, cam.f_number,
                                                            cam.pitch_um)
                  * np.exp(-2 * np.pi ** 2 * ((sx * nx) ** 2 + (sy * ny) ** 2)))


def _mtf50(curve_fn):
    nu = np.linspace(0, 1.5, 150001)
    m = curve_fn(nu)
    i = np.nonzero(m <= 0.5)[0][0]
    return float(nu[i - 1] + (m[i - 1] - 0.5) * (nu[i] - nu[i - 1]) / (m[i - 1] - m[i]))


def _bare():
    return replace(load_camera().ideal_optics(), distortion=(0.0,) * 5)


def test_table_marginals_follow_the_analytic_mtf_along_each_axis():
    """Gaussian alone: within 2e-3; with diffraction within 0.01 (the table keeps 99 % of the Airy energy and
    renormalises: ``AIRY_TAIL_LOSS``), as the isotropic table does."""
    for cutoff, tol in ((np.inf, 2e-3), (4.8 / (0.55 * 4.0), 1e-2)):
        p = PsfParams(cutoff_cy_px=cutoff, sigma_px=0.3, sigma_growth=0.0, olpf_px=0.0, sigma_y_px=0.9)
        assert p.anisotropic and p.sigma_along(0.0) == pytest.approx(0.3)
        assert p.sigma_along(np.pi / 2) == pytest.approx(0.9)
        t = psf_table(p)
        diff = _diffraction(NU, 550.0, 4.0, 4.8) if np.isfinite(cutoff) else 1.0
        for got, sigma in ((table_otf_x(t, 0, NU), 0.3), (table_otf_y(t, 0, NU), 0.9)):
            want = np.sinc(NU) * diff * np.exp(-2 * np.pi ** 2 * sigma ** 2 * NU ** 2)
            assert np.max(np.abs(got - want)) < tol


def test_off_is_the_isotropic_code_path():
    """sigma_y None or equal to sigma_x: the isotropic table to the bit; no new key in the camera's identity/JSON."""
    base = dict(cutoff_cy_px=2.0, sigma_px=0.5, sigma_growth=0.2, olpf_px=0.0)
    a = psf_table(PsfParams(**base))
    b = psf_table(PsfParams(**base, sigma_y_px=0.5))
    assert a.density.tobytes() == b.density.tobytes()
    cam = load_camera()
    assert "aberration_sigma_y_um" not in cam.to_dict()
    assert "aberration_sigma_y_um" not in cam.ground_truth()["optics"]["psf"]
    assert psf_params(cam).sigma_y_px is None


def test_camera_key_and_checks():
    cam = camera_from_dict({"aberration_sigma_um": 2.0, "aberration_sigma_y_um": 6.0}, name="aniso")
    assert psf_params(cam).sigma_y_px == pytest.approx(6.0 / 4.8)
    gt = cam.ground_truth()
    assert gt["optics"]["psf"]["aberration_sigma_y_um"] == 6.0
    assert gt["optics"]["mtf50_centre_y_cy_px"] < gt["optics"]["mtf50_centre_cy_px"]
    assert cam.to_dict()["aberration_sigma_y_um"] == 6.0
    with pytest.raises(InputError, match="one axis only"):
        camera_from_dict({"aberration_sigma_um": 0.0, "aberration_sigma_y_um": 6.0,
                          "diffraction_wavelength_nm": 0.0}, name="bad")


def _measure(cam, side: str, spp: int = 1024):
    """e-SFR of the left (normal ~ x) or top (normal ~ y) side of a 5-degree-rolled emissive square at the
    image centre; returns (Sfr, normal angle from x)."""
    from edgetruth.evaluate.sfr import esfr
    from edgetruth.render.scene.emissive import render_emissive

    cx, cy = cam.principal_point_px
    z = 1.5
    roll = np.radians(5.0)
    c, s = np.cos(roll), np.sin(roll)
    if side == "left":  # local midpoint (-H, 0) -> (-H c, -H s)
        pose, size = Pose(z, HALF_M * c, HALF_M * s, roll_deg=5.0), (48, 64)
    else:  # top: local (0, -H) -> (H s, -H c)
        pose, size = Pose(z, -HALF_M * s, HALF_M * c, roll_deg=5.0), (64, 48)
    w, h = size
    crop = (int(round(cx)) - w // 2, int(round(cy)) - h // 2, w, h)
    img = render_emissive(cam, [("square", HALF_M, pose)], spp=spp, seed=7, crop=crop)
    r = esfr(img)
    theta = np.radians(r.edge_angle_deg) + (np.pi / 2 if r.transposed else 0.0)
    return r, theta


def test_rendered_edges_show_the_anisotropic_mtf(fast_variant):
    cam = replace(_bare(), f_number=4.0, diffraction_wavelength_nm=550.0, aberration_sigma_um=1.5,
                  aberration_sigma_y_um=4.5)
    m50 = {}
    for side in ("left", "top"):
        r, theta = _measure(cam, side)
        want = _mtf50(lambda nu: analytic_mtf(cam, nu, theta))
        dev = float(np.max(np.abs(r.at(NU) - analytic_mtf(cam, NU, theta))))
        print(f"{side}: MTF50 measured {r.mtf50():.4f} analytic {want:.4f} ({100 * (r.mtf50() / want - 1):+.2f} %), "
              f"max |curve - analytic| {dev:.4f}")
        assert abs(r.mtf50() / want - 1.0) < 0.03
        assert dev < 0.03
        m50[side] = r.mtf50()
    assert m50["top"] < 0.75 * m50["left"]  # the y blur is 3x the x blur
