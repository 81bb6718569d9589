"""The scene of a digital twin of Zhang's 1998 calibration photos, done generally: a camera with a
stated K (free principal point, fx != fy), a board of many squares from a model file or a pattern,
explicit poses, and the shipped twin (``scenes/zhang1998_twin.toml``, ``assets/cameras/zhang1998.toml``).

Measured here (2 shared cores, llvm_ad_rgb): Zhang's published K, k1, k2 and five poses project his
Model.txt onto his own measured corners (dataN.txt) with a 2-D RMS of 0.347, 0.231, 0.540, 0.236 and
0.211 px (per axis 0.245, 0.164, 0.382, 0.167, 0.149 px; 0.336 px over all five, as OpenCV's
calibration RMS of 0.337 px on his corners); a rendered board's square sides lie on the exact
distorted outline to a mean of < 0.001 px, SD 0.005 px at 64 spp (0.0024 px at 256 spp: Monte-Carlo
noise, falling as spp^-1/2).
"""
from __future__ import annotations

import json
import re
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest

from edgetruth.errors import InputError
from edgetruth.render.optics.camera import Camera, camera_from_dict, load_camera
from edgetruth.render.scene.outline import OutlineCurve
from edgetruth.render.scene.pose import ExplicitPose, Pose
from edgetruth.render.dataset.spec import load_spec
from edgetruth.render.scene.targets import TARGET_STANDOFF_M, SquareBoard
from edgetruth.resources import real_set
from tests.support.side_offsets import side_offsets

ROOT = Path(__file__).resolve().parents[3]
INCH = 0.0254


def _zhang():
    """Zhang's published calibration: K (with skew), (k1, k2), poses [(R, t_inches)], model (64, 4, 2) inches."""
    d = real_set("zhang1998")
    v = [float(x) for x in (d / "calibration-result-zhang-withdistortion.txt").read_text().split()]
    alpha, gamma, beta, u0, v0 = v[:5]
    poses = np.array(v[7:]).reshape(5, 4, 3)
    return {"K": np.array([[alpha, gamma, u0], [0.0, beta, v0], [0.0, 0.0, 1.0]]), "k": tuple(v[5:7]),
            "poses": [(p[:3], p[3]) for p in poses], "model": np.loadtxt(d / "Model.txt").reshape(-1, 4, 2),
            "data": [np.loadtxt(d / f"data{i}.txt").reshape(-1, 4, 2) for i in range(1, 6)]}


def _rms(a, b) -> tuple[float, float]:
    """(2-D RMS distance, per-axis RMS) of two point sets (px)."""
    e = np.asarray(a, float).reshape(-1, 2) - np.asarray(b, float).reshape(-1, 2)
    return float(np.sqrt((e ** 2).sum(1).mean())), float(np.sqrt((e ** 2).mean()))


# --- the camera: a stated K ------------------------------------------------------------------------
def test_stated_intrinsics_project_like_opencv():
    """fx != fy, an off-centre principal point and all five distortion terms: Camera.project and
    cv2.projectPoints agree to 1e-9 px; undistort_pixels inverts the distortion; binning keeps K consistent."""
    cam = Camera.from_intrinsics(1500.0, 1650.0, 600.3, 480.7, width_px=1280, height_px=1024,
                                 distortion=(-0.2, 0.1, 0.001, -0.002, 0.01))
    assert cam.K.tolist() == [[1500.0, 0.0, 600.3], [0.0, 1650.0, 480.7], [0.0, 0.0, 1.0]]
    assert cam.focal_length_mm == pytest.approx(1500.0 * 4.8e-3) and cam.stated_intrinsics
    rng = np.random.default_rng(0)
    pts = np.c_[rng.uniform(-0.4, 0.4, (2000, 2)), rng.uniform(1.0, 2.0, 2000)]
    ref, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), cam.K, cam.dist_coeffs)
    np.testing.assert_allclose(cam.project(pts), ref.reshape(-1, 2), rtol=0, atol=1e-9)
    np.testing.assert_allclose(cam.undistort_pixels(cam.project(pts)), cam.project(pts, distorted=False), atol=1e-8)
    half = cam.scaled(2)  # the same rays through 2x2-binned pixels: x_half = (x + 1/2) / 2 - 1/2
    np.testing.assert_allclose(half.project(pts), (cam.project(pts) + 0.5) / 2 - 0.5, atol=1e-9)
    assert cam.ground_truth()["fy_px"] == 1650.0 and cam.ground_truth()["cx_px"] == 600.3
    # the default camera is untouched: derived K, and nothing new in its identity
    default = load_camera()
    assert default.fy_px == default.fx_px and default.principal_point_px == (639.5, 511.5)
    assert not default.stated_intrinsics and "focal_x_px" not in default.to_dict()


