"""A curled board (``render.scene.bend``, spec key ``board_bend_mm``): its height terms are the bend check's, its
meshes cover the print exactly and stay within a stated sag of the surface, its truth lies on the curled surface,
and a render of it puts every square side on the curled outline -- not on the flat one.

Measured here (Zhang's twin, image 0, 64 spp, llvm_ad_rgb): with a 7-term curl (≤ 1.5 mm at the squares' edge)
the 256 sides' ERF positions sit at -0.0002 px (SD 0.0053 px, the flat twin's Monte-Carlo noise; max 0.015 px)
from the curled outline, and 0.63 px RMS (up to 2.6 px) from the flat one.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from edgetruth.errors import InputError
from edgetruth.render.dataset.spec import load_spec
from edgetruth.render.scene.bend import MAX_SAG_M, BoardBend, check_sag, grid_mesh, height_terms, term_names
from edgetruth.render.scene.outline import OutlineCurve
from edgetruth.render.scene.pose import Pose
from edgetruth.render.scene.targets import TARGET_STANDOFF_M, Checkerboard
from tests.support.side_offsets import side_offsets

CURL_MM = (1.0, -0.6, 1.5, 0.3, 0.0, -0.4, 0.2)


def _cross(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _zhang_job():
    spec = load_spec("zhang1998_twin")
    return spec, spec.jobs[0]


# --- the height -------------------------------------------------------------------------------------------
def test_height_terms_are_the_bend_checks():
    """One set of monomials for the renderer and the check: x², xy, y², then x³, x²y, xy², y³."""
    from edgetruth.evaluate.board_bend import monomials

    assert term_names((2,)) == ["x^2", "xy", "y^2"]
    assert term_names((2, 3)) == ["x^2", "xy", "y^2", "x^3", "x^2y", "xy^2", "y^3"]
    p = np.array([[0.5, -2.0], [3.0, 1.5]])
    np.testing.assert_array_equal(height_terms(p, (2, 3))[1], [9.0, 4.5, 2.25, 27.0, 13.5, 6.75, 3.375])
    xy = np.random.default_rng(0).uniform(-0.1, 0.1, (30, 2))
    m, s = monomials(xy, (2, 3))
    np.testing.assert_array_equal(m, height_terms((xy - xy.mean(0)) / s, (2, 3)))


def test_bend_scale_and_height():
    """s is half the larger side of the squares' box; each coefficient is its monomial's height there (mm)."""
    board = Checkerboard()  # 10 x 7 squares of 30 mm: the box is 300 x 210 mm
    bend = BoardBend.of((0.4, 0.0, -0.2), board.black_quads_local(0.0))
    assert bend.scale_m == pytest.approx(0.15) and bend.degrees == (2,)
    np.testing.assert_allclose(bend.height_m(np.array([[0.15, 0.0], [0.0, -0.15], [0.075, 0.075]])),
                               [0.4e-3, -0.2e-3, (0.4 - 0.2) / 4 * 1e-3], rtol=1e-12)
    lifted = bend.lift(np.array([[[0.15, 0.0, -TARGET_STANDOFF_M]]]))
    assert lifted.shape == (1, 1, 3) and lifted[0, 0, 2] == pytest.approx(0.4e-3 - TARGET_STANDOFF_M, abs=1e-15)
    with pytest.raises(InputError, match="give 3"):
        BoardBend.of((0.1, 0.2), board.black_quads_local(0.0))


# --- the meshes -------------------------------------------------------------------------------------------
def test_mesh_covers_each_quad_exactly_and_faces_the_camera():
    """Cells of at most 2 mm tile every quad (areas add up to 1e-12), wound as CheckerRig's flat quads (whose
    normals face the camera), and the quad's sides stay straight (every vertex lies inside the quad)."""
    quads = Checkerboard().black_quads_local(0.0)[:3].copy()
    quads[2, 1, :2] += (0.004, 0.002)  # a general convex quad
    for q in quads:
        v, f = grid_mesh(q[None])
        a = v[f]
        area2 = _cross(a[:, 1, :2] - a[:, 0, :2], a[:, 2, :2] - a[:, 0, :2])
        ref2 = _cross(q[2, :2] - q[0, :2], q[1, :2] - q[0, :2])  # CheckerRig's face (0, 2, 1)
        assert np.all(np.sign(area2) == np.sign(ref2))
        quad_area = 0.5 * abs(_cross(q[2, :2] - q[0, :2], q[3, :2] - q[1, :2]))
        assert 0.5 * np.abs(area2).sum() == pytest.approx(quad_area, rel=1e-12)
        side = np.max(np.linalg.norm(a[:, [1, 2, 0], :2] - a[:, :, :2], axis=2)[:, :2])
        assert side <= 0.002 * np.sqrt(2) + 1e-12
        for k in range(4):  # every vertex on the inner side of each of the quad's sides
            e, n = q[(k + 1) % 4, :2] - q[k, :2], v[:, :2] - q[k, :2]
            assert np.all(np.sign(ref2) * _cross(e, n) <= 1e-15)


