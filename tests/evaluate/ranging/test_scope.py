"""Which rendered target images the ranging sizes: one target of a shape it models (square, rectangle, circle).
An own scene of several outlines, or another shape, is scored per point only (its rows say why); a rectangle's
floors come from its own geometry (width, and its height for the pose), not a circle's."""
from __future__ import annotations

import numpy as np
import pytest

from edgetruth.evaluate.ranging.images import ranging_scope, true_pose_distance, true_size_px
from edgetruth.render.scene.ground_truth import scene_ground_truth
from edgetruth.render.scene.shapes import Shape
from edgetruth.render.scene.target_scene import TargetScene

from tests.support.scenes import FRONTAL, PINHOLE, TILTED


def _gt(*shapes, pose=FRONTAL):
    gt = scene_ground_truth(PINHOLE, pose, TargetScene("custom", tuple(shapes)))
    gt["camera"] = {"K": [[PINHOLE.fx_px, 0.0, PINHOLE.principal_point_px[0]],
                          [0.0, PINHOLE.fy_px, PINHOLE.principal_point_px[1]], [0.0, 0.0, 1.0]]}
    return gt


def test_scope_names_what_is_not_ranged():
    assert ranging_scope(_gt(Shape("rectangle", width_m=0.1, height_m=0.06))) == ""
    assert ranging_scope(_gt(Shape("circle", diameter_m=0.05))) == ""
    two = ranging_scope(_gt(Shape("rectangle", width_m=0.1, height_m=0.06),
                            Shape("circle", offset_m=(0.08, 0.0), diameter_m=0.04)))
    assert two.startswith("a scene of several outlines") and two.endswith("scored per point")
    assert ranging_scope(_gt(Shape("ellipse", width_m=0.1, height_m=0.05))) == \
        "an ellipse (ranging sizes a square, a rectangle or a circle); scored per point"


def test_a_rectangles_floors_are_its_width_and_its_pose():
    """Frontal at 0.8 m through the pinhole (fx 400 px): l = fx w / z = 50 px to 1e-9, and the pose distance is
    the true 0.8 m (the circle's formula on four corners gave 94 px and "circle pose: 4 edge points")."""
    gt = _gt(Shape("rectangle", width_m=0.1, height_m=0.06))
    z = float(gt["true_distance_m"])
    assert true_size_px(gt) == pytest.approx(PINHOLE.fx_px * 0.1 / z, abs=1e-6)
    assert true_pose_distance(gt) == pytest.approx(z, abs=1e-6)
    tilted = _gt(Shape("rectangle", width_m=0.1, height_m=0.06), pose=TILTED)
    assert true_pose_distance(tilted) == pytest.approx(float(tilted["true_distance_m"]), rel=1e-6)
    assert np.isfinite(true_size_px(tilted))


SCENE_SPEC = """
[spec]
name = "scene_eval"
camera = "mid.toml"
spp = 16
edge_spp = 64
checkerboard_spp = 16
edge_mode = "path"
board_mode = "path"
checkerboard = { cols = 8, rows = 6, square_m = 0.03, margin_m = 0.02 }

[[group]]
name = "scene"
distance_range_cm = [100, 150]
count = 2
[[group.shapes]]
type = "rectangle"
width_m = 0.10
height_m = 0.07
[[group.shapes]]
type = "circle"
offset_m = [0.09, 0]
diameter_m = 0.05

[[group]]
name = "boards"
kind = "checkerboard"
distance_range_cm = [90, 130]
count = 8
tilt_max_deg = 30
"""
MID_CAMERA = """
[camera]
width_px = 320
height_px = 256
pitch_um = 4.8
focal_length_mm = 4
f_number = 4
focus_distance_m = 1.0
[camera.distortion]
k1 = -0.05
"""


@pytest.mark.slow
def test_evaluate_scores_an_own_scene_per_point_and_says_it_is_not_ranged(tmp_path, capsys, fast_variant):
    """`edgetruth evaluate` on a two-shape scene stopped with "circle pose: 4 edge points (need 8)" (a rectangle's
    truth read as a circle's): now its rows say why it is not ranged, the report's header counts them, and Table
    E1 scores its points on both shapes against the exact outlines."""
    from edgetruth.cli import main

    (tmp_path / "mid.toml").write_text(MID_CAMERA)
    (tmp_path / "scene.toml").write_text(SCENE_SPEC)
    assert main(["render", str(tmp_path / "scene.toml"), "-o", str(tmp_path / "d"), "--no-progress"]) == 0
    out = tmp_path / "ev"
    assert main(["evaluate", str(tmp_path / "d"), "-o", str(out), "--methods", "erf4p_fixed11,canny_devernay",
                 "--no-progress"]) == 0
    assert "Traceback" not in capsys.readouterr().err
    text = (out / "report.md").read_text()
    assert "- **not ranged**: 2 image(s): a scene of several outlines" in text
    e1 = text[text.index("## Table E1"):text.index("## Table E2")]
    row = [ln for ln in e1.splitlines() if ln.startswith("| ERF4P-fixed11 |")][0]
    rmse = float(row.split("|")[4])
    assert 0.0 < rmse < 0.1  # a 320-px camera, path-traced edges at 64 spp: measured 0.049