def test_zhang_camera_states_his_k():
    cam = load_camera("zhang1998")
    z = _zhang()
    assert (cam.fx_px, cam.fy_px, *cam.principal_point_px) == (z["K"][0, 0], z["K"][1, 1], z["K"][0, 2], z["K"][1, 2])
    assert cam.distortion == (*z["k"], 0.0, 0.0, 0.0) and (cam.width_px, cam.height_px) == (640, 480)
    assert cam.focal_length_mm == pytest.approx(832.5 * 7.5e-3)  # f = fx * pitch: a "6 mm lens"


def _clip_area(poly: np.ndarray, x: float, y: float) -> float:
    """Exact area of polygon ``poly`` (N, 2) inside the pixel [x - 1/2, x + 1/2] x [y - 1/2, y + 1/2]
    (Sutherland-Hodgman against the four sides, then the shoelace formula)."""
    pts = poly
    for axis, bound, keep_below in ((0, x - 0.5, False), (0, x + 0.5, True), (1, y - 0.5, False), (1, y + 0.5, True)):
        if not len(pts):
            return 0.0
        nxt = np.roll(pts, -1, axis=0)
        inside = pts[:, axis] <= bound if keep_below else pts[:, axis] >= bound
        inside_n = np.roll(inside, -1)
        out = []
        for p, q, a, b in zip(pts, nxt, inside, inside_n):
            if a:
                out.append(p)
            if a != b:
                s = (bound - p[axis]) / (q[axis] - p[axis])
                out.append(p + s * (q - p))
        pts = np.asarray(out)
    if len(pts) < 3:
        return 0.0
    return 0.5 * abs(float(np.sum(pts[:, 0] * np.roll(pts[:, 1], -1) - np.roll(pts[:, 0], -1) * pts[:, 1])))


def test_rendered_square_matches_the_projection_with_a_stated_k(fast_variant):
    """An emissive square through a pinhole with fx/fy = 1.1, the principal point 37 px right of and 21 px
    above the centre, and strong distortion: each side's rendered coverage, summed along the side,
    puts the edge within 0.005 px of the exactly projected (distorted) outline (256 spp, crop)."""
    from edgetruth.render.scene.emissive import render_emissive

    cam = Camera.from_intrinsics(400.0, 440.0, 196.5, 98.5, width_px=320, height_px=240,
                                 distortion=(-0.15, 0.05, 0.001, -0.0008, 0.0)).ideal_optics()
    cam = replace(cam, f_number=0.0)  # pinhole: the pixel box alone
    pose = Pose(0.5, 0.02, -0.01, 12.0, -8.0, 20.0)
    curve = OutlineCurve(cam, pose, "square", 0.08, standoff_m=0.0)  # the emissive rectangle lies at z = 0
    poly = curve.polyline(step_px=0.5)  # chords within 1e-4 px of the slightly bowed sides
    x0, y0 = np.floor(poly.min(0) - 3).astype(int)
    x1, y1 = np.ceil(poly.max(0) + 3).astype(int)
    crop = (int(x0), int(y0), int(x1 - x0 + 1), int(y1 - y0 + 1))
    img = render_emissive(cam, [("square", 0.04, pose)], spp=256, seed=5, crop=crop)
    offsets = []
    for k in range(4):
        t_side = (k + np.linspace(0.1, 0.9, 400)) / 4
        side = curve.points(t_side)
        ys, xs = (a.ravel() for a in np.mgrid[y0:y1 + 1, x0:x1 + 1])
        d = np.hypot(xs[:, None] - side[None, :, 0], ys[:, None] - side[None, :, 1])
        j = d.argmin(1)
        near = (d.min(1) <= 1.5) & (j > 0) & (j < len(side) - 1)  # near this side, its foot inside the middle
        sum_r = float(img[ys[near] - y0, xs[near] - x0].sum())
        sum_e = sum(_clip_area(poly, xx, yy) for xx, yy in zip(xs[near], ys[near]))
        length = float(np.sum(np.linalg.norm(np.diff(side, axis=0), axis=1)))
        offsets.append((sum_r - sum_e) / length)  # > 0: the rendered square reaches further out
    print("edge offsets of the rendered square (px, outward):", np.round(offsets, 5))
    assert np.max(np.abs(offsets)) < 0.005
    # and the square is where K puts it: 37 px off the centre in x, scaled by fy in y
    ys, xs = np.mgrid[0:img.shape[0], 0:img.shape[1]]
    area = img.sum()
    centroid = np.array([(xs * img).sum() / area + x0, (ys * img).sum() / area + y0])
    ring = curve.points(np.linspace(0, 1, 4001)[:-1])
    a2 = ring[:, 0] * np.roll(ring[:, 1], -1) - np.roll(ring[:, 0], -1) * ring[:, 1]
    c = np.array([((ring[:, 0] + np.roll(ring[:, 0], -1)) * a2).sum(),
                  ((ring[:, 1] + np.roll(ring[:, 1], -1)) * a2).sum()]) / (3.0 * a2.sum())
    np.testing.assert_allclose(centroid, c, atol=0.01)
    assert area == pytest.approx(0.5 * abs(a2.sum()), rel=2e-4)


