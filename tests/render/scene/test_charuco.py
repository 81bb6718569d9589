"""``kind = "charuco"``: OpenCV's ChArUco board rendered as exact dark squares, with its corners and markers as truth.

Without Mitsuba: the board's layout and bitmaps are OpenCV's (its object points to float32, its own
``generateImage`` pixel for pixel); the truth is an independent projection (``cv2.projectPoints``); bad
tables are refused.  Against Mitsuba (llvm): OpenCV's ``CharucoDetector`` finds every marker id and every
ChArUco corner of the renders, its corners within its own error of the truth (measured here, 400 x 320 px,
squares ~30 px, 16 spp: ChArUco corners 0.05-0.12 px RMS; marker corners 0.7 px RMS, ~0.55 px inside the
marker: its contour corners sit inside the dark region); the rendered square and marker sides lie on their exact
distorted outline within 0.01 px.
"""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from edgetruth.errors import InputError
from edgetruth.render.dataset.spec import load_spec
from edgetruth.render.scene.charuco import CharucoBoard, merge_cells
from edgetruth.render.scene.targets import TARGET_STANDOFF_M

CAMERA = """[camera]
width_px = 400
height_px = 320
pitch_um = 15.0
focal_length_mm = 8.0
f_number = 4.0
focus_distance_m = 0.7
[camera.distortion]
k1 = -0.08
k2 = 0.03
p1 = 0.0002
p2 = -0.0001
"""
SPEC = """[spec]
name = "charuco_tiny"
camera = "cam.toml"
spp = 16
board_mode = "path"
sampler = "multijitter"
charuco = {{ cols = 5, rows = 7, square_m = 0.04, marker_m = 0.03, dictionary = "DICT_4X4_50" {extra}}}

[[group]]
name = "ch"
kind = "charuco"
distance_range_cm = [65, 75]
count = 2
tilt_max_deg = 25
roll_max_deg = 20
lateral_fraction = 0.3
irradiance_w_m2 = 0.1
"""


def _spec(tmp_path, extra: str = "", group: str = ""):
    (tmp_path / "cam.toml").write_text(CAMERA)
    path = tmp_path / "charuco_tiny.toml"
    path.write_text(SPEC.format(extra=extra) + group)
    return load_spec(path)


def _raster(board: CharucoBoard, px_per_square: int) -> np.ndarray:
    """The dark rectangles, sampled at pixel centres (px_per_square a multiple of the cells per square)."""
    h, w = board.rows * px_per_square, board.cols * px_per_square
    ys, xs = np.mgrid[0:h, 0:w] + 0.5
    q = board.dark_quads_model() / board.square_m * px_per_square
    inside = ((xs[..., None] > q[:, 0, 0]) & (xs[..., None] < q[:, 2, 0])
              & (ys[..., None] > q[:, 0, 1]) & (ys[..., None] < q[:, 2, 1]))
    return inside.any(-1)


@pytest.mark.parametrize("board, px", [(CharucoBoard(), 24), (CharucoBoard(cols=6, rows=6, legacy=True), 24),
                                       (CharucoBoard(cols=6, rows=6), 24),
                                       (CharucoBoard(8, 5, 0.03, 0.021, "DICT_5X5_100"), 20)])
def test_layout_and_bitmaps_are_opencvs(board, px):
    cv = board.cv_board()
    np.testing.assert_allclose(board.corner_object_points(), cv.getChessboardCorners(), atol=3e-8)
    np.testing.assert_allclose(board.marker_object_points(), np.reshape(cv.getObjPoints(), (-1, 4, 3)), atol=3e-8)
    np.testing.assert_array_equal(board.marker_ids, np.ravel(cv.getIds()))
    image = cv.generateImage((board.cols * px, board.rows * px), marginSize=0, borderBits=1)
    np.testing.assert_array_equal(_raster(board, px), image == 0)
    q = board.dark_quads_model()
    assert np.all(q[:, 2] > q[:, 0])  # every rectangle non-degenerate, corners top-left ... bottom-left


def test_merged_cells_cover_the_dark_cells_once():
    rng = np.random.default_rng(3)
    dark = rng.random((8, 8)) < 0.5
    count = np.zeros(dark.shape, int)
    for r0, c0, r1, c1 in merge_cells(dark):
        count[r0:r1, c0:c1] += 1
    np.testing.assert_array_equal(count, dark.astype(int))


