"""A twin of circle-grid photos (``twin.measure_circles``, ``derive.twin_texts`` of a circle grid, ``circle_study``):
the measurements read known values off synthetic circles and renders; on BoofCV's circle-grid photos the camera is
plain OpenCV's and the circles the printed size; the twin, rendered, gives its camera, poses and circles back."""
from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from edgetruth.errors import InputError
from edgetruth.evaluate.board.circles import object_points, predicted_outlines
from edgetruth.evaluate.board.twin import derive as td
from edgetruth.evaluate.board.twin import measure_circles as mc
from edgetruth.evaluate.pattern import parse_board_pattern
from edgetruth.resources import real_set

PATTERN = parse_board_pattern("circles:10x8", "--pattern", kinds=("circles",))


def _grid_outlines(radius=0.3, tilt_deg=20.0, z=12.0):
    """A 10 x 8 grid (spacing 1) seen by a pinhole of f = 600 px, tilted about y: its outlines (n, m, 2)."""
    K = np.array([[600.0, 0, 320], [0, 600.0, 240], [0, 0, 1]])
    obj = object_points((10, 8), 1.0, False).astype(float)
    R = cv2.Rodrigues(np.array([0.0, math.radians(tilt_deg), 0.0]))[0]
    t = np.array([-4.5, -3.5, z]) - R @ np.array([4.5, 3.5, 0.0]) + np.array([4.5, 3.5, 0.0])
    rvec = cv2.Rodrigues(R)[0]
    return obj, K, rvec, t, predicted_outlines(obj, radius, rvec, t, K, np.zeros(5))


def test_ellipse_radius_of_a_conic_is_its_area_radius():
    """x²/a² + y²/b² = 1 moved to (5, -3): √(ab) to 1e-12."""
    a, b, x0, y0 = 7.0, 3.0, 5.0, -3.0
    D = np.diag([1 / a ** 2, 1 / b ** 2, -1.0])
    T = np.array([[1, 0, -x0], [0, 1, -y0], [0, 0, 1.0]])  # p' = T p puts the centre at the origin
    q = T.T @ D @ T
    assert mc.ellipse_radius_px(q) == pytest.approx(math.sqrt(a * b), rel=1e-12)
    assert mc.ellipse_radius_px(-3.0 * q) == pytest.approx(math.sqrt(a * b), rel=1e-12)  # any scale of the conic


def test_circle_blur_reads_the_sigma_of_synthetic_circles():
    """Circles of ~15 px radius drawn with an ERF of σ 0.8 px along x and 0.5 along y (no pixel box): the arcs read
    them to 0.03 px (measured 0.015 and 0.023: the arcs within 25 degrees of an axis mix the other axis' σ in by
    sin² of their angle; the curvature of a 15 px circle biases a straight-edge ERF by less)."""
    *_, outlines = _grid_outlines()
    img = mc.synthetic_circles((480, 640), outlines, 0.8, 0.5, 30.0, 200.0)
    b = mc.circle_blur(img, outlines)
    assert b["vertical"]["sigma_px"] == pytest.approx(0.8, abs=0.03)
    assert b["horizontal"]["sigma_px"] == pytest.approx(0.5, abs=0.03)
    assert b["vertical"]["sides"] >= 100 and b["horizontal"]["sides"] >= 100


def test_flat_regions_lie_inside_and_between_the_circles():
    """Dark labels only inside a circle, at least the margin from its outline; white ones only outside every
    circle, within the grid's hull; one label per circle."""
    *_, outlines = _grid_outlines()
    dark, white = mc.flat_regions((480, 640), outlines, 3.0)
    img = mc.synthetic_circles((480, 640), outlines, 0.3, 0.3, 0.0, 1.0)
    assert img[dark > 0].max() < 1e-6 and img[white > 0].min() > 1 - 1e-6
    assert len(np.unique(dark[dark > 0])) == 80 and len(np.unique(white[white > 0])) == 80
    assert not np.any((dark > 0) & (white > 0))


def test_jpeg_blur_of_a_lossless_quality_is_nearly_nothing():
    """At quality 100 the JPEG moves σ by less than 0.01 px; at quality 30 it raises it more than at 100."""
    *_, outlines = _grid_outlines()
    hi = mc.jpeg_blur_px((480, 640), outlines, 0.6, 0.6, 30.0, 200.0, 100)
    lo = mc.jpeg_blur_px((480, 640), outlines, 0.6, 0.6, 30.0, 200.0, 30)
    assert abs(hi["x"]) < 0.01 and abs(hi["y"]) < 0.01
    assert lo["x"] > hi["x"] and lo["y"] > hi["y"]


@pytest.fixture(scope="module")
def sony():
    photos = sorted(real_set("sony_hx5v_circles").glob("*.jpg"))
    return photos, mc.measure_circles(photos, PATTERN)