# --- Zhang's poses --------------------------------------------------------------------------------
def test_zhang_calibration_reproduces_his_corners():
    """X_cam = R X_model + t with his K, k1, k2 projects Model.txt onto dataN.txt: RMS per image
    0.21-0.54 px (2-D; per axis 0.15-0.38 px), 0.336 px over all five."""
    z = _zhang()
    per, all_e = [], []
    for (r, t), data in zip(z["poses"], z["data"]):
        xc = np.c_[z["model"].reshape(-1, 2), np.zeros(256)] @ r.T + t
        x, y = xc[:, 0] / xc[:, 2], xc[:, 1] / xc[:, 2]
        r2 = x * x + y * y
        radial = 1 + z["k"][0] * r2 + z["k"][1] * r2 * r2
        px = (np.c_[x * radial, y * radial, np.ones_like(x)] @ z["K"].T)[:, :2]
        per.append(_rms(px, data))
        all_e.append(px - data.reshape(-1, 2))
    rms2d = np.array([p[0] for p in per])
    axis = np.array([p[1] for p in per])
    total = float(np.sqrt((np.concatenate(all_e) ** 2).sum(1).mean()))
    print("2-D RMS per image", rms2d.round(3), "per axis", axis.round(3), f"all {total:.3f}")
    assert np.all(axis < 0.5) and np.all(rms2d < 0.55) and 0.3 < total < 0.35
    assert np.sum(rms2d < 0.5) == 4  # image 3 (24 deg tilt) is the worst: 0.54 px 2-D, 0.38 px per axis