def test_truth_is_opencvs_projection(tmp_path):
    """Explicit poses are in OpenCV's board frame: the truth's corners and marker corners are
    ``cv2.projectPoints`` of OpenCV's own object points (at the print's 10 um stand-off) to 1e-6 px."""
    from edgetruth.render.scene.charuco_truth import charuco_ground_truth

    r = cv2.Rodrigues(np.array([0.3, -0.2, 0.1]))[0]
    t = [-0.08, -0.12, 0.7]
    group = f"\n[[group]]\nname = \"fixed\"\nkind = \"charuco\"\nposes = [{{ R = {r.tolist()}, t = {t} }}]\n"
    spec = _spec(tmp_path, group=group)
    job = spec.jobs[2]
    gt = charuco_ground_truth(job.camera, job.pose, spec.charuco)["charuco"]
    cv = spec.charuco.cv_board()
    k, dist = job.camera.K, job.camera.dist_coeffs
    for obj, got in ((np.asarray(cv.getChessboardCorners(), float), gt["corners"]["distorted_px"]),
                     (np.reshape(cv.getObjPoints(), (-1, 3)).astype(float), gt["markers"]["corners_distorted_px"])):
        obj = np.round(obj / 1e-4) * 1e-4  # OpenCV's float32 points, back on their 0.1 mm grid
        obj[:, 2] = -TARGET_STANDOFF_M
        want = cv2.projectPoints(obj, cv2.Rodrigues(r)[0], np.array(t, float), k, dist)[0].reshape(-1, 2)
        np.testing.assert_allclose(np.reshape(got, (-1, 2)), want, atol=1e-6)
    assert gt["markers"]["ids"] == list(range(17)) and gt["corners"]["ids"] == list(range(24))
    np.testing.assert_allclose(gt["pose_model"]["t_m"], t, atol=1e-15)


@pytest.mark.parametrize("table, match", [("marker_m = 0.05", "marker_m"), ('dictionary = "DICT_9X9"', "DICT_4X4_50"),
                                          ("cols = 12, rows = 10", "needs 60 markers")])
def test_bad_boards_are_refused(tmp_path, table, match):
    (tmp_path / "cam.toml").write_text(CAMERA)
    path = tmp_path / "bad.toml"
    path.write_text(SPEC.split("charuco = ")[0] + "charuco = { " + table + " }\n" + SPEC.split("}\n", 1)[1])
    with pytest.raises(InputError, match=match):
        load_spec(path)


def test_specs_without_charuco_are_unchanged(tmp_path):
    from edgetruth.render.testing import write_tiny_spec

    spec = load_spec(write_tiny_spec(tmp_path))
    assert spec.charuco is None and "charuco" not in spec.resolved()


@pytest.fixture(scope="module")
def renders(fast_variant, tmp_path_factory):
    import mitsuba as mi

    from edgetruth.render.dataset.image import render_job

    mi.set_variant(fast_variant)
    spec = _spec(tmp_path_factory.mktemp("charuco"))
    return spec, [render_job(spec, job) for job in spec.jobs]


def test_opencv_finds_every_marker_and_corner(renders):
    spec, out = renders
    detector = cv2.aruco.CharucoDetector(spec.charuco.cv_board())
    for _, image, gt in out:
        g = image.astype(np.float64)
        g8 = np.clip(g / np.percentile(g, 99.5) * 230, 0, 255).astype(np.uint8)
        cc, cid, mc, mid = detector.detectBoard(g8)
        t = gt["charuco"]
        assert gt["kind"] == "charuco" and all(t["markers"]["in_view"]) and all(t["corners"]["in_view"])
        assert sorted(np.ravel(mid).tolist()) == t["markers"]["ids"]
        assert sorted(np.ravel(cid).tolist()) == t["corners"]["ids"]
        d = cc.reshape(-1, 2) - np.asarray(t["corners"]["distorted_px"])[np.ravel(cid)]
        rms = float(np.sqrt(np.mean(np.sum(d ** 2, 1))))
        truth = np.asarray(t["markers"]["corners_distorted_px"])[np.ravel(mid)]
        e = np.reshape(mc, (-1, 4, 2)) - truth
        outward = truth - truth.mean(1, keepdims=True)
        outward /= np.linalg.norm(outward, axis=-1, keepdims=True)
        radial = np.sum(e * outward, -1)
        print(f"ChArUco corners RMS {rms:.3f} px (n = {len(d)}); marker corners RMS "
              f"{np.sqrt(np.mean(np.sum(e ** 2, -1))):.3f} px, outward {radial.mean():+.3f} px")
        assert rms < 0.2 and np.abs(d).max() < 0.5
        assert -1.0 < radial.mean() < -0.2 and np.sqrt(np.mean(np.sum(e ** 2, -1))) < 1.0


