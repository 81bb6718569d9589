"""kind = "circles_grid": OpenCV's circle grids rendered with exact truth (render/scene/circles_grid.py,
circles_truth.py, circle_conic.py).

Without Mitsuba: OpenCV's layouts; the path-traced polygons keep each circle's area; the image ellipse's centre
in closed form equals the centre of C' = H^-T C H^-1 (to 1e-9 px, tilts 0-60 deg); the truth's centres equal
cv2.projectPoints (1e-9 px); the spec's checks.  With Mitsuba (llvm): a tiny render in board_mode = "frame",
where cv2.findCirclesGrid finds the grid in the truth's order and an edge method's points lie on the exact
outline (within 0.01 px per circle, median)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from edgetruth.errors import InputError
from edgetruth.render.optics.camera import load_camera
from edgetruth.render.scene import circle_conic as cc
from edgetruth.render.scene.circles_grid import POLYGON_SIDES, CirclesGrid
from edgetruth.render.scene.pose import Pose


def test_object_points_are_opencvs_layouts():
    g = CirclesGrid(cols=4, rows=3, spacing_m=0.02, asymmetric=True)
    want = [((2 * j + i % 2) * 0.02, i * 0.02, 0.0) for i in range(3) for j in range(4)]
    np.testing.assert_allclose(g.object_points(), want, atol=1e-15)
    s = CirclesGrid(cols=5, rows=4, spacing_m=0.03, diameter_m=0.015, asymmetric=False)
    np.testing.assert_allclose(s.object_points(), [(j * 0.03, i * 0.03, 0.0) for i in range(4) for j in range(5)],
                               atol=1e-15)
    c = g.centres_local()  # the board frame: centred on the circles' bounding box
    np.testing.assert_allclose(0.5 * (c.min(0) + c.max(0)), 0.0, atol=1e-15)


def test_the_path_polygons_keep_each_circles_area():
    g = CirclesGrid(cols=3, rows=2, diameter_m=0.012)
    q = g.black_quads_local(0.0).reshape(g.n_circles, -1, 4, 3)
    x, y = q[..., 0], q[..., 1]
    area = 0.5 * np.sum(x * np.roll(y, -1, -1) - np.roll(x, -1, -1) * y, axis=-1)  # shoelace per quad
    assert np.all(area > 0)  # wound as the checkerboard's squares (facing the camera)
    np.testing.assert_allclose(area.sum(axis=1), math.pi * g.radius_m ** 2, rtol=1e-12)
    assert q.shape[1] == (POLYGON_SIDES - 2) // 2
    assert g.polygon_error_m() < 1e-4 * g.radius_m


def _poses(n: int = 24):
    rng = np.random.default_rng(48)
    for k in range(n):
        tilt = 60.0 * k / (n - 1)
        a = rng.uniform(0, 2 * np.pi)
        yield Pose(rng.uniform(0.4, 1.2), rng.uniform(-0.05, 0.05), rng.uniform(-0.05, 0.05),
                   tilt * math.cos(a), tilt * math.sin(a), rng.uniform(-30, 30))


def test_closed_form_conic_centre_is_the_centre_of_the_image_conic():
    """c + delta, delta = -(r^2 / Z_c)(R20, R21), images to the centre of H^-T C H^-1 (two derivations)."""
    cam = load_camera()
    g = CirclesGrid()
    z = -1e-5
    worst, biggest = 0.0, 0.0
    for pose in _poses():
        R, t = pose.rotation, pose.translation_m
        c = g.centres_local(z)[:, :2]
        H = cc.plane_homography(cam.K, R, t, z)
        conic = cc.conic_centre(cc.image_conic(H, cc.circle_conics(c, g.radius_m)))
        closed = cc.conic_centre_px(cam.K, R, t, c, g.radius_m, z)
        worst = max(worst, float(np.max(np.abs(conic - closed))))
        biggest = max(biggest, float(np.max(np.abs(cc.centre_bias_px(cam.K, R, t, c, g.radius_m, z)))))
    assert worst < 1e-9
    assert biggest > 0.05  # the bias is there to be measured
    # an untilted board: no bias
    p = Pose(0.8)
    assert np.max(np.abs(cc.centre_bias_px(cam.K, p.rotation, p.translation_m, g.centres_local()[:, :2],
                                           g.radius_m))) < 1e-12


def test_truth_centres_equal_cv2_projectPoints():
    import cv2

    from edgetruth.render.scene.circles_truth import circles_ground_truth

    cam = load_camera()
    g = CirclesGrid()
    for pose in list(_poses(6)):
        gt = circles_ground_truth(cam, pose, g)["circles"]
        pm = gt["pose_model"]
        rvec, _ = cv2.Rodrigues(np.asarray(pm["R"]))
        obj = g.object_points(-gt["standoff_m"])
        got, _ = cv2.projectPoints(obj, rvec, np.asarray(pm["t_m"]), cam.K, cam.dist_coeffs)
        np.testing.assert_allclose(np.asarray(gt["centre_distorted_px"]), got.reshape(-1, 2), rtol=0, atol=1e-9)
        und, _ = cv2.projectPoints(obj, rvec, np.asarray(pm["t_m"]), cam.K, None)
        np.testing.assert_allclose(np.asarray(gt["centre_undistorted_px"]), und.reshape(-1, 2), rtol=0, atol=1e-9)
        np.testing.assert_allclose(np.asarray(gt["bias_undistorted_px"]),
                                   np.asarray(gt["conic_centre_undistorted_px"]) - und.reshape(-1, 2), atol=1e-12)
        # the polylines lie on the distorted circle: each point is the distorted image of a board circle point
        poly = np.asarray(gt["polylines_distorted_px"][5])
        tt = np.asarray(gt["polylines_parameter"][5])
        c = g.centres_local()[5]
        board = np.column_stack([c[0] + g.radius_m * np.cos(2 * np.pi * tt), c[1] + g.radius_m * np.sin(2 * np.pi * tt),
                                 np.full(len(tt), -gt["standoff_m"])])
        np.testing.assert_allclose(poly, cam.project(pose.to_camera(board)), atol=1e-9)


SPEC = """
[spec]
name = "tiny_circles"
camera = "{camera}"
spp = 16
board_mode = "frame"
circles_grid = {{ cols = 4, rows = 5, spacing_m = 0.012, diameter_m = {diameter}, asymmetric = true, margin_m = 0.01 }}