def test_twin_truth_is_his_projection():
    """The twin's ground-truth corners: exactly (1e-9 px) cv2.projectPoints of the model with the spec's
    camera and pose (the printed plane 10 um in front of the plate); within 0.015 px of Zhang's own
    R, t (his R made orthonormal; the 10 um stand-off) and within 0.07 px of his K with skew; his dataN
    corners within the RMS above."""
    from edgetruth.render.scene.ground_truth import squares_ground_truth

    z = _zhang()
    spec = load_spec("zhang1998_twin")
    assert spec.n_images == 5 and {j.kind for j in spec.jobs} == {"squares"}
    for i, job in enumerate(spec.jobs):
        gt = squares_ground_truth(job.camera, job.pose, spec.squares)["squares"]
        corners = np.asarray(gt["corners_distorted_px"])
        assert corners.shape == (64, 4, 2) and all(gt["in_view"])
        model = np.asarray(gt["model_points_m"])
        np.testing.assert_allclose(model[..., :2], z["model"] * INCH, atol=1e-12)
        pm = gt["pose_model"]
        r, t = np.asarray(pm["R"]), np.asarray(pm["t_m"])
        np.testing.assert_allclose(t / INCH, pm["t_model_unit"], atol=1e-12)
        printed = model.reshape(-1, 3) + [0.0, 0.0, -TARGET_STANDOFF_M]
        ref, _ = cv2.projectPoints(printed, cv2.Rodrigues(r)[0], t, job.camera.K, job.camera.dist_coeffs)
        np.testing.assert_allclose(corners.reshape(-1, 2), ref.reshape(-1, 2), atol=1e-9)
        r_z, t_z = z["poses"][i]
        np.testing.assert_allclose(r, r_z, atol=2e-6)
        np.testing.assert_allclose(t / INCH, t_z, atol=1e-9)
        his, _ = cv2.projectPoints(model.reshape(-1, 3), cv2.Rodrigues(r_z)[0], t_z * INCH, job.camera.K,
                                   job.camera.dist_coeffs)
        assert np.abs(corners.reshape(-1, 2) - his.reshape(-1, 2)).max() < 0.015
        xc = z["model"].reshape(-1, 2) @ r_z[:, :2].T + t_z
        xn = xc[:, :2] / xc[:, 2:]
        radial = 1 + z["k"][0] * (xn ** 2).sum(1) + z["k"][1] * (xn ** 2).sum(1) ** 2
        skewed = (np.c_[xn * radial[:, None], np.ones(len(xn))] @ z["K"].T)[:, :2]
        assert np.abs(corners.reshape(-1, 2) - skewed).max() < 0.07
        assert _rms(corners, z["data"][i])[0] < 0.55


# --- a rendered board of squares ------------------------------------------------------------------
def test_rendered_board_edges_lie_on_the_exact_outline(fast_variant):
    """The twin's image 0 (its PSF, distortion and K; radiance at 64 spp): an ERF fitted across each of
    the 256 square sides against the signed distance to the exact distorted outline centres within
    0.025 px of it on every side, and within 0.002 px on average.  Why these tolerances: the mean
    offset is < 0.001 px (no bias from the geometry, the PSF sampling or the float32 mesh, ~5e-5 px);
    the spread is Monte-Carlo noise (SD 0.0056 px at 64 spp with CalibIm1's measured PSF, sigma 4.41 x
    4.47 um; it falls as spp^-1/2), so the largest of 256 sides lies near 3-4 SD = 0.017-0.022 px."""
    from edgetruth.render.dataset.image import get_rig
    from edgetruth.render.scene.mitsuba_scene import RenderSettings

    spec = load_spec("zhang1998_twin")
    job = spec.jobs[0]
    rig = get_rig("squares", job.camera, RenderSettings(spp=64, sampler="multijitter"), spec.squares)
    rig.set_state(job.pose, job.irradiance_w_m2, job.light_position_m)
    img = rig.render(7)
    mu = side_offsets(img, job.camera, job.pose, spec.squares.quads_local(-TARGET_STANDOFF_M))
    print(f"side offsets: mean {mu.mean():+.4f} px, SD {mu.std():.4f}, max |.| {np.abs(mu).max():.4f} (n = {len(mu)})")
    assert len(mu) == 256 and abs(mu.mean()) < 0.002 and np.abs(mu).max() < 0.025


