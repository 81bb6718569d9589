"""A photo set's lens shading (``evaluate/board/twin/shading.py``): the light squares' levels, the twin's light at them,
and the fit of the renderer's 1 + a2 h² + a4 h⁴ on what is left."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from edgetruth.evaluate.board.twin import shading as sh
from edgetruth.evaluate.board.twin import derive as td
from edgetruth.evaluate.board.twin import measure as tm
from tests.evaluate.board.chessboard_images import write_views

H = np.linspace(0.0, 1.0, 11)


def test_light_squares_are_those_between_dark_ones():
    """A 9x6 board's light squares among its dark ones (the model's dark squares are those between inner corners):
    the 20 light ones of the 8 x 5 inner squares, each once, at half-integer centres."""
    c = sh.light_square_centres((9, 6))
    assert len(c) == len(np.unique(c, axis=0)) == 20
    assert np.all((c * 2) % 2 == 1) and c.min(axis=0).tolist() == [0.5, 0.5] and c.max(axis=0).tolist() == [7.5, 4.5]
    assert all(((x - 0.5) + (y - 0.5)) % 2 == 1 for x, y in c)  # the model's dark square (0, 0) is not among them


def test_the_light_is_one_at_the_centre_and_falls_off_as_cos_cos_over_r2():
    """A board facing a light 1 m straight ahead: at 0.1 m off the centre cos_b = cos_l = 1/sqrt(1.01) and r² = 1.01,
    so 1/1.01² of the centre."""
    pts = np.array([[0.0, 0.0, 1.0], [0.1, 0.0, 1.0]])
    f = sh.light_falloff(pts, np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, -1.0]), np.array([0.0, 0.0, 0.0]))
    assert f == pytest.approx([1.0, 1.0 / 1.01 ** 2], rel=1e-12)


def test_the_fit_recovers_a_known_shading():
    """Levels W_i · light · (1 - 0.3 h² + 0.1 h⁴) with 0.5 % noise over 4 photos (30 levels each, h up to 0.9): the
    fitted polynomial within 0.01 of the true one over 0 ≤ h ≤ 1, the RMS about it the noise's (to 20 %); with
    one photo, no shading and a note."""
    rng = np.random.default_rng(0)
    photos = []
    for i in range(4):
        h, light = rng.uniform(0.0, 0.9, 30), rng.uniform(0.8, 1.2, 30)
        level = (150 + 20 * i) * light * sh.lens_shading(h, -0.3, 0.1) * (1 + 0.005 * rng.standard_normal(30))
        photos.append({"level": level, "light": light, "h": h})
    fit = sh.fit_shading(photos)
    assert np.abs(sh.lens_shading(H, fit["a2"], fit["a4"]) - sh.lens_shading(H, -0.3, 0.1)).max() < 0.01
    assert fit["rms_after"] == pytest.approx(0.005, rel=0.2) and fit["rms_before"] > 3 * fit["rms_after"]
    one = sh.fit_shading(photos[:1])
    assert (one["a2"], one["a4"]) == (0.0, 0.0) and "too few" in one["note"]


@pytest.mark.parametrize("a2, a4", [(0.0, 0.0), (-0.3, 0.1)])
def test_a_twin_reads_the_views_shading(tmp_path, a2, a4):
    """The 4 PNG views times a known shading (none, or 1 - 0.3 h² + 0.1 h⁴ about the principal point): the twin's
    camera carries it within 0.005 (measured: 0.001) over the field heights its light squares span (0 to 0.39;
    beyond them the polynomial is not measured, and the twin's board is not there either). The views are lit evenly,
    so the twin's light is placed far off (100 m behind the camera), where it lights a plane evenly too."""
    from edgetruth.render.dataset.spec import load_spec

    paths, _ = write_views(tmp_path, ".png", noise_dn=1.0)
    yy, xx = np.mgrid[0:480, 0:640]
    h = np.hypot(xx - 319.5, yy - 239.5) / 400.0
    for p in paths:
        img = cv2.imread(str(p), cv2.IMREAD_GRAYSCALE).astype(float)
        cv2.imwrite(str(p), np.clip(np.round(img * sh.lens_shading(h, a2, a4)), 0, 255).astype(np.uint8))
    m = tm.measure_chessboard(paths, (9, 6))
    assert all(len(p["light_levels"]) == 20 for p in m["photos"])
    far = td.TwinAssumptions(light_position_m=(0.0, 0.0, -100.0))
    cam, scene = td.twin_texts(m, "s", "shaded views", "camera.toml", 0.03, "four views", far)
    (tmp_path / "camera.toml").write_text(cam)
    (tmp_path / "twin.toml").write_text(scene)
    c = load_spec(tmp_path / "twin.toml").camera
    uv = np.concatenate([sh.project(sh.light_square_centres((9, 6)), p["R"], p["t_squares"], m["K"], m["dist"])
                         for p in m["photos"]])
    hs = np.linspace(0.0, np.hypot(uv[:, 0] - m["K"][0][2], uv[:, 1] - m["K"][1][2]).max() / 400.0, 21)
    err = np.abs(sh.lens_shading(hs, c.shading_a2, c.shading_a4) - sh.lens_shading(hs, a2, a4)).max()
    print(f"shading a2 {c.shading_a2:.4f} a4 {c.shading_a4:.4f}: within {err:.4f} of the views' to h {hs[-1]:.2f}")
    assert 0.3 < hs[-1] < 0.5 and err < 0.005


def test_the_board_centre_is_the_renderers():
    """The twin's board centre (where its lamp aims and its irradiance is set) is the renderer's: the middle of the
    inner corners is ``SquareBoard.centre_model_m`` for any ring cut alike on both sides."""
    from edgetruth.render.scene.targets import SquareBoard

    for cols, rows, ring in ((9, 6, (0.49, 0.955)), (7, 5, (1.0, 1.0)), (8, 6, (0.3, 0.7))):
        centre = SquareBoard.chessboard(cols, rows, 0.03, ring).centre_model_m
        photo = {"R": np.eye(3).tolist(), "t_squares": [0.0, 0.0, 0.0]}
        centre_model = td.centre_model({"pattern": [cols, rows]})
        assert np.allclose(td.board_centre_m(photo, centre_model, 0.03), centre, atol=1e-15)


def test_a_models_board_centre_is_the_renderers():
    """For a board of separate squares (Zhang's model, in inches) the twin's centre is the renderer's too: the
    squares' bounding-box centre, carried by the pose."""
    from edgetruth.evaluate.board.model import read_model
    from edgetruth.evaluate.board.reference import shipped_set
    from edgetruth.render.scene.targets import SquareBoard

    model = read_model(shipped_set("zhang1998")["model"])
    q = model.corners.reshape(-1, 2)
    m = {"board": {"centre_model": (0.5 * (q.min(0) + q.max(0))).tolist()}}
    board = SquareBoard(quads_model_m=model.corners * 0.0254)
    photo = {"R": np.eye(3).tolist(), "t_model": [0.0, 0.0, 0.0]}
    assert np.allclose(td.board_centre_m(photo, td.centre_model(m), 0.0254), board.centre_model_m, atol=1e-15)
