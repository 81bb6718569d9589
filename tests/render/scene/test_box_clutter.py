"""Box clutter: a cuboid standing on the board.  Its image bounds the board along its silhouette (the convex
hull of its corners' images: straight 3-D edges through the lens), it hides the outlines behind it, and it
casts a shadow (from a point light: the hull of its corners' central projections on the board).  Checked
against hand geometry in a frontal pinhole view and against renders: a distorted, tilted view for the
silhouette (edge within 0.01 px), a frontal one for the shadow (dark / lit pixels as predicted)."""
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
from edgetruth.render.scene.clutter import Box, Clutter, clutter_from_list
from edgetruth.render.scene.shapes import Shape
from edgetruth.render.scene.target_scene import TargetScene
from tests.support.scenes import polyline_region

CAM = Camera(width_px=128, height_px=96, pitch_um=40.0, focal_length_mm=8.0, f_number=0.0, focus_distance_m=0.8,
             diffraction_wavelength_nm=0.0, natural_vignetting=False)  # fx = 200 px, no distortion, no PSF
POSE = Pose(0.8, 0.0, 0.0, 0.0, 0.0, 0.0)  # frontal: the camera centre is (0, 0, -0.8) in the board frame
BASE_M = 20e-6  # one shape on the board: the box stands 2 stand-offs in front of it
TARGET = Shape("rectangle", width_m=0.1, height_m=0.1, material=Material("diffuse", 0.04))
BOX = Box(size_m=(0.04, 0.04, 0.05), offset_m=(0.05, 0.0), material=Material("diffuse", 0.5), base_m=BASE_M)
LIGHT = Light("point", position_m=(0.0, -0.1, -0.05))
SCENE = TargetScene("custom", (TARGET,), lights=(LIGHT,), clutter=(Clutter(BOX, 0.0),))


def _px(xyz):
    """Frontal pinhole image of board-frame points (N, 3)."""
    p = np.atleast_2d(xyz)
    z = 0.8 + p[:, 2]
    cx, cy = CAM.principal_point_px
    return np.column_stack([cx + CAM.fx_px * p[:, 0] / z, cy + CAM.fy_px * p[:, 1] / z])


def test_silhouette_is_the_hull_of_the_corners_images():
    """Seen from (0, 0, -0.8) the box (x in [0.03, 0.07]) shows its top and its left side: the silhouette
    is the top's 4 corners and the left side's 2 base corners (the right base corners fall inside)."""
    gt = scene_ground_truth(CAM, POSE, SCENE)
    c = gt["clutter"][0]
    assert c["type"] == "box" and c["size_m"] == [0.04, 0.04, 0.05] and c["base_m"] == BASE_M
    o = c["outlines"][0]
    assert o["name"] == "silhouette" and o["visible_intervals"] == [[0.0, 1.0]]
    top, base = -BASE_M - 0.05, -BASE_M
    exp = _px(np.array([[0.03, -0.02, top], [0.07, -0.02, top], [0.07, 0.02, top], [0.03, 0.02, top],
                        [0.03, -0.02, base], [0.03, 0.02, base]]))
    got = np.asarray(o["corners_distorted_px"])
    assert len(got) == 6
    assert max(np.min(np.linalg.norm(got - e, axis=1)) for e in exp) < 1e-9
    # each side is straight in this undistorted view: the polyline lies on the chords between its corners
    poly = np.asarray(o["polyline_distorted_px"])
    e = np.roll(got, -1, 0) - got
    d = [np.min(np.abs(e[:, 0] * (p - got)[:, 1] - e[:, 1] * (p - got)[:, 0]) / np.linalg.norm(e, axis=1)) for p in poly]
    assert max(d) < 1e-9