def test_twin_spec_renders_image_0_with_documented_truth(fast_variant, tmp_path):
    """The shipped twin through the driver (4 spp): an 8-bit image whose white board and squares sit at
    CalibIm1's levels (squares ~38 of 255, the white clipped near 255: docs/board.md "Digital twin"), and a
    ground truth whose corners are the projection and whose every key is documented."""
    from edgetruth.render.dataset.driver import render_spec
    from edgetruth.render.scene.ground_truth import squares_ground_truth

    text = (ROOT / "scenes" / "zhang1998_twin.toml").read_text()
    text = re.sub(r"(?m)^spp = \d+", "spp = 4", text)
    p = tmp_path / "twin.toml"
    p.write_text(text)
    spec = load_spec(p)
    out = tmp_path / "data"
    render_spec(spec, out, only=[0], progress=False, announce=lambda s: None)
    gt = json.loads((out / "0000_calib1.json").read_text())
    from edgetruth.render import open_dataset

    assert [s.name for s in open_dataset(out).square_boards()] == ["0000_calib1"]
    img = cv2.imread(str(out / "0000_calib1.png"), cv2.IMREAD_UNCHANGED)
    assert img.dtype == np.uint8 and img.shape == (480, 640) and gt["kind"] == "squares"
    expect = squares_ground_truth(spec.jobs[0].camera, spec.jobs[0].pose, spec.squares)["squares"]
    np.testing.assert_array_equal(gt["squares"]["corners_distorted_px"], expect["corners_distorted_px"])
    assert gt["pose"]["explicit"] and gt["illumination"]["position_m"] == [0.0, -1.5, -2.0]
    assert gt["camera"]["K"] == load_camera("zhang1998").K.tolist()
    assert gt["squares"]["polyline_chord_error_px"] < 1e-3 and gt["saturation"]["fraction_lit"] == 0.0
    # levels like the photos: inner half of each square, and the white gaps between squares in a row
    c = np.asarray(gt["squares"]["corners_distorted_px"])
    black, white = [], []
    for q in c:
        m = np.zeros(img.shape, np.uint8)
        cv2.fillConvexPoly(m, np.round((q.mean(0) + 0.5 * (q - q.mean(0))) * 16).astype(np.int32), 1, shift=4)
        black.append(np.median(img[m > 0]))
    g = c.reshape(8, 8, 4, 2)
    for r in range(8):
        for k in range(7):
            x, y = np.round(0.5 * (g[r, k][[1, 2]].mean(0) + g[r, k + 1][[0, 3]].mean(0))).astype(int)
            white.append(np.median(img[y - 2:y + 3, x - 2:x + 3]))
    print(f"twin levels: squares {np.median(black)}, white {np.median(white)}")
    assert 33 <= np.median(black) <= 43 and 240 <= np.median(white) <= 255
    # every key is documented (docs/formats.md, docs/spec.md)
    doc = (ROOT / "docs" / "formats.md").read_text() + (ROOT / "docs" / "spec.md").read_text()
    documented = set(re.findall(r"`([A-Za-z_][A-Za-z0-9_]*)`", doc))
    keys = set(gt) | set(gt["squares"]) | set(gt["squares"]["pose_model"]) | set(gt["pose"]) | set(gt["camera"])
    assert not sorted(keys - documented)


# --- a board from a pattern, sampled poses; the polygon outline ------------------------------------
SQUARES_SPEC = """
[spec]
name = "boards"
camera = "default"
camera_scale = 8
spp = 4
board_mode = "path"
squares = {{ {squares} }}

[[group]]
name = "b"
kind = "squares"
{group}
"""


def _spec(tmp_path: Path, squares: str = "rows = 3, cols = 4, side_m = 0.02, pitch_m = 0.03",
          group: str = "count = 2\ndistance_range_cm = [60, 90]\ntilt_max_deg = 20\nlateral_fraction = 0.5",
          name: str = "boards.toml") -> Path:
    p = tmp_path / name
    p.write_text(SQUARES_SPEC.format(squares=squares, group=group))
    return p


def test_pattern_board_with_drawn_poses(tmp_path):
    from edgetruth.render.dataset.image import job_pose
    from edgetruth.render.scene.ground_truth import squares_ground_truth

    spec = load_spec(_spec(tmp_path))
    b = spec.squares
    assert b.n_squares == 12 and b.half_size_m == pytest.approx((0.11 / 2 + 0.02, 0.08 / 2 + 0.02))
    q = b.quads_model
    np.testing.assert_allclose(q[5], [[0.03, 0.03], [0.05, 0.03], [0.05, 0.05], [0.03, 0.05]])  # row 1, col 1
    for job in spec.jobs:
        pose = job_pose(job, job.camera, b.plate_corners_local())
        gt = squares_ground_truth(job.camera, pose, b)["squares"]
        assert all(gt["in_view"]) and len(gt["polylines_distorted_px"]) == 12
        r, t = np.asarray(gt["pose_model"]["R"]), np.asarray(gt["pose_model"]["t_m"])
        ref, _ = cv2.projectPoints(b.model_points(-TARGET_STANDOFF_M).reshape(-1, 3), cv2.Rodrigues(r)[0], t,
                                   job.camera.K, job.camera.dist_coeffs)
        np.testing.assert_allclose(np.reshape(gt["corners_distorted_px"], (-1, 2)), ref.reshape(-1, 2), atol=1e-9)