# --- edges: an in-focus pinhole camera with distortion, no PSF, close up (a marker cell ~13 px) ---------------------
EDGE_CAMERA = dict(width_px=320, height_px=240, pitch_um=15.0, focal_length_mm=8.0, f_number=0.0, focus_distance_m=0.3,
                   distortion=(-0.08, 0.03, 2e-4, -1e-4, 0.0), diffraction_wavelength_nm=0.0, natural_vignetting=False)


@pytest.mark.slow  # ~10 s of CPU (a 256-spp render and 34 sides measured); longer on shared cores
def test_rendered_square_and_marker_sides_lie_on_the_exact_outline(fast_variant):
    """Every chessboard square's and marker's outer side in view (17 + 17 here): a line fit to (measured - exact)
    along it within 0.01 px at both ends (measured 0.003 px at worst, 256 spp), measured as
    tests/render/scene/test_shapes_edges.py does (the bright part of each pixel column or row summed across
    the edge: exact for box pixels without a PSF), away from every other edge (the marker's inner cells lie at
    least one cell inside its border)."""
    import mitsuba as mi

    from edgetruth.render.optics.camera import Camera
    from edgetruth.render.scene.mitsuba_scene import CheckerRig, RenderSettings
    from edgetruth.render.scene.outline import OutlineCurve
    from edgetruth.render.scene.pose import Pose
    from tests.render.scene.test_shapes_edges import TOL_PX, measure_piece

    mi.set_variant(fast_variant)
    cam, board = Camera(**EDGE_CAMERA), CharucoBoard(marker_m=0.03)
    pose = Pose(0.22, -0.02, 0.035, 4.0, -3.0, 2.0)
    rig = CheckerRig(cam, RenderSettings(spp=256, sampler="multijitter"), board=board.squares)
    rig.set_state(pose, 0.05, None)
    img = rig.render(7).astype(np.float64)
    squares = board.squares.black_quads_local(-TARGET_STANDOFF_M)[:len(board._layout["dark_squares"])]
    markers = board.marker_object_points() - board.squares.centre_model_m
    markers[..., 2] = -TARGET_STANDOFF_M
    cell = board.marker_m / board._layout["bits"]
    inset = markers + np.array([[cell, cell, 0], [-cell, cell, 0], [-cell, -cell, 0], [cell, -cell, 0]])
    outer = [("square", q) for q in squares] + [("marker", q) for q in markers]
    curves = [OutlineCurve.polygon(cam, pose, q) for _, q in outer]
    dense = [c.points(np.linspace(0, 1, 4000)) for c in curves + [OutlineCurve.polygon(cam, pose, q) for q in inset]]
    worst = {"square": [], "marker": []}
    for j, ((kind, _), curve) in enumerate(zip(outer, curves)):
        for k in range(4):
            t0, t1 = k / 4 + 1e-6, (k + 1) / 4 - 1e-6
            side = curve.points(np.linspace(t0, t1, 200))
            lo, hi = side.min(0) - 15, side.max(0) + 15
            others = [d[np.all((d >= lo) & (d <= hi), axis=1)] for i, d in enumerate(dense) if i != j]
            rest = curve.points(np.linspace(t1 + 1e-5, t0 + 1 - 1e-5, 4000))
            pos, r = measure_piece(img, curve, t0, t1, [o for o in others if len(o)] + [rest])
            if len(r) >= 4:
                b, a = np.polyfit(pos, r, 1)
                worst[kind].append(max(abs(a - b), abs(a + b)))
    print({k: (len(v), round(max(v), 4)) for k, v in worst.items()})
    assert len(worst["square"]) >= 12 and len(worst["marker"]) >= 12
    assert max(worst["square"] + worst["marker"]) <= TOL_PX
