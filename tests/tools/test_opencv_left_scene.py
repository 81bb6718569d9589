"""tools/twins/opencv_left_scene.py: OpenCV's shipped twins (scenes/opencv_left_twin.toml, opencv_left_twin_bent.toml)
and their camera (assets/cameras/opencv_left.toml) are `edgetruth twin`'s derivation on the shipped photos (the bent
one with --bend), byte for byte; the camera and the curls are what `edgetruth calibrate opencv_left --corners lines`
measures."""
from __future__ import annotations

import json

import numpy as np
import pytest

from tests.support.tools import load_tool


@pytest.fixture(scope="module")
def tool():
    return load_tool("tools/twins/opencv_left_scene.py", "opencv_left_scene")


@pytest.mark.slow
def test_shipped_twins_are_the_packaged_derivation(tool):
    """Derived now from the shipped photos, the three files are the shipped ones byte for byte; the bent twin differs
    from the flat one only in its header, name, description, one board_bend_mm a group and its noise (the loop
    closed on path-traced renders: K, read noise and the irradiances that K sets), and it renders path-traced (the
    flat one without Monte-Carlo noise, board_mode = "frame")."""
    cam, flat, bent = tool.texts()
    assert cam == tool.CAMERA.read_text()
    assert flat == tool.SCENE.read_text()
    assert bent == tool.BENT.read_text()
    extra = [ln for ln in bent.splitlines() if ln not in flat.splitlines()]
    assert sum(ln.startswith("board_bend_mm = ") for ln in extra) == 13
    assert {ln.split(" =")[0] for ln in extra if not ln.startswith("#")} == {
        "board_bend_mm", "name", "description", "k0_dn_per_e", "dark_noise_e", "irradiance_w_m2", "board_mode"}
    assert 'board_mode = "frame"' in flat and 'board_mode = "frame"' not in bent.replace('(board_mode = "frame" takes', "")
    assert 'board_mode = "path"' in bent  # named: a curled board is outside the composite's scope


def test_bent_twin_is_what_calibrate_measures(tmp_path):
    """The shipped curls, converted from `edgetruth calibrate`'s bend check (its s, in metres) to the renderer's s
    (half the printed squares' box, ``render.scene.bend.BoardBend``: 112.25 mm for this board), agree with the
    derivation's own (in squares) to the file's rounding: within 2e-5 mm (measured: 1e-5, the last digit)."""
    from edgetruth.cli import main
    from edgetruth.render.dataset.spec import load_spec
    from edgetruth.render.scene.bend import BoardBend

    out = tmp_path / "cal.json"
    assert main(["calibrate", "opencv_left", "--pattern", "9x6", "--square-m", "0.025", "--corners", "lines",
                 "-o", str(out), "--no-progress"]) == 0
    q = json.loads(out.read_text())["board_bend"]["quadratic"]
    spec = load_spec("opencv_left_twin_bent")
    s_render_mm = 1e3 * BoardBend.of((0, 0, 0), spec.squares.black_quads_local(0.0)).scale_m
    assert s_render_mm == pytest.approx(112.25, abs=1e-9)  # (8 squares + 2 x 0.490 of the ring) x 25 mm / 2
    given = np.array([g.board_bend_mm for g in spec.groups])
    measured = np.array(q["coefficients_mm"]) * (s_render_mm / np.array(q["scale_mm"])[:, None]) ** 2
    assert given.shape == (13, 3) and np.abs(measured - given).max() <= 2e-5


def test_shipped_camera_is_the_photos_calibration(tmp_path):
    """K within 1e-4 px and the 5 distortion terms within 1e-5 (the default line corners: grid lines fitted in the
    undistorted image; the photo-frame fit would read fx 534.74 against 533.85).  The tool calibrates in squares and
    the command in metres, so OpenCV's solver stops at slightly different points: measured 2e-5 px on fx, 4e-6 on k3
    (the file rounds K to 1e-4 px and the terms to 1e-6)."""
    from edgetruth.cli import main
    from edgetruth.render.optics.camera import load_camera

    out = tmp_path / "cal.json"
    assert main(["calibrate", "opencv_left", "--pattern", "9x6", "--square-m", "0.025", "--corners", "lines",
                 "-o", str(out), "--no-progress"]) == 0
    d = json.loads(out.read_text())
    cam = load_camera("opencv_left")
    assert np.allclose(cam.K, d["K"], rtol=0, atol=1e-4)
    assert np.allclose(cam.dist_coeffs, d["dist_coeffs_opencv"], rtol=0, atol=1e-5)
