"""``edge_mode = "frame"``: every pixel is S_out (1 − c) + S_in c, the shading rendered on a grid of nodes
and interpolated (``edgetruth.render.scene.shading_frame``).

Interpolation (no Mitsuba): the 4-point Lagrange cubic reproduces bicubic polynomials to rounding and the
nodes exactly; a crop interpolates the same values as the whole frame; c's inside/outside part agrees
with the exact coverage beyond the kernel's reach.

Against Mitsuba (llvm): the interpolated shading against the same shading rendered at every pixel, at the
image corner (the strongest falloff) and on the glossy target's highlight, within the two renders'
Monte-Carlo error; the composite of a crop across an outline against the plain path tracer at 65,536
spp (tests/render/scene/test_edge_coverage.py's comparison); a spec through ``render_job``; the Monte-Carlo
noise by distance from the outline (slow).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from edgetruth.render.scene import shading_frame as sf
from edgetruth.render.optics.camera import load_camera
from edgetruth.render.scene.pose import Pose


def _bicubic(rng):
    a = rng.normal(size=(4, 4))

    def f(x, y):  # scaled to the frame, so every term matters
        u, v = np.asarray(x, float) / 1280.0, np.asarray(y, float) / 1024.0
        return sum(a[i, j] * u ** i * v ** j for i in range(4) for j in range(4))
    return f


def test_lagrange_cubic_reproduces_bicubics_and_the_nodes():
    rng = np.random.default_rng(3)
    f = _bicubic(rng)
    xn, yn = sf.axis_nodes(1280, 16), sf.axis_nodes(1024, 16)
    assert xn[0] == 0 and xn[-1] == 1279 and yn[-1] == 1023 and np.all(np.diff(xn) <= 16)
    grid = f(xn[None, :], yn[:, None])
    rows, cols = np.arange(1024), np.arange(1280)
    out = sf.interpolate(grid, yn, xn, rows, cols)
    truth = f(cols[None, :], rows[:, None])
    assert np.max(np.abs(out - truth)) < 1e-11 * np.max(np.abs(truth))
    at_nodes = out[np.ix_(yn, xn)]
    assert np.max(np.abs(at_nodes - grid)) < 1e-13 * np.max(np.abs(grid))
    # a quartic is not reproduced: the test can tell
    q = sf.interpolate((xn[None, :] / 1280.0) ** 4 + 0 * yn[:, None], yn, xn, rows[:1], cols)
    assert np.max(np.abs(q[0] - (cols / 1280.0) ** 4)) > 1e-9


def test_a_crop_reads_the_same_nodes_as_the_frame():
    rng = np.random.default_rng(5)
    xn, yn = sf.axis_nodes(640, 16), sf.axis_nodes(512, 16)
    grid = rng.normal(size=(len(yn), len(xn)))
    full = sf.interpolate(grid, yn, xn, np.arange(512), np.arange(640))
    for x0, y0, w, h in ((0, 0, 40, 30), (600, 480, 40, 32), (123, 77, 61, 45), (631, 500, 9, 12)):
        sx, sy = sf.nodes_for(xn, x0, x0 + w), sf.nodes_for(yn, y0, y0 + h)
        crop = sf.interpolate(grid[sy, sx], yn[sy], xn[sx], np.arange(y0, y0 + h), np.arange(x0, x0 + w))
        np.testing.assert_array_equal(crop, full[y0:y0 + h, x0:x0 + w])


def test_inside_mask_is_the_coverage_beyond_the_kernels_reach():
    from edgetruth.render.scene.edge_band import band_width_px
    from edgetruth.render.scene.edge_coverage import outline_curve, pixel_coverage

    cam = load_camera()
    for target, pose in (("T1", Pose(0.6, 0.03, -0.02, 2.0, -1.5, roll_deg=7.0)),
                         ("T2", Pose(1.2, -0.1, 0.05, -2.0, 1.0, roll_deg=0.0))):
        curve = outline_curve(cam, pose, target, 0.13)
        poly = curve.polyline()
        reach = band_width_px(cam, float(cam.defocus_radius_px(pose.translation_m[2])))
        x0, y0 = (np.floor(poly.min(0)) - 30).astype(int)
        x1, y1 = (np.ceil(poly.max(0)) + 30).astype(int)
        mask = sf.inside_mask(poly, x0, y0, x1 - x0, y1 - y0)
        ys, xs = np.mgrid[y0:y1, x0:x1]
        d = np.abs(curve.signed_distance(xs.astype(float), ys.astype(float)))
        far = d > reach
        rng = np.random.default_rng(1)
        pick = rng.choice(np.flatnonzero(far), 3000, replace=False)
        c = pixel_coverage(cam, curve, xs.ravel()[pick].astype(float), ys.ravel()[pick].astype(float))
        assert np.all((c < 1e-12) | (c > 1.0 - 1e-12))  # 0 or 1 to rounding
        np.testing.assert_array_equal(c > 0.5, mask.ravel()[pick])
        assert 0.2 < mask.mean() < 0.9


@pytest.mark.slow
@pytest.mark.parametrize("where,target", [("corner", "T1"), ("centre", "T4")])
def test_interpolated_shading_is_the_rendered_shading(fast_variant, where, target):
    """S_out at the image corner (falloff, distortion) and S_in of the glossy target (its highlight) at
    0.5 m: nodes every 16 px at 4,096 spp, interpolated, against the same rig rendering every pixel of a
    48 x 48 crop at 4,096 spp -- their difference is the two renders' Monte-Carlo error, no more, and
    its mean is below 1e-4 of the signal."""
    from edgetruth.render.scene.edge_band import BIG_TARGET_M, _park_active, tile_rig
    from edgetruth.render.scene.mitsuba_scene import RenderSettings, TargetRig

    cam = load_camera()
    pose = Pose(0.5, 0.02, -0.01, 2.0, -1.5, roll_deg=4.0)
    x0, y0 = (cam.width_px - 48, cam.height_px - 48) if where == "corner" else (cam.width_px // 2 - 24, 380)
    crop = (x0, y0, 48, 48)
    spp = 4096
    settings = RenderSettings(spp=spp)
    size = BIG_TARGET_M if target == "T4" else 0.13
    direct = TargetRig(cam, settings, target_size_m=size, crop=crop)
    direct.set_state(target, pose, 1.2)
    if target == "T1":
        _park_active(direct, target)
    imgs = [direct.render(s).astype(np.float64) for s in (21, 22)]
    ref = 0.5 * (imgs[0] + imgs[1])
    ref_err = np.abs(imgs[0] - imgs[1]) / 2.0  # the mean's MC error (per pixel, |a - b| / 2)
    rig = tile_rig(cam, settings, size, 64)
    rig.set_state(target, pose, 1.2)
    if target == "T1":
        _park_active(rig, target)
    xn_all, yn_all = sf.axis_nodes(cam.width_px, 16), sf.axis_nodes(cam.height_px, 16)
    sx, sy = sf.nodes_for(xn_all, x0, x0 + 48), sf.nodes_for(yn_all, y0, y0 + 48)
    grids = [sf._render_grid((rig, None), xn_all[sx], yn_all[sy], s, "test")[0] for s in (31, 32)]
    interp = [sf.interpolate(g, yn_all[sy], xn_all[sx], np.arange(y0, y0 + 48), np.arange(x0, x0 + 48))
              for g in grids]
    comp = 0.5 * (interp[0] + interp[1])
    comp_err = np.abs(interp[0] - interp[1]) / 2.0
    diff = comp - ref
    expected = np.mean(ref_err ** 2) + np.mean(comp_err ** 2)
    print(f"{where} {target}: signal {ref.mean():.4g}, rms diff {np.sqrt(np.mean(diff ** 2)):.3g}, "
          f"expected {math.sqrt(expected):.3g}, mean diff {diff.mean():.3g}, range over the crop "
          f"{(ref.max() - ref.min()) / ref.mean():.3g}")
    # |a - b| / 2 estimates the error with E = σ² / 2 per pixel: the bound allows for that and for spread
    assert np.mean(diff ** 2) <= 3.0 * expected
    assert abs(diff.mean()) <= 1e-4 * ref.mean()


@pytest.mark.parametrize("target,z_m", [
    pytest.param("T1", 1.5, marks=pytest.mark.slow), pytest.param("T1", 0.5, marks=pytest.mark.slow),
    pytest.param("T2", 1.5, marks=pytest.mark.slow), pytest.param("T2", 0.5, marks=pytest.mark.slow),
    pytest.param("T4", 1.5, marks=pytest.mark.slow), ("T4", 0.5)])
def test_frame_composite_agrees_with_the_path_tracer(fast_variant, target, z_m):
    from tests.render.scene.test_edge_coverage import assert_agrees_with_reference, composite_against_reference

    r = composite_against_reference(target, z_m, mode="frame")
    print(f"frame {target} {z_m} m: " + ", ".join(f"{k} {v:.4g}" for k, v in r.items()))
    assert_agrees_with_reference(r)


def test_frame_mode_through_render_job(tmp_path, fast_variant):
    """``edge_mode = "frame"`` in a spec: no full-frame render, the JSON says so, and the image agrees with the
    path-traced one to the latter's Monte-Carlo noise (tiny camera: box only, defocused circles)."""
    from edgetruth.render.dataset.image import render_job
    from edgetruth.render.testing import tiny_spec_pair

    frame, reference = tiny_spec_pair(tmp_path, 'edge_mode = "frame"\nshading_step_px = 8', spp=64, edge_spp=4096)
    assert frame.render.edge_mode == "frame" and frame.render.to_dict()["shading_step_px"] == 8
    assert "shading_step_px" not in reference.render.to_dict()
    rad_f, _, gt_f = render_job(frame, frame.jobs[0])
    rad_p, _, _ = render_job(reference, reference.jobs[0])
    band = gt_f["render"]["edge_band"]
    assert band["mode"] == "frame" and band["shading_step_px"] == 8 and band["fractional_pixels"] > 20
    assert band["shading_nodes"]["out"] == len(sf.axis_nodes(64, 8)) * len(sf.axis_nodes(48, 8))
    scale = float(np.percentile(rad_p, 99))
    assert np.max(np.abs(rad_f - rad_p)) < 0.03 * scale  # the path band's own MC noise (4096 spp)
    assert abs(float(np.mean(rad_f - rad_p))) < 1e-3 * scale
    # the checkerboard of the same spec renders as before: the mode is for target images
    assert render_job(frame, frame.jobs[2])[2]["render"]["edge_band"] is None