def test_box_hides_the_target_behind_it():
    """The target's right side x = 0.05 m runs under the box; a point on it is hidden where the ray to the
    eye crosses the box: for |y| below the top's edge 0.02 m seen through the ray, 0.02 x (0.8 - 1e-5) /
    (0.8 - 0.05 - 2e-5)."""
    gt = scene_ground_truth(CAM, POSE, SCENE)
    o = gt["shapes"][0]["outlines"][0]
    y_cut = 0.02 * (0.8 - 10e-6) / (0.8 - 0.05 - BASE_M)
    assert len(o["visible_intervals"]) == 1
    t0, t1 = o["visible_intervals"][0]
    assert t0 == pytest.approx(0.25 + (0.05 + y_cut) / 0.4, abs=1e-9)
    assert t1 == pytest.approx(1.25 + (0.05 - y_cut) / 0.4, abs=1e-9)
    so = SceneOutline.from_ground_truth(gt)
    q = _px(np.array([[0.05, 0.0, -10e-6]]))
    assert so.edge_shape(q[:, 0], q[:, 1])[0] == 1 and so.shape_at(q[:, 0], q[:, 1])[0] == 1
    # the nearest visible edge there: the silhouette's left side, the base's left edge (the left face is seen)
    left = _px(np.array([[0.03, 0.0, -BASE_M]]))[0, 0]
    assert so.signed_distance(q[:, 0], q[:, 1])[0] == pytest.approx(-(q[0, 0] - left), abs=1e-6)


def test_shadow_is_the_hull_of_the_corners_projections():
    sh = scene_ground_truth(CAM, POSE, SCENE)["clutter"][0]["shadows"][0]
    assert sh["cast"] and sh["exact"]
    lb = np.array([0.0, -0.1, -0.85])
    c = BOX.corners()
    s = lb[2] / (lb[2] - c[:, 2])
    proj = lb[:2] + s[:, None] * (c[:, :2] - lb[:2])
    # the light's foot (0, -0.1) lies up and left of the box: the shadow spreads right and down; its
    # corners are the hull's (scipy's, an implementation of its own) of the 8 projections: 6 of them
    from scipy.spatial import ConvexHull

    exp = proj[ConvexHull(proj).vertices]
    assert len(exp) == 6 and sorted(ConvexHull(proj).vertices) == [0, 1, 3, 5, 6, 7]
    got = np.asarray(sh["outlines"][0]["corners_distorted_px"])
    assert len(got) == 6
    assert max(np.min(np.linalg.norm(got - e, axis=1)) for e in _px(np.column_stack([exp, np.zeros(6)]))) < 1e-9
    # its side along the base (under the box's upper edge) is not a shadow edge in the image
    vis = sh["outlines"][0]["visible_intervals"]
    assert vis and all(t1 - t0 < 1.0 for t0, t1 in vis)


def test_box_segment_test_and_faces():
    box = Box(size_m=(0.02, 0.04, 0.03), offset_m=(0.1, -0.05), rotation_deg=35.0)
    eye = np.array([0.0, 0.0, -0.8])
    centre = np.array([[0.1, -0.05, -0.015 - box.base_m]])
    behind = eye + (centre[0] - eye) * (-eye[2] / (centre[0, 2] - eye[2]))  # on the board, on the eye's ray
    assert behind[2] == pytest.approx(0.0, abs=1e-15) and box.segment_hits(eye, behind[None])[0]
    assert not box.segment_hits(eye, np.array([[0.3, 0.2, 0.0]]))[0]
    assert not box.segment_hits(eye, box.silhouette(eye)).any()  # its own silhouette only grazes it
    tris = box.faces()
    c = box.corners()
    n = np.cross(c[tris[:, 1]] - c[tris[:, 0]], c[tris[:, 2]] - c[tris[:, 0]])
    assert len(tris) == 10 and np.all(np.sum(n * (c[tris].mean(1) - c.mean(0)), axis=1) > 0)  # outward


@pytest.mark.parametrize("item, needle", [
    ({"type": "box"}, "size_m"),
    ({"type": "box", "size_m": [0.1, 0.1]}, "size_m"),
    ({"type": "box", "size_m": [0.1, 0.1, 0.0]}, "size_m"),
    ({"type": "box", "size_m": [0.1, 0.1, 0.1], "raised_m": 0.05}, "raised_m does not apply"),
    ({"type": "box", "size_m": [0.1, 0.1, 0.1], "diameter_m": 0.05}, "diameter_m"),
    ({"type": "box", "size_m": [0.1, 0.1, 0.1], "material": {"albedo": 2}}, "albedo"),
])
def test_bad_box_is_a_one_line_error(item, needle):
    with pytest.raises(InputError) as e:
        clutter_from_list([item], 0.13, "group 'g' clutter")
    assert needle in str(e.value) and "\n" not in str(e.value), str(e.value)