def test_mesh_sag_is_the_analytic_sagitta():
    """Under z = (a x² + c y²) / s a cell's diagonal chord (d along x and y) leaves the surface by (a + c) d² /
    (4 s²) at its middle, the largest gap on the cell: the measured sag is that to 1e-9.  A curl too strong for
    the mesh is refused."""
    q = Checkerboard().black_quads_local(0.0)[:1]
    v, f = grid_mesh(q)
    d = np.ptp(v[:, 1]) / round(np.ptp(v[:, 1]) / 0.002)
    bend = BoardBend((2.0, 0.0, 3.0), 0.15)
    assert check_sag(bend, v, f, "the squares") == pytest.approx(5e-3 * d ** 2 / (4 * 0.15 ** 2), rel=1e-9)
    with pytest.raises(InputError, match="gentler bend"):
        check_sag(BoardBend((0.0, 0.0, 45.0), 0.05), v, f, "the squares")
    assert MAX_SAG_M == TARGET_STANDOFF_M / 4


# --- the truth --------------------------------------------------------------------------------------------
def test_truth_lies_on_the_curled_surface():
    """Squares: every corner is the lifted corner's projection; every outline point lies on the surface (its z is
    the stand-off plus the height at its x, y); heights are recorded; the model points stay flat.  A
    checkerboard's inner corners likewise."""
    from edgetruth.render.scene.ground_truth import checker_ground_truth, squares_ground_truth

    spec, job = _zhang_job()
    b, cam, pose = spec.squares, job.camera, job.pose
    bend = BoardBend.of(CURL_MM, b.black_quads_local(0.0))
    gt = squares_ground_truth(cam, pose, b, bend, 1e-7)
    q = b.quads_local(-TARGET_STANDOFF_M)
    lifted = q + np.concatenate([np.zeros(q.shape[:2] + (2,)), bend.height_m(q.reshape(-1, 3)).reshape(
        q.shape[:2] + (1,))], axis=2)
    ref = cam.project(pose.to_camera(lifted.reshape(-1, 3)))
    np.testing.assert_allclose(np.reshape(gt["squares"]["corners_distorted_px"], (-1, 2)), ref, atol=1e-9)
    flat = cam.project(pose.to_camera(q.reshape(-1, 3)))
    assert np.abs(ref - flat).max() > 0.5  # the curl moves corners by px here: the check above can fail
    np.testing.assert_allclose(gt["board_bend"]["heights_m"], bend.height_m(q.reshape(-1, 3)).reshape(-1, 4),
                               rtol=1e-12)
    assert gt["board_bend"]["mesh_sag_m"] == 1e-7 and gt["board_bend"]["coefficients_mm"] == list(CURL_MM)
    np.testing.assert_array_equal(gt["squares"]["model_points_m"], b.model_points(0.0).tolist())
    curve = OutlineCurve.polygon(cam, pose, q[5], bend=bend)
    p = curve.local(np.linspace(0.0, 1.0, 97, endpoint=False))
    np.testing.assert_allclose(p[:, 2], -TARGET_STANDOFF_M + bend.height_m(p), atol=1e-15)

    board = Checkerboard()
    cb = BoardBend.of((0.5, 0.0, 0.5), board.black_quads_local(0.0))
    g = checker_ground_truth(cam, Pose(0.8), board, cb, 2e-7)
    local = board.inner_corners_local(-TARGET_STANDOFF_M)
    local[:, 2] += cb.height_m(local)
    np.testing.assert_allclose(g["corners"]["distorted_px"], cam.project(Pose(0.8).to_camera(local)), atol=1e-9)
    assert g["corners"]["object_points_m"] == board.inner_corners_local(0.0).tolist()
    assert "board_bend" not in checker_ground_truth(cam, Pose(0.8), board)


