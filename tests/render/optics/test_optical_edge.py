"""The optical edge: the thin lens's vignetting weight moves a defocused edge off the geometric outline,
by what ``edgetruth.render.optics.optical_edge`` derives.

Renders: a 13 cm emissive square on black through the sensor plugin (radiance 1: a pixel's value is
the weighted share of its rays that hit the square), a crop across the middle of one side, rolled
5° so that the pixels sample the edge-spread function at every phase (ISO 12233's slanted edge).
Each pixel's value is divided by a flat field (the same crop inside a 1 m square), and its signed
distance d to the exact geometric outline (> 0 outside) is known; then

- centroid: ∫ S(d) dd − L over [−L, L] (S the normalised edge-spread, 1 inside) -- the light-deficit
  (area) estimate of where the edge is;
- 50 % level: the root of a cubic fitted to S(d) for |d| < 0.8 px.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from edgetruth.render.optics import optical_edge as oe
from edgetruth.render.optics.camera import load_camera
from edgetruth.render.scene.outline import OutlineCurve
from edgetruth.render.scene.pose import Pose


# --- the analytic side ------------------------------------------------------------------------------
def _brute_force_mean(rho, bx, by, n=801):
    """E_w[a] by a plain Cartesian grid over the disk (independent of the module's quadrature)."""
    g = (np.arange(n) + 0.5) / n * 2 * rho - rho
    ax, ay = np.meshgrid(g, g)
    inside = ax ** 2 + ay ** 2 <= rho * rho
    w = np.where(inside, (1.0 + rho * rho) / (1.0 + (ax + bx) ** 2 + (ay + by) ** 2) ** 2, 0.0)
    return np.array([(w * ax).sum(), (w * ay).sum()]) / w.sum()


@pytest.mark.parametrize("rho,b", [(0.125, (0.13, 0.0)), (0.125, (0.3, -0.2)), (0.36, (0.05, 0.4)),
                                   (0.0625, (0.45, 0.35))])
def test_aperture_centroid_formula_matches_the_numeric_integral(rho, b):
    exact = oe.aperture_mean(rho, b[0], b[1])[0]
    brute = _brute_force_mean(rho, *b)
    first = oe.aperture_mean_first_order(rho, b[0], b[1])[0]
    assert np.allclose(exact, brute, rtol=2e-3, atol=1e-7)
    # first order in a/f: relative error O(ρ²)
    assert np.allclose(first, exact, rtol=2.5 * rho * rho + 1e-3)


def test_held_out_case_closed_form():
    """f 8 mm, R 1 mm, focus 1.5 m, a side 6.5 cm off axis at 0.5 m: the issue's 0.036 px."""
    cam = load_camera()
    v = oe.first_order_offset_px(cam.fx_px, cam.aperture_radius_m, cam.focal_length_m, 0.5, 1.5, 0.13)
    assert v == pytest.approx(0.0355, abs=5e-4)
    curve = OutlineCurve(replace(cam, distortion=(0.0,) * 5), Pose(0.5), "square", 0.13, standoff_m=0.0)
    off = oe.curve_optical_offsets(curve, np.array([0.125, 0.375, 0.625, 0.875]))
    assert np.all(off["centroid"] > 0.033) and np.all(off["centroid"] < 0.037)  # outward on every side
    assert np.all(off["median"] > off["centroid"])  # a tilted disk's median lies beyond its mean


def test_no_offset_in_focus_or_on_axis_and_sign_flips_beyond_focus():
    cam = replace(load_camera(), distortion=(0.0,) * 5)
    ring = OutlineCurve(cam, Pose(1.5), "square", 0.13, standoff_m=0.0)
    assert np.abs(oe.curve_optical_offsets(ring, np.array([0.375]))["centroid"]).max() < 1e-9
    near = oe.curve_optical_offsets(OutlineCurve(cam, Pose(0.5), "square", 0.13, 0.0), np.array([0.375]))
    far = oe.curve_optical_offsets(OutlineCurve(cam, Pose(3.0), "square", 0.13, 0.0), np.array([0.375]))
    assert near["centroid"][0] > 0 > far["centroid"][0]
    # on the axis (b = 0) the weight is symmetric: the circle's point at the principal point row
    tiny = OutlineCurve(cam, Pose(0.5), "circle", 1e-4, standoff_m=0.0)
    assert abs(oe.curve_optical_offsets(tiny, np.array([0.0]))["centroid"][0]) < 1e-4  # b = 6e-5 there


# --- the renders -------------------------------------------------------------------------------------
def measure_side(cam, pose, t_side, spp=2048, half_len=100, half_w=20, seed=3, size_m=0.13):
    """(centroid, 50 % level, predicted centroid, predicted 50 %) in px along the outward normal at the
    middle of the side of the square at parameter ``t_side`` (module docstring)."""
    from edgetruth.render.scene.emissive import render_emissive
    from edgetruth.render.optics.prediction import relative_illumination
    from edgetruth.render.optics.psf import kernel_radius_px, psf_params

    curve = OutlineCurve(cam, pose, "square", size_m, standoff_m=0.0)
    p = curve.points(np.array([t_side]))[0]
    # the crop stays on the side, clear of its corners by the window (8 px) and the PSF's reach: a blurred
    # convex corner is darker than a straight edge at the same distance, and a 200-px crop on a 144-px side
    # (the square at 1.5 m) biased both figures inward by 0.005-0.009 px (the former "in-focus shift")
    ends = curve.points(np.array([t_side - 0.125, t_side + 0.125]))
    half_len = min(half_len, int(0.5 * np.hypot(*(ends[1] - ends[0])) - 8.0 - kernel_radius_px(psf_params(cam)) - 1))
    x0, y0 = int(round(p[0])) - half_w, int(round(p[1])) - half_len
    vertical = int(4 * t_side) % 2 == 1  # right and left sides
    crop = (x0, y0, 2 * half_w, 2 * half_len) if vertical else (int(round(p[0])) - half_len,
                                                                 int(round(p[1])) - half_w, 2 * half_len, 2 * half_w)
    img = render_emissive(cam, [("square", size_m / 2, pose)], spp=spp, seed=seed, crop=crop)
    ys, xs = np.mgrid[crop[1]:crop[1] + crop[3], crop[0]:crop[0] + crop[2]].astype(float)
    d = curve.signed_distance(xs.ravel(), ys.ravel(), step_px=0.05)
    s, xs, ys = img.ravel(), xs.ravel(), ys.ravel()
    # flat field: the same crop inside a square 1 m wide (the lens's falloff, exactly as rendered);
    # the PSF's tails (the Airy pattern's: the edge-spread is still 0.1 % short of its plateau 6-10 px
    # from the edge) are symmetric, so the window [-big, big] sees as much of them on either side
    flat = render_emissive(cam, [("square", 0.5, pose)], spp=spp, seed=seed + 1, crop=crop).ravel()
    s = s / flat
    big = 8.0
    use = np.abs(d) < big
    d, s = d[use], s[use]
    nb = 800
    edges = np.linspace(-big, big, nb + 1)
    k = np.clip(np.digitize(d, edges) - 1, 0, nb - 1)
    cnt = np.bincount(k, minlength=nb)
    mean = np.bincount(k, weights=s, minlength=nb) / np.maximum(cnt, 1)
    mean = np.where(cnt > 0, mean, np.interp(np.arange(nb), np.flatnonzero(cnt), mean[cnt > 0]))
    centroid = float(mean.sum() * (edges[1] - edges[0]) - big)
    near = np.abs(d) < 0.8
    coef = np.polyfit(d[near], s[near] - 0.5, 3)
    roots = np.roots(coef)
    roots = roots[np.isreal(roots)].real
    level50 = float(roots[np.argmin(np.abs(roots))])
    pred = oe.curve_optical_offsets(curve, np.array([t_side]))
    return centroid, level50, float(pred["centroid"][0]), float(pred["median"][0])


@pytest.fixture(scope="module")
def variant(fast_variant):
    return fast_variant


CASES = {  # (camera change, pose, side parameter)
    "held-out 0.5 m, on axis, right side": ({}, Pose(0.5, roll_deg=5.0), 0.375),
    "0.5 m, on axis, top side": ({}, Pose(0.5, roll_deg=5.0), 0.125),
    "0.5 m, 10 cm off axis, right side": ({}, Pose(0.5, 0.10, 0.0, roll_deg=5.0), 0.375),
    "0.5 m, 10 cm off axis, left side": ({}, Pose(0.5, 0.10, 0.0, roll_deg=5.0), 0.875),
    "in focus 1.5 m, on axis, right side": ({}, Pose(1.5, roll_deg=5.0), 0.375),
    "in focus 1.5 m, 30 cm off axis, right side": ({}, Pose(1.5, 0.30, 0.15, roll_deg=5.0), 0.375),
    "f/2, 0.5 m, 10 cm off axis, right side": ({"f_number": 2.0}, Pose(0.5, 0.10, 0.0, roll_deg=5.0), 0.375),
}


@pytest.mark.slow
@pytest.mark.parametrize("case", list(CASES))
def test_derived_displacement_matches_high_spp_renders(variant, case):
    change, pose, t_side = CASES[case]
    cam = replace(load_camera(), **change)
    cen, med, p_cen, p_med = measure_side(cam, pose, t_side)
    print(f"{case}: centroid {cen:+.4f} (predicted {p_cen:+.4f}), 50 % {med:+.4f} (predicted {p_med:+.4f})")
    assert abs(cen - p_cen) <= 0.005
    assert abs(med - p_med) <= 0.005