def test_box_in_a_spec_and_as_a_design_factor(tmp_path):
    from edgetruth.render.dataset.spec import load_spec
    from tests.support.scenes import GROUP_SPEC

    p = tmp_path / "x.toml"
    p.write_text(GROUP_SPEC.format(extra='shapes = [{ type = "circle" }, { type = "rectangle", offset_m = [0.2, 0] }]\n'
                                         'clutter = [{ type = "box", size_m = [0.05, 0.04, 0.1], offset_m = [-0.2, 0],'
                                         ' rotation_deg = 10 }]'))
    sc = load_spec(p).groups[0].target
    box = sc.clutter[0].shape
    assert box.type == "box" and box.size_m == (0.05, 0.04, 0.1) and box.base_m == pytest.approx(30e-6)
    assert sc.resolved()["clutter"][0] == box.to_dict()
    d = tmp_path / "d.toml"
    d.write_text('[spec]\nname = "x"\ncamera_scale = 16\n[design]\ncount = 2\n[[design.factor]]\nname = "clutter"\n'
                 'levels = [{ name = "short", clutter = [{ type = "box", size_m = [0.05, 0.05, 0.02], offset_m = [0.2, 0] }] },\n'
                 '          { name = "tall", clutter = [{ type = "box", size_m = [0.05, 0.05, 0.2], offset_m = [0.2, 0] }] }]\n')
    spec = load_spec(d)
    heights = sorted(g.target.clutter[0].shape.size_m[2] for g in spec.groups)
    assert heights == [0.02, 0.2] and len({g.target for g in spec.groups}) == 2


# --- renders ------------------------------------------------------------------------------------------
def test_rendered_shadow_of_a_box_lies_where_the_truth_puts_it(fast_variant):
    """Point light to the left, no ambient: a board pixel wholly inside the recorded shadow (and off the
    box's image) is black, one wholly outside it, the box and the target shows 0.8 E / pi."""
    import mitsuba as mi

    from edgetruth.render.scene.mitsuba_scene import RenderSettings, TargetRig

    mi.set_variant(fast_variant)
    side = Light("point", position_m=(-0.6, 0.3, -0.05))
    target = Shape("rectangle", offset_m=(-0.1, 0.0), width_m=0.05, height_m=0.05, material=Material("diffuse", 0.04))
    scene = TargetScene("custom", (target,), lights=(side,), clutter=(Clutter(BOX, 0.0),))
    rig = TargetRig(CAM, RenderSettings(spp=64, sampler="multijitter"))
    rig.set_state(scene, POSE, 1.0)
    img = rig.render(2).astype(np.float64)
    gt = scene_ground_truth(CAM, POSE, scene)
    v, u = np.mgrid[0:96, 0:128].astype(float)
    q = np.column_stack([u.ravel(), v.ravel()])

    def region(poly):  # inside, and the distance to the closed polyline (px)
        return polyline_region(poly, q)

    sh = gt["clutter"][0]["shadows"][0]
    assert sh["cast"] and sh["exact"]
    in_sh, d_sh = region(sh["outlines"][0]["polyline_distorted_px"])
    in_box, d_box = region(gt["clutter"][0]["outlines"][0]["polyline_distorted_px"])
    in_t, d_t = region(gt["shapes"][0]["outlines"][0]["polyline_distorted_px"])
    clear = (d_sh > 0.75) & (d_box > 0.75) & (d_t > 0.75) & ~in_box & ~in_t
    shadowed, lit = clear & in_sh, clear & ~in_sh
    assert shadowed.sum() > 100 and lit.sum() > 1000
    z = 0.8
    cx, cy = CAM.principal_point_px
    pts = np.column_stack([(q[:, 0] - cx) * z / CAM.fx_px, (q[:, 1] - cy) * z / CAM.fx_px, np.full(len(q), z)])
    pred = 0.8 * side.irradiance_at(1.0, POSE, pts) / math.pi
    val = img.ravel()
    assert np.max(val[shadowed]) == 0.0
    assert np.max(np.abs(val[lit] / pred[lit] - 1)) < 1e-4  # the irradiance across a pixel
    # the box's visible faces are lit (albedo 0.5): its silhouette is an edge against the board
    assert np.min(val[in_box & (d_box > 0.75)]) > 0.0