def test_chessboard_squares_start_with_the_board_studys_model(tmp_path):
    """A chessboard target's first squares are the board study's chessboard model (same corners, same order, in
    side_m); the rest are the outer ring's dark squares, cut to ``ring`` beyond the outermost inner corners."""
    from edgetruth.evaluate.board.detect.chessboard import chessboard_model

    spec = load_spec(_spec(tmp_path, squares='chessboard = "9x6", side_m = 0.03, ring = [0.5, 0.8]'))
    b = spec.squares
    model = chessboard_model((9, 6), 0.03, "m")
    assert b.n_squares == 35  # 70 squares of a 10 x 7 board, half dark
    np.testing.assert_allclose(b.quads_model[:len(model)], model.corners, atol=1e-15)
    ring = b.quads_model[len(model):].reshape(-1, 2)
    assert ring[:, 0].min() == pytest.approx(-0.015) and ring[:, 0].max() == pytest.approx(8.5 * 0.03)
    assert ring[:, 1].min() == pytest.approx(-0.024) and ring[:, 1].max() == pytest.approx(5.8 * 0.03)
    u, v = b.quads_model[:, 1] - b.quads_model[:, 0], b.quads_model[:, 3] - b.quads_model[:, 0]
    area = np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0])  # the 2-D cross product (np.cross of 2-vectors: deprecated)
    # 20 whole squares; the ring's dark ones: 4 + 4 in the top and bottom rows (0.8 high), 2 + 3 in the left and
    # right columns (0.5 wide), 2 corners (0.5 x 0.8)
    assert area.sum() == pytest.approx(0.03 ** 2 * (20 + 8 * 0.8 + 5 * 0.5 + 2 * 0.5 * 0.8))


@pytest.mark.slow
def test_rendered_chessboard_is_found_in_model_order(fast_variant, tmp_path):
    """The board study finds a rendered chessboard's model squares where the render's truth puts its first
    squares (cornerSubPix corners at 4 spp: within 0.5 px, median 0.2 px; a square is 27 px)."""
    from edgetruth.evaluate.board.detect.chessboard import chessboard_model
    from edgetruth.evaluate.board.detect.squares import board_squares
    from edgetruth.image_io import read_gray
    from edgetruth.render.dataset.driver import render_spec
    from edgetruth.render.dataset.reader import open_dataset

    pose = "R = [[0.98, 0.0, 0.198997], [0.0, 1.0, 0.0], [-0.198997, 0.0, 0.98]]\nt = [-0.12, -0.075, 0.9]"
    p = _spec(tmp_path, 'chessboard = "9x6", side_m = 0.03, ring = [0.5, 0.8]',
              f"irradiance_w_m2 = 0.3\n[[group.poses]]\n{pose}")
    p.write_text(p.read_text().replace("camera_scale = 8", "camera_scale = 2"))  # 640 x 512: the corner finder's
    spec = load_spec(p)
    render_spec(spec, tmp_path / "out", variant=fast_variant, progress=False)
    s = next(iter(open_dataset(tmp_path / "out").square_boards()))
    img = read_gray(s.dataset.path / s.dataset.manifest["images"][s.name]["files"]["png"]["path"])
    model = chessboard_model((9, 6), 0.03, "m")
    found = board_squares(img, model)[0]
    truth = np.asarray(s.truth["squares"]["corners_distorted_px"])
    assert truth.shape == (35, 4, 2)
    err = np.linalg.norm(found.corners - truth[:len(model)], axis=2)
    assert np.isfinite(err).all() and err.max() < 0.5 and np.median(err) < 0.2


def test_polygon_outline_lies_on_the_projection():
    cam = load_camera()
    pose = ExplicitPose.from_rt(cv2.Rodrigues(np.array([0.2, -0.3, 0.1]))[0], [0.05, -0.03, 0.7])
    quad = np.array([[0.01, 0.02, -1e-5], [0.05, 0.015, -1e-5], [0.06, 0.07, -1e-5], [0.0, 0.06, -1e-5]])
    c = OutlineCurve.polygon(cam, pose, quad)
    t = c.parameters()
    ref, _ = cv2.projectPoints(c.local(t), cv2.Rodrigues(pose.rotation)[0], pose.translation_m, cam.K, cam.dist_coeffs)
    np.testing.assert_allclose(c.polyline(), ref.reshape(-1, 2), atol=1e-6)
    corners = c.points(np.arange(4) / 4)
    ref, _ = cv2.projectPoints(quad, cv2.Rodrigues(pose.rotation)[0], pose.translation_m, cam.K, cam.dist_coeffs)
    np.testing.assert_allclose(corners, ref.reshape(-1, 2), atol=1e-9)
    poly = c.polyline()
    assert np.linalg.norm(np.diff(np.vstack([poly, poly[:1]]), axis=0), axis=1).max() <= 2.0 + 1e-9
    inside = cv2.projectPoints(quad.mean(0, keepdims=True), cv2.Rodrigues(pose.rotation)[0], pose.translation_m,
                               cam.K, cam.dist_coeffs)[0].reshape(2)
    assert c.signed_distance(*inside) < 0 < c.signed_distance(*(inside + 200.0))


