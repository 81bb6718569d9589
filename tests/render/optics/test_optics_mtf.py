"""Slanted-edge MTF (e-SFR) of rendered edges against the analytic MTF of the configured optics.

An emissive square (radiance 1) on black, rolled 5° so its side is a slanted edge, is rendered
with the full-resolution pitch (4.8 µm) in a crop around the middle of one side; the e-SFR
(``edgetruth.evaluate.sfr``) of the crop must match the product of the optics' factors --
computed HERE from their textbook forms, not with the renderer's ``edgetruth.render.optics.mtf`` --
to 3 % in MTF50 and 0.03 up to Nyquist.  Measured (256-4096 spp): MTF50 within 0.8 %, curves
within 0.012 (docs/optics.md has the table).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.special import j1

from edgetruth.render.optics.camera import load_camera
from edgetruth.render.scene.pose import Pose

NU = np.linspace(0.0, 0.5, 101)
HALF_M = 0.065


@pytest.fixture(scope="module", autouse=True)
def variant(fast_variant):
    return fast_variant


# --- the analytic side, independent of the renderer -------------------------------------
def _diffraction(nu, wavelength_nm, f_number, pitch_um):
    if wavelength_nm == 0 or f_number == 0:
        return np.ones_like(nu)
    q = np.clip(nu * wavelength_nm * 1e-3 * f_number / pitch_um, 0, 1)
    return 2 / np.pi * (np.arccos(q) - q * np.sqrt(1 - q * q))


def _disk(nu, r):
    x = 2 * np.pi * r * nu
    return np.where(x < 1e-9, 1.0, 2 * j1(x) / np.where(x < 1e-9, 1.0, x))


def analytic_mtf(cam, nu, theta, field_h, defocus_px):
    """|pixel x diffraction x Gaussian(sigma(h)) x defocus disk x OLPF| along the normal angle theta."""
    nx, ny = nu * np.cos(theta), nu * np.sin(theta)
    sigma_px = cam.aberration_sigma_um * (1 + cam.aberration_sigma_growth * field_h ** 2) / cam.pitch_um
    d = cam.olpf_split_um / cam.pitch_um
    m = (np.sinc(nx) * np.sinc(ny) * _diffraction(nu, cam.diffraction_wavelength_nm, cam.f_number, cam.pitch_um)
         * np.exp(-2 * np.pi ** 2 * sigma_px ** 2 * nu ** 2) * _disk(nu, defocus_px)
         * np.cos(np.pi * nx * d) * np.cos(np.pi * ny * d))
    return np.abs(m)


def _mtf50(curve_fn):
    nu = np.linspace(0, 1.5, 150001)
    m = curve_fn(nu)
    i = np.nonzero(m <= 0.5)[0][0]
    return float(nu[i - 1] + (m[i - 1] - 0.5) * (nu[i] - nu[i - 1]) / (m[i - 1] - m[i]))


# --- the rendered side -------------------------------------------------------------------
def measure(cam, side_px: tuple[float, float], z_m: float = 1.5, spp: int = 1024, size=(48, 64)):
    """e-SFR of the left side of a rolled emissive square whose side midpoint images near ``side_px``."""
    from edgetruth.evaluate.sfr import esfr
    from edgetruth.render.scene.emissive import render_emissive

    cx, cy = cam.principal_point_px
    roll = 5.0
    # the left side's midpoint, local (-H, 0), lands at side_px (no distortion in these cameras)
    mx, my = (side_px[0] - cx) * z_m / cam.fx_px, (side_px[1] - cy) * z_m / cam.fx_px
    c, s = np.cos(np.radians(roll)), np.sin(np.radians(roll))
    pose = Pose(z_m, mx + HALF_M * c, my + HALF_M * s, roll_deg=roll)
    w, h = size
    crop = (int(round(side_px[0])) - w // 2, int(round(side_px[1])) - h // 2, w, h)
    img = render_emissive(cam, [("square", HALF_M, pose)], spp=spp, seed=7, crop=crop)
    r = esfr(img)
    theta = np.radians(r.edge_angle_deg)  # the normal's angle from x equals the edge's from the columns
    field_h = np.hypot(side_px[0] - cx, side_px[1] - cy) / np.hypot(cam.width_px / 2, cam.height_px / 2)
    return r, theta, float(field_h), float(cam.defocus_radius_px(z_m))


def check(cam, side_px, label, z_m=1.5, spp=1024, size=(48, 64)):
    r, theta, h, dpx = measure(cam, side_px, z_m, spp, size)
    ana = analytic_mtf(cam, NU, theta, h, dpx)
    m50 = _mtf50(lambda nu: analytic_mtf(cam, nu, theta, h, dpx))
    dev = float(np.abs(r.at(NU) - ana).max())
    print(f"{label}: MTF50 measured {r.mtf50():.4f} analytic {m50:.4f} ({100 * (r.mtf50() / m50 - 1):+.2f} %), "
          f"max |curve - analytic| to Nyquist {dev:.4f} (h = {h:.2f}, defocus {dpx:.2f} px)")
    assert abs(r.mtf50() / m50 - 1.0) < 0.03
    assert dev < 0.03
    return r.mtf50(), m50


def _bare():
    return replace(load_camera().ideal_optics(), distortion=(0.0,) * 5)


CENTRE = (639.5 - 0.0, 511.5)


def test_diffraction_only_at_f16():
    cam = replace(_bare(), f_number=16.0, diffraction_wavelength_nm=550.0)
    check(cam, CENTRE, "diffraction f/16", spp=1024, size=(128, 96))  # the Airy tail needs a wide ESF


def test_gaussian_aberration():
    cam = replace(_bare(), f_number=0.0, aberration_sigma_um=3.0)  # pinhole: no diffraction, no defocus
    check(cam, CENTRE, "Gaussian sigma 3 um")


def test_defocus_disk():
    cam = replace(_bare(), f_number=2.0, focus_distance_m=1.0)  # 1.11 px blur disk at 1.5 m
    check(cam, CENTRE, "defocus", spp=4096)


def test_olpf_with_diffraction_and_aberration():
    cam = replace(_bare(), diffraction_wavelength_nm=550.0, aberration_sigma_um=1.0, olpf_split_um=3.0)
    check(cam, CENTRE, "4-dot OLPF 3 um + diffraction f/4 + sigma 1 um")


def test_default_camera_in_focus_centre_and_corner():
    """The default camera (its PSF and falloff; distortion off -- it bends the edge, not the MTF):
    0.27-0.33 cy/px at the centre, lower towards the corner, both as predicted."""
    cam = replace(load_camera(), distortion=(0.0,) * 5)
    centre, centre_pred = check(cam, CENTRE, "default camera, centre")
    assert 0.27 <= centre <= 0.33
    corner, _ = check(cam, (130.0, 110.0), "default camera, near the corner")
    assert corner < centre - 0.03