[[group]]
name = "cg"
kind = "circles_grid"
distance_range_cm = [38, 38]
count = 1
tilt_max_deg = 25
irradiance_w_m2 = 0.3
{extra}
"""

CAMERA = """
[camera]
width_px = 240
height_px = 180
pitch_um = 12.0
focal_length_mm = 8.0
f_number = 8.0
focus_distance_m = 0.38
[camera.distortion]
k1 = -0.1
k2 = 0.05
"""


def _spec(tmp_path, diameter=0.011, extra=""):
    from edgetruth.render.dataset.spec import load_spec

    cam = tmp_path / "cam.toml"
    cam.write_text(CAMERA)
    p = tmp_path / "circles.toml"
    p.write_text(SPEC.format(camera=cam, diameter=diameter, extra=extra))
    return load_spec(p)


def test_spec_reads_a_circle_grid_and_refuses_touching_circles_and_bends(tmp_path):
    spec = _spec(tmp_path)
    assert spec.circles_grid == CirclesGrid(4, 5, 0.012, 0.011, True, 0.01)
    assert spec.resolved()["circles_grid"]["asymmetric"] is True
    with pytest.raises(InputError, match="would touch"):
        _spec(tmp_path, diameter=0.017)
    with pytest.raises(InputError, match="circle grid renders flat"):
        _spec(tmp_path, extra="board_bend_mm = [1.0, 0.0, 0.0]")


def test_a_spec_without_circle_grids_hashes_as_before(tmp_path):
    from edgetruth.render.dataset.spec import load_spec

    from edgetruth.render.testing import write_tiny_spec

    spec = load_spec(write_tiny_spec(tmp_path))
    assert "circles_grid" not in spec.resolved()


@pytest.mark.slow
def test_render_findCirclesGrid_order_and_edges_on_the_exact_outline(tmp_path, fast_variant):
    """~10 px circles in focus: the edge method's points (erf4p_fixed11, whose own curvature bias on a circle
    this small is a few 1e-3 px) lie within 0.01 px of the exact outline, median over all circles' points."""
    import cv2

    from edgetruth import locate
    from edgetruth.render.dataset.image import render_job
    from edgetruth.render.scene.outline import OutlineCurve

    spec = _spec(tmp_path)
    job = spec.jobs[0]
    radiance, image, gt = render_job(spec, job)
    c = gt["circles"]
    g8 = np.clip(255.0 * radiance / np.percentile(radiance, 99.5), 0, 255).astype(np.uint8)
    ok, found = cv2.findCirclesGrid(g8, (4, 5), flags=cv2.CALIB_CB_ASYMMETRIC_GRID)
    assert ok
    truth = np.asarray(c["centre_distorted_px"])
    assert np.max(np.linalg.norm(found.reshape(-1, 2) - truth, axis=1)) < 0.5  # the truth's order is OpenCV's
    img = image.astype(np.float64)
    cand = locate.candidates(img)
    cam, pose = spec.camera, job_pose_of(gt)
    curves = spec.circles_grid.dark_curves(cam, pose)
    medians, every = [], []
    for curve in curves:
        poly = curve.polyline()
        box = ((cand.x > poly[:, 0].min() - 3) & (cand.x < poly[:, 0].max() + 3) & (cand.y > poly[:, 1].min() - 3)
               & (cand.y < poly[:, 1].max() + 3))
        near = box.copy()
        near[box] = np.abs(curve.signed_distance(cand.x[box], cand.y[box])) < 1.5
        pts = locate.refine(img, cand.subset(near), "erf4p_fixed11")
        okp = np.asarray(pts.converged, bool)
        d = curve.signed_distance(np.asarray(pts.x)[okp], np.asarray(pts.y)[okp], exact=True)
        assert len(d) > 20
        medians.append(float(np.median(d)))
        every.append(d)
    print("median signed distance per circle (px):", np.round(medians, 4))
    assert abs(float(np.median(np.concatenate(every)))) < 0.01
    assert np.max(np.abs(medians)) < 0.03
    assert isinstance(curves[0], OutlineCurve)


def job_pose_of(gt):
    from edgetruth.render.scene.pose import ExplicitPose

    p = gt["pose"]
    return ExplicitPose.from_rt(np.asarray(p["R_cam_from_board"]), np.asarray(p["t_cam_from_board_m"]))


def test_the_prints_albedos_are_keys_kept_out_of_old_specs_identity():
    """``circle_reflectance`` and ``board_reflectance`` (a twin's print contrast) reach the grid and its truth;
    at their defaults they stay out of ``resolved`` (what a spec's identity hashes), so specs written before them
    keep their identity."""
    from edgetruth.render.scene.circles_grid import circles_grid_from_dict

    plain = circles_grid_from_dict({}, "t")
    assert "circle_reflectance" not in plain.resolved() and "board_reflectance" not in plain.resolved()
    g = circles_grid_from_dict({"circle_reflectance": 0.02, "board_reflectance": 0.7}, "t")
    assert g.resolved()["circle_reflectance"] == 0.02 and g.resolved()["board_reflectance"] == 0.7
    assert g.square_reflectance == 0.02
    assert g.to_dict()["black_reflectance"] == 0.02 and g.to_dict()["white_reflectance"] == 0.7