def test_moved_origin_keeps_the_placement():
    pose = ExplicitPose.from_rt(cv2.Rodrigues(np.array([0.1, 0.2, -0.3]))[0], [0.1, 0.2, 1.0])
    c = np.array([0.03, -0.02, 0.0])
    moved = pose.moved_origin(c)
    p = np.array([[0.01, 0.02, 0.0], [-0.05, 0.0, 0.0]])
    np.testing.assert_allclose(moved.to_camera(p - c), pose.to_camera(p), atol=1e-15)


# --- bad keys: one line each ----------------------------------------------------------------------
POSE = "R = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]\nt = [0.0, 0.0, 0.8]"


@pytest.mark.parametrize("squares,group,expect", [
    ('model = "zhang1998"', "count = 1", "needs model_unit_m"),
    ('model = "zhang1998", model_unit_m = 0.0254, rows = 3', "count = 1", "not both"),
    ('model = "missing.txt", model_unit_m = 1.0', "count = 1", "cannot read model file"),
    ('model = "nope", model_unit_m = 1.0', "count = 1", "no shipped real set 'nope'"),
    ('model = "bad.txt", model_unit_m = 1.0', "count = 1", "line 2: expected 8 numbers"),
    ('model = "twisted.txt", model_unit_m = 1.0', "count = 1", "not a convex quad"),
    ("model_unit_m = 0.0254", "count = 1", "model_unit_m applies to a model file"),
    ('chessboard = "9x6", model = "zhang1998", model_unit_m = 0.0254', "count = 1", "model and chessboard both"),
    ('chessboard = "9x6", rows = 3', "count = 1", "a chessboard takes side_m"),
    ('chessboard = "9by6"', "count = 1", "give COLSxROWS inner corners"),
    ('chessboard = "1x6"', "count = 1", "give COLSxROWS inner corners"),
    ("ring = [0.5, 0.5]", "count = 1", "ring applies to a chessboard"),
    ('chessboard = "9x6", ring = [0, 1]', "count = 1", "ring"),
    ("side_m = 0.03, pitch_m = 0.02", "count = 1", "pitch_m = 0.02 < side_m"),
    ("rows = 2, cols = 2, plate_size_m = [0.01, 0.2]", "count = 1", "plate_size_m"),
    ("plate_size_m = [0.2]", "count = 1", "give [x, y]"),
    ("square_reflectance = 1.5", "count = 1", "square_reflectance = 1.5"),
    ("colour = 1", "count = 1", "unknown key(s) colour"),
    ("rows = 2", 'target = "T1"', "a squares group has no target"),
    ("rows = 2", f"count = 2\n[[group.poses]]\n{POSE}", "poses and count"),
    ("rows = 2", "pose_unit_m = 0.0254", "pose_unit_m applies to explicit poses"),
    ("rows = 2", "[[group.poses]]\nR = [[1, 0, 0], [0, 1, 0], [0, 0, 1.1]]\nt = [0, 0, 1]", "R is not a rotation"),
    ("rows = 2", "[[group.poses]]\nR = [[1, 0, 0], [0, 1, 0], [0, 0, -1]]\nt = [0, 0, 1]", "R is not a rotation"),
    ("rows = 2", "[[group.poses]]\nR = [[1, 0], [0, 1]]\nt = [0, 0, 1]", "give a 3 x 3 matrix"),
    ("rows = 2", "[[group.poses]]\nR = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]\nt = [0, 1]", "give [tx, ty, tz]"),
    ("rows = 2", "[[group.poses]]\nR = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]", "give exactly R"),
    ("rows = 2", "[[group.poses]]\nR = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]\nt = [0, 0, -0.5]", "behind the camera"),
    ("rows = 2", "light_position_m = [0, 1]", "light_position_m"),
    ("rows = 2", "light_position_m = [0, 0.1, 0.2]", "z must be < 0"),
])
def test_bad_keys_are_one_line_errors(tmp_path, squares, group, expect):
    (tmp_path / "bad.txt").write_text("0 0 1 0 1 1 0 1\n0 0 1 0 1\n")
    (tmp_path / "twisted.txt").write_text("0 0 1 1 1 0 0 1\n")
    with pytest.raises(InputError, match=re.escape(expect)) as exc:
        load_spec(_spec(tmp_path, squares, group))
    assert "\n" not in str(exc.value) and str(tmp_path / "boards.toml") in str(exc.value)