def test_measured_on_boofcvs_circle_photos(sony):
    """On the 6 photos: the grid where plain OpenCV finds it (4), the camera within 0.2 % of plain OpenCV's
    blob-centroid calibration (fx 454.10, fy 451.93: other centres, the same photos), the circles' diameter the
    printed 15 mm (15 of 25 mm, board.toml) within 2 % (measured 15.09 mm), JPEG quality 92 read from the files,
    the dark below a fifth of the white."""
    _, m = sony
    assert [o["photo"] for o in m["left_out"]] == ["image00000.jpg", "image00004.jpg"]
    assert len(m["photos"]) == 4
    K = np.asarray(m["K"])
    assert K[0, 0] == pytest.approx(454.10, rel=2e-3) and K[1, 1] == pytest.approx(451.93, rel=2e-3)
    assert 2 * m["board"]["radius_spacings"] * 25.0 == pytest.approx(15.0, rel=0.02)
    for p in m["photos"]:
        assert p["jpeg_quality"] == {"quality": 92, "exact": True}
        assert 0 < p["dark"] < 0.2 * p["white"] and not p["white_saturated"]
        assert 0.2 < p["sigma_x_px"] < 1.0 and 0.2 < p["sigma_y_px"] < 1.0


def test_circle_twin_text_and_its_refusals(sony):
    _, m = sony
    cam, scene = td.twin_texts(m, "c", "circles", "camera.toml", 0.025, "BoofCV's photos")
    assert "[spec.circles_grid]" in scene and scene.count('kind = "circles_grid"') == 4
    assert "cols = 10\nrows = 8\nspacing_m = 0.025\n" in scene and "asymmetric = false" in scene
    assert "pose_unit_m = 0.025" in scene and 'board_mode = "frame"' in scene
    with pytest.raises(InputError, match="--bend"):
        td.twin_texts(m, "c", "circles", "camera.toml", 0.025, "x", bend=True)


@pytest.mark.slow
def test_rendered_circle_twin_gives_its_camera_poses_and_circles_back(sony, fast_variant, tmp_path):
    """The twin of the 4 photos rendered at 16 spp (frame board: no Monte-Carlo noise at the edges) and measured
    again (measured at 256 spp in brackets): fx, fy within 0.05 % (0.003 %) and cx, cy within 0.1 px (0.04) of the
    twin's camera, every pose's t within 0.01 spacing (0.0014), the circles' radius within 0.5 % of the rendered one
    (0.06 %: the edges found on the tone-decoded values; 3.7 % small before), the dark and white levels within 3 DN
    of the photos' (1.3 and 2.8), the ERF σ within 0.12 px of the photos' (0.099 on image00003, the sharpest photo:
    its σ of 0.365 px lies below the twin's floor at the assumed f/4 and 6 um pitch, ~0.46 px at no aberration;
    within 0.06 on the others)."""
    from edgetruth.render.dataset.driver import render_spec
    from edgetruth.render.dataset.reader import open_dataset
    from edgetruth.render.dataset.spec import load_spec

    photos, m = sony
    cam, scene = td.twin_texts(m, "c", "circles", "camera.toml", 0.025, "BoofCV's photos")
    (tmp_path / "camera.toml").write_text(cam)
    (tmp_path / "twin.toml").write_text(scene.replace("\nspp = 256\n", "\nspp = 16\n", 1))
    spec = load_spec(tmp_path / "twin.toml")
    render_spec(spec, tmp_path / "r", variant=fast_variant, progress=False, announce=lambda s: None)
    ds = open_dataset(tmp_path / "r")
    pngs = [s.dataset.path / s.dataset.manifest["images"][s.name]["files"]["png"]["path"] for s in ds]
    back = mc.measure_circles(pngs, PATTERN)
    truth = ds[0].truth["camera"]
    K = np.asarray(back["K"])
    assert K[0, 0] == pytest.approx(truth["fx_px"], rel=5e-4) and K[1, 1] == pytest.approx(truth["fy_px"], rel=5e-4)
    assert abs(K[0, 2] - truth["cx_px"]) < 0.1 and abs(K[1, 2] - truth["cy_px"]) < 0.1
    assert back["board"]["radius_spacings"] == pytest.approx(m["board"]["radius_spacings"], rel=5e-3)
    for a, b in zip(m["photos"], back["photos"]):
        assert np.abs(np.subtract(a["t_model"], b["t_model"])).max() < 0.01
        assert abs(a["dark"] - b["dark"]) < 3.0 and abs(a["white"] - b["white"]) < 3.0
        assert abs(a["sigma_x_px"] - b["sigma_x_px"]) < 0.12 and abs(a["sigma_y_px"] - b["sigma_y_px"]) < 0.12
