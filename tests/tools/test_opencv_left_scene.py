"""tools/twins/opencv_left_scene.py: OpenCV's shipped twin (scenes/opencv_left_twin.toml) and its camera
(assets/cameras/opencv_left.toml) are `edgetruth twin`'s derivation on the shipped photos, byte for byte, and the
camera is what `edgetruth calibrate opencv_left --corners lines` measures."""
from __future__ import annotations

import json

import numpy as np
import pytest

from tests.support.tools import load_tool


@pytest.fixture(scope="module")
def tool():
    return load_tool("tools/twins/opencv_left_scene.py", "opencv_left_scene")


def test_shipped_twin_is_the_packaged_derivation(tool):
    """Derived now from the shipped photos, both files are the shipped ones byte for byte."""
    cam, scene = tool.texts()
    assert cam == tool.CAMERA.read_text()
    assert scene == tool.SCENE.read_text()


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