def test_default_mode_agrees_with_the_path_tracer_on_the_edge_pixels(tmp_path, fast_variant):
    """The benchmark's own spec (``render.bench.DEFAULT_MODE_SPEC``: T1 at 0.5, 1.5 and 2.5 m, default camera, 64
    spp; here one image per distance and 1,024 spp at the edges) naming no edge_mode (the default: "frame") against
    the same spec naming "path", on the same poses, a 48 x 48 crop across a side of each: on the pixels within
    1.5 px of the outline the two differ by the path render's own Monte-Carlo noise (from two path seeds) and no
    more, and the default's own noise there is a small part of it."""
    from dataclasses import replace

    from edgetruth.render.bench import DEFAULT_MODE_SPEC
    from edgetruth.render.dataset.image import render_job, target_pose
    from edgetruth.render.dataset.spec import load_spec
    from edgetruth.render.scene.outline import OutlineCurve

    specs = {}
    for label, mode in (("default", ""), ("path", 'edge_mode = "path"')):
        (tmp_path / label).mkdir()
        p = tmp_path / label / "own_t1.toml"
        p.write_text(DEFAULT_MODE_SPEC.format(mode=mode).replace("count = 3", "count = 1")
                     .replace("edge_spp = 4096", "edge_spp = 1024"))
        specs[label] = load_spec(p)
    default, path = specs["default"], specs["path"]
    assert (default.render.edge_mode, path.render.edge_mode) == ("frame", "path")
    rms = lambda v: float(np.sqrt(np.mean(np.asarray(v, np.float64) ** 2)))  # noqa: E731
    for index in range(3):
        job_d, job_p = default.jobs[index], path.jobs[index]
        assert job_d.render_seed == job_p.render_seed
        pose = target_pose(default, job_d, job_d.camera)
        curve = OutlineCurve(job_d.camera, pose, "square", default.target_size_m)
        x, y = np.round(curve.points(np.array([0.375]))[0]).astype(int)
        crop = (int(x) - 24, int(y) - 24, 48, 48)
        rad_d, _, gt = render_job(default, job_d, crop=crop)
        assert gt["render"]["edge_mode"] == "frame" and gt["render"]["edge_band"]["mode"] == "frame"
        rad_d2 = render_job(default, replace(job_d, render_seed=job_d.render_seed + 1), crop=crop)[0]
        rad_p, _, gt_p = render_job(path, job_p, crop=crop)
        assert "edge_mode" not in gt_p["render"] and gt_p["render"]["edge_band"]["mode"] == "path"
        assert gt_p["pose"] == gt["pose"]
        rad_p2 = render_job(path, replace(job_p, render_seed=job_p.render_seed + 1), crop=crop)[0]
        ys, xs = np.mgrid[crop[1]:crop[1] + 48, crop[0]:crop[0] + 48]
        edge = np.abs(curve.signed_distance(xs.astype(float), ys.astype(float))) < 1.5
        d = (rad_d - rad_p)[edge].astype(np.float64)
        sp, so = ((a - b)[edge] / math.sqrt(2.0) for a, b in ((rad_p, rad_p2), (rad_d, rad_d2)))
        print(f"{job_d.distance_cm:.0f} cm, {d.size} edge pixels: RMS(default - path) {rms(d):.3g}, path's MC "
              f"noise {rms(sp):.3g}, default's own {rms(so):.3g}, mean difference {d.mean():.3g}")
        assert d.size > 60
        # the difference is the two renders' noise, E[d^2] = sigma_path^2 + sigma_own^2 (the estimates' spread allowed)
        assert rms(d) <= 1.3 * math.sqrt(rms(sp) ** 2 + rms(so) ** 2)
        assert abs(d.mean()) <= 4.0 * rms(sp) / math.sqrt(d.size)
        assert rms(so) <= 0.25 * rms(sp)  # the default's edge pixels carry little Monte-Carlo noise

