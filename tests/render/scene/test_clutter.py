"""Clutter: a planar shape held in front of the board.  It hides the target along the camera's rays and
casts a shadow (parallel planes: the outline scaled by D / (D - h) about the light's foot); checked against
the analytic geometry of a frontal pinhole view and against a render."""
from __future__ import annotations

import math

import numpy as np
import pytest

from edgetruth.errors import InputError
from edgetruth.render.optics.camera import Camera
from edgetruth.render.scene.ground_truth import SceneOutline, scene_ground_truth
from edgetruth.render.scene.lights import Light
from edgetruth.render.scene.materials import Material
from edgetruth.render.scene.pose import Pose
from edgetruth.render.scene.clutter import Clutter
from edgetruth.render.scene.shapes import Shape
from edgetruth.render.scene.target_scene import TargetScene
from tests.support.scenes import polyline_region

CAM = Camera(width_px=128, height_px=96, pitch_um=40.0, focal_length_mm=8.0, f_number=0.0, focus_distance_m=0.8,
             diffraction_wavelength_nm=0.0, natural_vignetting=False)  # fx = 200 px, no distortion, no PSF
POSE = Pose(0.8, 0.0, 0.0, 0.0, 0.0, 0.0)  # frontal: the camera centre is (0, 0, -0.8) in the board frame
H_M = 0.05  # how far the box stands in front of the board (raised_m)
LIGHT = Light("point", position_m=(0.0, -0.1, -0.05))  # board frame (0, -0.1, -0.85): D = 0.85 m
TARGET = Shape("rectangle", width_m=0.1, height_m=0.1, material=Material("diffuse", 0.04))
BOX = Shape("rectangle", offset_m=(0.05, 0.0), width_m=0.04, height_m=0.04, material=Material("diffuse", 0.5))
SCENE = TargetScene("custom", (TARGET,), lights=(LIGHT,), clutter=(Clutter(BOX, H_M),))


def _px(xy, z):
    cx, cy = CAM.principal_point_px
    xy = np.atleast_2d(xy)
    return np.column_stack([cx + CAM.fx_px * xy[:, 0] / z, cy + CAM.fy_px * xy[:, 1] / z])


def test_clutter_hides_the_target_along_the_camera_rays():
    gt = scene_ground_truth(CAM, POSE, SCENE)
    o = gt["shapes"][0]["outlines"][0]
    # a target point (x, y) at ~0.8 m is hidden where the ray meets z = -0.05 inside the box: the ray's
    # point there is (x, y) x 0.75 / 0.8; the right side x = 0.05 is hidden for |y| < 0.02 / 0.9375
    z0 = 0.8 - 10e-6
    s = (0.8 - H_M) / z0
    y_cut = 0.02 / s
    assert len(o["visible_intervals"]) == 1
    t0, t1 = o["visible_intervals"][0]
    assert t0 == pytest.approx(0.25 + (0.05 + y_cut) / 0.4, abs=1e-9)
    assert t1 == pytest.approx(1.25 + (0.05 - y_cut) / 0.4, abs=1e-9)
    assert o["corners_visible"] == [True, True, True, True]
    c = gt["clutter"][0]
    assert c["raised_m"] == H_M and c["height_m"] == 0.04 and c["type"] == "rectangle"
    exp = _px(np.array([[0.03, -0.02], [0.07, -0.02], [0.07, 0.02], [0.03, 0.02]]), 0.8 - H_M)
    assert np.max(np.abs(np.asarray(c["outlines"][0]["corners_distorted_px"]) - exp)) < 1e-9
    # the reader: on the target's hidden side the nearest visible edge is the box's (layer 1 = clutter 0)
    so = SceneOutline.from_ground_truth(gt)
    q = _px(np.array([[0.05, 0.0]]), z0)
    assert so.edge_shape(q[:, 0], q[:, 1])[0] == 1 and so.shape_at(q[:, 0], q[:, 1])[0] == 1
    box_left = _px(np.array([[0.03, 0.0]]), 0.8 - H_M)[0, 0]
    assert so.signed_distance(q[:, 0], q[:, 1])[0] == pytest.approx(-(q[0, 0] - box_left), abs=1e-6)