# --- the render -------------------------------------------------------------------------------------------
def _render(job, squares, bend, bent: bool):
    from edgetruth.render.dataset.image import get_rig
    from edgetruth.render.scene.mitsuba_scene import RenderSettings

    rig = get_rig("squares", job.camera, RenderSettings(spp=64, sampler="multijitter"), squares, bent=bent)
    rig.set_state(job.pose, job.irradiance_w_m2, job.light_position_m, bend=bend)
    return rig, rig.render(7)


def test_zero_bend_renders_the_flat_board(fast_variant):
    """The bent rig's meshes, uncurled, render the flat rig's image: the same seed gives the same samples, so
    pixels differ only where float rounding moves a sample across a side (one sample of 64: 1/64 of the
    contrast), on fewer than 1 % of pixels; elsewhere by < 1e-4 of the white."""
    spec, job = _zhang_job()
    _, flat = _render(job, spec.squares, None, False)
    rig, zero = _render(job, spec.squares, None, True)
    d = np.abs(zero.astype(np.float64) - flat) / flat.max()
    print(f"zero bend vs flat: max {d.max():.4f}, > 1e-4 on {np.mean(d > 1e-4):.4%}")
    assert d.max() <= 1.5 / 64 and np.mean(d > 1e-4) < 0.01
    with pytest.raises(ValueError, match="bent=True"):
        _render(job, spec.squares, BoardBend((0.1, 0.0, 0.0), 0.1), False)


def test_rendered_sides_lie_on_the_curled_outline(fast_variant):
    """Zhang's twin, image 0, curled by ``CURL_MM``: an ERF across each of the 256 square sides centres on the
    curled outline (|mean| < 0.002 px, every side within 0.025 px: the flat twin's tolerances, Monte-Carlo
    noise) and misses the flat outline (RMS > 0.3 px): the bend is rendered, and the truth follows it."""
    spec, job = _zhang_job()
    bend = BoardBend.of(CURL_MM, spec.squares.black_quads_local(0.0))
    rig, img = _render(job, spec.squares, bend, True)
    assert rig.mesh_sag_m(bend) < 1e-6
    q = spec.squares.quads_local(-TARGET_STANDOFF_M)
    mu = side_offsets(img, job.camera, job.pose, q, bend=bend)
    mf = side_offsets(img, job.camera, job.pose, q)
    print(f"curled: mean {mu.mean():+.4f} px, SD {mu.std():.4f}, max {np.abs(mu).max():.4f}; "
          f"flat: RMS {np.sqrt(np.mean(mf ** 2)):.3f}")
    assert len(mu) == 256 and abs(mu.mean()) < 0.002 and np.abs(mu).max() < 0.025
    assert np.sqrt(np.mean(mf ** 2)) > 0.3


# --- the spec -----------------------------------------------------------------------------------------------
SPEC = """
[spec]
name = "curl"
camera = "default"
camera_scale = 8
spp = 4
board_mode = "path"
squares = { rows = 3, cols = 4, side_m = 0.02, pitch_m = 0.03 }

[[group]]
name = "b"
kind = "KIND"
count = 2
distance_range_cm = [60, 90]
EXTRA
"""


def _spec(tmp_path: Path, extra: str, kind: str = "squares"):
    p = tmp_path / "curl.toml"
    p.write_text(SPEC.replace("KIND", kind).replace("EXTRA", extra))
    return load_spec(p)