@pytest.mark.slow
@pytest.mark.parametrize("distance_m", [0.5, 1.5, 2.5])
def test_frame_mode_noise_is_below_a_quarter_of_the_dark_noise(fast_variant, distance_m):
    """MC noise on every |d| band, the pixels within 1 px of the outline included, at the study's shading
    (1,024 spp, nodes every 16 px): measured 0.02-0.09 e-, against 2.5 e- (1/4 of the dark noise)."""
    from edgetruth.render.mc_noise import edge_mc_noise
    from edgetruth.render.scene.mitsuba_scene import RenderSettings
    from edgetruth.render.sensor.linear_model import SensorModel

    noise = edge_mc_noise(load_camera(), RenderSettings(spp=64, edge_spp=1024, edge_mode="frame"), distance_m)
    print(f"{distance_m} m: " + "; ".join(f"|d| {lo:g}-{hi:g} px {mc:.3f} e-" for (lo, hi), (mc, _) in noise.items()))
    for band, (mc, _) in noise.items():
        assert 0.0 < mc <= SensorModel().dark_noise_e / 4, band


def test_film_plan_holds_every_node_and_pads_little():
    """Whole 4,096-pixel films, then the remainder in 256-pixel films where those cost fewer samples than one
    more big film (a render call's fixed cost counted in samples)."""
    for n in (1, 255, 257, 1353, 4096, 4097, 5265, 9000):
        for spp in (64, 256, 1024):
            plan = sf._film_plan(n, 4096, 256, spp)
            assert sum(plan) >= n and sum(plan) - n < 4096 and plan[:n // 4096] == [4096] * (n // 4096)
    assert sf._film_plan(1353, 4096, 256, 1024) == [256] * 6  # the quick camera's 41 x 33 nodes
    assert sf._film_plan(5265, 4096, 256, 1024) == [4096] + [256] * 5  # the study camera's 81 x 65
    assert sf._film_plan(3000, 4096, 256, 64) == [4096]  # at few spp the calls' fixed cost wins