def test_rendered_silhouette_is_the_visible_outline(fast_variant):
    """A black box (albedo 0) on the white board, seen through lens distortion from a tilted pose: each side
    of the recorded silhouette is where the image's edge is, within 0.01 px (line fit per side of the
    measured - exact offsets, as tests/render/scene/test_shapes_edges.py measures the printed shapes).  The
    point light sits 1 mm behind the camera on the line from the box's centre, so the box's shadow lies
    wholly behind it (the truth says so: no visible shadow edge) and the board next to it is lit."""
    import mitsuba as mi

    from edgetruth.render.scene.mitsuba_scene import RenderSettings, TargetRig
    from edgetruth.render.scene.outline import OutlineCurve
    from tests.render.scene.test_shapes_edges import CAMERA, POSE as TILTED, TOL_PX, measure_piece

    mi.set_variant(fast_variant)
    box = Box(size_m=(0.06, 0.05, 0.05), offset_m=(0.03, 0.02), rotation_deg=25.0,
              material=Material("diffuse", 0.0), base_m=BASE_M)
    centre = TILTED.to_camera(np.array([[0.03, 0.02, -BASE_M - 0.025]]))[0]  # the box's centre, camera frame
    behind = tuple(-1e-3 * centre / np.linalg.norm(centre))  # 1 mm behind the eye, away from the box
    target = Shape("circle", offset_m=(-0.1, -0.06), diameter_m=0.03, material=Material("diffuse", 0.04))
    scene = TargetScene("custom", (target,), lights=(Light("point", position_m=behind),), clutter=(Clutter(box, 0.0),))
    gt = scene_ground_truth(CAMERA, TILTED, scene)
    sh = gt["clutter"][0]["shadows"][0]
    assert sh["cast"] and sh["outlines"][0]["visible_intervals"] == []  # hidden behind the box
    o = gt["clutter"][0]["outlines"][0]
    assert o["visible_intervals"] == [[0.0, 1.0]] and len(o["vertices_board_m"]) == 6
    rig = TargetRig(CAMERA, RenderSettings(spp=1024, sampler="multijitter"))
    rig.set_state(scene, TILTED, 1.0)
    img = rig.render(11).astype(np.float64)
    curve = OutlineCurve.polygon(CAMERA, TILTED, np.asarray(o["vertices_board_m"]))
    assert np.max(np.abs(curve.points(np.asarray(o["polyline_parameter"])) - np.asarray(o["polyline_distorted_px"]))) < 1e-9
    others = [np.asarray(gt["shapes"][0]["outlines"][0]["polyline_distorted_px"])]
    n = len(o["vertices_board_m"])
    fitted = []
    for j in range(n):
        t0, t1 = j / n + 1e-6, (j + 1) / n - 1e-6
        rest = curve.points(np.linspace(t1 + 1e-5, t0 + 1 - 1e-5, 4000))
        pos, r = measure_piece(img, curve, t0, t1, others + [rest])
        if len(r) >= 4:
            b, a = np.polyfit(pos, r, 1)
            fitted.append((j, len(r), max(abs(a - b), abs(a + b))))
    assert len(fitted) >= 4, fitted
    assert max(f[2] for f in fitted) <= TOL_PX, fitted


def test_every_box_truth_key_is_documented():
    """The box's truth block (silhouette, shadows from a point and an area light, their regions) uses only
    keys docs/formats.md names."""
    from tests.package.test_formats_doc import DOCUMENTED, _nested_keys

    scene = TargetScene("custom", (TARGET,), lights=(LIGHT, Light("area", size_m=0.1)), clutter=(Clutter(BOX, 0.0),))
    gt = scene_ground_truth(CAM, POSE, scene)
    assert gt["clutter"][0]["shadows"][1]["regions_given"]
    missing = sorted(_nested_keys(gt["clutter"]) - DOCUMENTED)
    assert not missing, missing