def test_spec_key_board_bend_mm(tmp_path):
    """Jobs carry the group's curl; it enters the identity hash only when given; bad values and target groups are
    one-line errors naming the key."""
    flat = _spec(tmp_path, "")
    curled = _spec(tmp_path, "board_bend_mm = [0.0, 0.0, 0.4]")
    assert flat.jobs[0].board_bend_mm is None and curled.jobs[1].board_bend_mm == (0.0, 0.0, 0.4)
    assert "board_bend_mm" not in flat.resolved()["groups"][0]
    assert flat.identity_sha256 != curled.identity_sha256
    for extra, msg in (("board_bend_mm = [0.1, 0.2]", "give 3 coefficients"),
                       ("board_bend_mm = [0.1, 0.2, 99.0]", r"\[-50, 50\]")):
        with pytest.raises(InputError, match=msg):
            _spec(tmp_path, extra)
    with pytest.raises(InputError, match="board_bend_mm: a target scene's board is flat"):
        _spec(tmp_path, "board_bend_mm = [0.1, 0.2, 0.3]", kind="target")


def test_a_curled_checkerboard_renders_through_the_driver(fast_variant, tmp_path):
    """kind = checkerboard through ``render_job`` (4 spp): the truth carries the curl, its corners the lift."""
    from edgetruth.render.dataset.image import render_job

    p = tmp_path / "cb.toml"
    p.write_text(re.sub("squares = .*\n", "", SPEC).replace("KIND", "checkerboard").replace(
        "EXTRA", "irradiance_w_m2 = 0.02\nboard_bend_mm = [0.3, 0.1, -0.2, 0.05, 0.0, 0.0, 0.02]"))
    spec = load_spec(p)
    _, image, gt = render_job(spec, spec.jobs[0])
    b = gt["board_bend"]
    assert b["terms"][-1] == "y^3" and 0 < b["mesh_sag_m"] < 1e-7 and np.ptp(image) > 0
    bend = BoardBend(tuple(b["coefficients_mm"]), b["scale_m"])
    local = spec.checkerboard.inner_corners_local(-TARGET_STANDOFF_M)
    np.testing.assert_allclose(b["heights_m"], bend.height_m(local), rtol=1e-12)
    local[:, 2] += bend.height_m(local)
    cam = np.asarray(gt["pose"]["R_cam_from_board"]) @ local.T + np.asarray(gt["pose"]["t_cam_from_board_m"])[:, None]
    np.testing.assert_allclose(gt["corners"]["distorted_px"], spec.jobs[0].camera.project(cam.T), atol=1e-9)


def test_a_design_sweeps_the_curl_on_shared_poses(tmp_path):
    """board_bend_mm as a [design] factor: the cells share their pose slots (the same seeds) but not their radiance
    (a curl changes it: each cell renders its own)."""
    p = tmp_path / "sweep.toml"
    p.write_text("""
[spec]
name = "curl_sweep"
camera = "default"
camera_scale = 8
spp = 4
board_mode = "path"

[design]
kind = "checkerboard"
count = 3
distance_range_cm = [60, 90]
tilt_max_deg = 20

[[design.factor]]
name = "curl"
levels = [ { name = "flat" }, { name = "c05", board_bend_mm = [0.0, 0.0, 0.5] } ]
""")
    spec = load_spec(p)
    jobs = list(spec.jobs)
    flat = [j for j in jobs if j.board_bend_mm is None]
    curled = [j for j in jobs if j.board_bend_mm == (0.0, 0.0, 0.5)]
    assert len(flat) == len(curled) == 3
    assert [j.pose_seed for j in flat] == [j.pose_seed for j in curled]
    assert {j.radiance_unit for j in flat}.isdisjoint({j.radiance_unit for j in curled})


def test_shipped_curl_sweep_pairs_its_boards():
    """scenes/calibration_curl.toml: three boards (flat, cylinder, dome) on the same 20 poses, each its own render."""
    spec = load_spec("calibration_curl")
    cells = {}
    for j in spec.jobs:
        cells.setdefault(j.group, []).append(j)
    assert sorted(cells) == ["cylinder", "dome", "flat"] and all(len(v) == 20 for v in cells.values())
    assert cells["flat"][0].board_bend_mm is None and cells["dome"][0].board_bend_mm == (0.5, 0.0, 0.5)
    assert [j.pose_seed for j in cells["flat"]] == [j.pose_seed for j in cells["dome"]]
    assert len({j.radiance_unit for v in cells.values() for j in v[:1]}) == 3