@pytest.mark.parametrize("table,expect", [
    ({"fx_px": 800.0, "focal_length_mm": 8.0}, "fx_px = 800 but focal_length_mm / pitch_um give 1666.67"),
    ({"cx_px": 2000.0}, "cx_px = 2000: the principal point must lie on the image"),
    ({"cy_px": -3.0}, "cy_px = -3.0: must be a finite number in [-0.5, 16384]"),
    ({"fy_px": 0.0}, "fy_px = 0.0: must be a finite number in [1, 1e+07]"),
    ({"fx_px": "800"}, "fx_px = '800': must be a finite number"),
])
def test_bad_intrinsics_are_one_line_errors(table, expect):
    with pytest.raises(InputError, match=re.escape(expect)) as exc:
        camera_from_dict(table)
    assert "\n" not in str(exc.value)


def test_stated_intrinsics_need_a_consistent_focal_length():
    cam = camera_from_dict({"fx_px": 800.0, "pitch_um": 6.0})
    assert cam.focal_length_mm == pytest.approx(4.8) and cam.fx_px == 800.0 and cam.fy_px == 800.0
    assert cam.principal_point_px == (639.5, 511.5)
    assert camera_from_dict({"fx_px": 800.0, "pitch_um": 6.0, "focal_length_mm": 4.8}).fx_px == 800.0
    with pytest.raises(InputError, match="leave focal_length_mm out"):
        Camera(focal_x_px=800.0)  # 8 mm / 4.8 um = 1666.7 px


def test_square_board_winding_faces_the_camera():
    """A model listing its corners counter-clockwise still renders its squares facing the camera (the
    mesh rewinds them) while the ground truth keeps the model's order."""
    cw = SquareBoard.pattern(2, 1, 0.02, 0.03)
    ccw = SquareBoard(quads_model_m=tuple(tuple(q[::-1]) for q in cw.quads_model_m))
    np.testing.assert_allclose(ccw.black_quads_local(0.0), cw.black_quads_local(0.0))
    np.testing.assert_allclose(ccw.quads_local(), cw.quads_local()[:, ::-1])


def test_light_position_reaches_every_render_of_an_image(fast_variant, tmp_path, monkeypatch):
    """A group's light_position_m lights the whole frame and the edge band's tiles alike, and the
    ground truth records it."""
    from edgetruth.render.dataset.image import render_job
    from edgetruth.render.scene.mitsuba_scene import TargetRig
    from edgetruth.render.testing import write_tiny_spec

    p = write_tiny_spec(tmp_path, spp=4, edge_spp=16)
    p.write_text(p.read_text().replace('target = "T2"\n', 'target = "T2"\nlight_position_m = [0.2, -0.1, -0.3]\n'))
    spec = load_spec(p)
    seen = []
    original = TargetRig.set_state

    def spy(self, target, pose, irradiance_w_m2, light_position_m=None):
        seen.append(light_position_m)
        return original(self, target, pose, irradiance_w_m2, light_position_m)

    monkeypatch.setattr(TargetRig, "set_state", spy)
    _, _, gt = render_job(spec, spec.jobs[0])
    assert gt["render"]["edge_band"]["tiles"] > 0 and len(seen) == 2 and set(seen) == {(0.2, -0.1, -0.3)}
    assert gt["illumination"]["position_m"] == [0.2, -0.1, -0.3]
    assert spec.jobs[2].light_position_m is None  # the checkerboard group keeps the default light