def test_shadow_outline_is_the_scaled_outline():
    sh = scene_ground_truth(CAM, POSE, SCENE)["clutter"][0]["shadows"][0]
    k = 0.85 / 0.8
    assert sh["cast"] and sh["exact"] and sh["scale"] == pytest.approx(k, rel=1e-12)
    foot = np.array([0.0, -0.1])
    box = np.array([[0.03, -0.02], [0.07, -0.02], [0.07, 0.02], [0.03, 0.02]])
    exp = _px(foot + k * (box - foot), 0.8)
    assert np.max(np.abs(np.asarray(sh["outlines"][0]["corners_distorted_px"]) - exp)) < 1e-9


def test_rendered_shadow_lies_where_the_truth_puts_it(fast_variant):
    """Point light, no ambient: a board pixel wholly inside the recorded shadow is black, one wholly
    outside it (and outside the box's and the target's images) shows 0.8 E / pi."""
    import mitsuba as mi

    from edgetruth.render.scene.mitsuba_scene import RenderSettings, TargetRig

    mi.set_variant(fast_variant)
    side = Light("point", position_m=(-0.6, 0.3, -0.05))  # the shadow falls right of the box's image
    scene = TargetScene("custom", (TARGET,), lights=(side,), clutter=(Clutter(BOX, H_M),))
    rig = TargetRig(CAM, RenderSettings(spp=64, sampler="multijitter"))
    rig.set_state(scene, POSE, 1.0)
    img = rig.render(2).astype(np.float64)
    gt = scene_ground_truth(CAM, POSE, scene)
    v, u = np.mgrid[0:96, 0:128].astype(float)
    q = np.column_stack([u.ravel(), v.ravel()])

    def region(poly):  # inside, and the distance to the closed polyline (px)
        return polyline_region(poly, q)

    in_sh, d_sh = region(gt["clutter"][0]["shadows"][0]["outlines"][0]["polyline_distorted_px"])
    in_box, d_box = region(gt["clutter"][0]["outlines"][0]["polyline_distorted_px"])
    in_t, d_t = region(gt["shapes"][0]["outlines"][0]["polyline_distorted_px"])
    clear = (d_sh > 0.75) & (d_box > 0.75) & (d_t > 0.75) & ~in_box & ~in_t
    shadowed, lit = clear & in_sh, clear & ~in_sh
    assert shadowed.sum() > 40 and lit.sum() > 1000
    z = 0.8
    cx, cy = CAM.principal_point_px
    pts = np.column_stack([(q[:, 0] - cx) * z / CAM.fx_px, (q[:, 1] - cy) * z / CAM.fx_px, np.full(len(q), z)])
    pred = 0.8 * side.irradiance_at(1.0, POSE, pts) / math.pi
    val = img.ravel()
    assert np.max(val[shadowed]) == 0.0
    assert np.max(np.abs(val[lit] / pred[lit] - 1)) < 1e-4  # measured 2e-5: the irradiance across a pixel


@pytest.mark.parametrize("item, needle", [
    ({"type": "ring", "inner_diameter_m": 0.02, "raised_m": 0.05}, "cannot stand as clutter"),
    ({"type": "circle"}, "raised_m missing"),
    ({"type": "circle", "raised_m": 1e-4}, "raised_m"),
    ({"type": "circle", "raised_m": 0.05, "width_m": 0.1}, "width_m"),
])
def test_bad_clutter_is_a_one_line_error(item, needle):
    from edgetruth.render.scene.clutter import clutter_from_list

    with pytest.raises(InputError) as e:
        clutter_from_list([item], 0.13, "group 'g' clutter")
    assert needle in str(e.value) and "\n" not in str(e.value)


def test_clutter_only_enters_the_identity_when_set():
    plain = TargetScene("custom", (TARGET,))
    assert "clutter" not in plain.resolved()
    assert SCENE.resolved()["clutter"][0]["raised_m"] == H_M
