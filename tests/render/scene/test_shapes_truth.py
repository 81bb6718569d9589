"""Exact truth of the shape catalogue: signed distances against the analytic curves, the visible outline
where one shape covers another, the JSON, the presets, and the spec keys' one-line errors."""
from __future__ import annotations

import math

import numpy as np
import pytest

from edgetruth.errors import InputError
from edgetruth.render.scene.outline import OutlineCurve
from edgetruth.render.scene.shapes import Shape, visible_intervals
from edgetruth.render.scene.target_scene import TargetScene

from tests.support.scenes import DISTORTED, FRONTAL, PINHOLE, TILTED, Z_M


def _points_near(curve, rng, n=400, spread_px=3.0):
    t = rng.uniform(0, 1, n)
    p = curve.points(t)
    return p + rng.normal(0, spread_px, p.shape)


def test_signed_distance_of_a_circle_equals_the_analytic_circle():
    """Frontal pinhole: a board circle of radius r at (ox, oy) images to a circle of radius fx r / Z."""
    rng = np.random.default_rng(1)
    s = Shape("circle", offset_m=(0.03, -0.02), diameter_m=0.08)
    curve = OutlineCurve.of(PINHOLE, FRONTAL, s.outlines()[0], Z_M)
    z = 0.8 - Z_M
    c = np.array([PINHOLE.principal_point_px[0] + PINHOLE.fx_px * 0.03 / z,
                  PINHOLE.principal_point_px[1] + PINHOLE.fy_px * -0.02 / z])
    r_px = PINHOLE.fx_px * 0.04 / z
    q = _points_near(curve, rng)
    exact = np.linalg.norm(q - c, axis=1) - r_px
    got = curve.signed_distance(q[:, 0], q[:, 1])
    # the polyline's chord error: step^2 / (8 r) at its 0.25 px step
    assert np.max(np.abs(got - exact)) < 1.05 * 0.25 ** 2 / (8 * r_px)
    assert np.max(np.abs(curve.signed_distance(q[:, 0], q[:, 1], exact=True) - exact)) < 1e-9


def test_signed_distance_of_a_turned_rectangle_equals_the_analytic_polygon():
    rng = np.random.default_rng(2)
    s = Shape("rectangle", offset_m=(-0.02, 0.01), rotation_deg=27.0, width_m=0.1, height_m=0.05)
    curve = OutlineCurve.of(PINHOLE, FRONTAL, s.outlines()[0], Z_M)
    corners = curve.points(np.arange(4) / 4)
    q = _points_near(curve, rng)

    def seg_dist(p, a, b):
        d = b - a
        u = np.clip(((p - a) @ d) / (d @ d), 0, 1)
        return np.linalg.norm(p - (a + u[:, None] * d), axis=1)

    dist = np.min([seg_dist(q, corners[i], corners[(i + 1) % 4]) for i in range(4)], axis=0)
    from edgetruth.render.scene.polygons import point_in_polygon

    exact = np.where(point_in_polygon(corners, q), -dist, dist)
    got = curve.signed_distance(q[:, 0], q[:, 1])
    assert np.max(np.abs(got - exact)) < 1e-6


@pytest.mark.parametrize("shape", [
    Shape("ellipse", offset_m=(0.02, 0.03), rotation_deg=35.0, axes_m=(0.12, 0.05)),
    Shape("polygon", offset_m=(-0.03, 0.0), rotation_deg=-15.0,
          vertices_m=((-0.04, -0.03), (0.05, -0.02), (0.0, 0.0), (0.04, 0.04), (-0.03, 0.03))),
    Shape("ring", outer_diameter_m=0.1, inner_diameter_m=0.04),
])
def test_signed_distance_through_the_lens_equals_the_nearest_point_of_the_exact_curve(shape):
    """Distorted, tilted: |signed distance| equals the distance to the exact curve found by minimising over
    its parameter (dense search, then a bounded 1-D minimisation)."""
    from scipy.optimize import minimize_scalar

    rng = np.random.default_rng(3)
    for o in shape.outlines():
        curve = OutlineCurve.of(DISTORTED, TILTED, o, Z_M)
        q = _points_near(curve, rng, n=60, spread_px=2.0)
        got = curve.signed_distance(q[:, 0], q[:, 1], exact=True)
        coarse = curve.signed_distance(q[:, 0], q[:, 1])
        # the polyline's chord error step^2 kappa / 8: the ellipse's ends curve at a 5 px radius here
        assert np.all(np.sign(coarse) == np.sign(got)) and np.max(np.abs(coarse - got)) < 2e-3
        t_dense = np.linspace(0, 1, 20001)
        dense = curve.points(t_dense)
        for p, g in zip(q, got):
            k = int(np.argmin(np.linalg.norm(dense - p, axis=1)))
            ref = float(np.linalg.norm(dense[k] - p))
            for lo, hi in ((max(k - 2, 0), k), (k, min(k + 2, len(t_dense) - 1))):  # each side of a corner
                res = minimize_scalar(lambda t: float(np.linalg.norm(curve.points(np.array([t]))[0] - p)),
                                      bounds=(t_dense[lo], t_dense[hi]), method="bounded",
                                      options={"xatol": 1e-13})
                ref = min(ref, float(res.fun))
            assert abs(abs(g) - ref) < 1e-8, (o.name, p, g, ref)


def test_ellipse_curve_lies_on_the_imaged_conic():
    """Frontal pinhole: the image of a board ellipse is the ellipse scaled by fx / Z."""
    s = Shape("ellipse", offset_m=(0.01, -0.02), rotation_deg=40.0, axes_m=(0.1, 0.04))
    curve = OutlineCurve.of(PINHOLE, FRONTAL, s.outlines()[0], Z_M)
    p = curve.points(np.linspace(0, 1, 500, endpoint=False))
    z = 0.8 - Z_M
    c = np.array(PINHOLE.principal_point_px) + PINHOLE.fx_px * np.array([0.01, -0.02]) / z
    th = math.radians(40.0)
    u = (p - c) @ np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
    a, b = PINHOLE.fx_px * 0.05 / z, PINHOLE.fx_px * 0.02 / z
    assert np.max(np.abs((u[:, 0] / a) ** 2 + (u[:, 1] / b) ** 2 - 1)) < 1e-12


def test_visible_outline_of_a_square_half_covered_by_a_disk():
    """A square of half side h, a disk of radius r < h centred on its right side: the right side is hidden
    for |y| < r; side 1 runs from (h, -h) to (h, h) at t = 1/4 ... 1/2."""
    h, r = 0.05, 0.02
    sq = Shape("rectangle", width_m=2 * h, height_m=2 * h)
    disk = Shape("circle", offset_m=(h, 0.0), diameter_m=2 * r)
    vis = visible_intervals(sq.outlines()[0], [disk])
    t_in, t_out = 0.25 + (h - r) / (2 * h) / 4, 0.25 + (h + r) / (2 * h) / 4
    assert len(vis) == 1
    t0, t1 = vis[0]
    assert t0 == pytest.approx(t_out, abs=1e-12) and t1 == pytest.approx(t_in + 1.0, abs=1e-12)
    # the disk's own outline: the arc inside the square is covered by nothing later, so all visible
    assert visible_intervals(disk.outlines()[0], []) == [[0.0, 1.0]]
    # the square's outline under the disk is hidden: the part of the disk's outline inside the square
    vis_d = visible_intervals(disk.outlines()[0], [sq])
    assert len(vis_d) == 1 and vis_d[0][0] == pytest.approx(0.75, abs=1e-12) and vis_d[0][1] == \
        pytest.approx(1.25, abs=1e-12)


def test_a_ring_covers_its_hole():
    ring = Shape("ring", outer_diameter_m=0.1, inner_diameter_m=0.05)
    assert ring.covers(np.array([[0.0, 0.0], [0.04, 0.0], [0.06, 0.0]])).tolist() == [True, True, False]
    small = Shape("circle", diameter_m=0.02)
    assert visible_intervals(small.outlines()[0], [ring]) == []


def test_scene_ground_truth_lists_every_outline_corner_and_occlusion():
    from edgetruth.render.scene.ground_truth import scene_ground_truth

    rect = Shape("rectangle", offset_m=(-0.02, 0.0), rotation_deg=10.0, width_m=0.08, height_m=0.05)
    ring = Shape("ring", offset_m=(0.03, 0.0), outer_diameter_m=0.05, inner_diameter_m=0.02)
    scene = TargetScene("custom", (rect, ring))
    gt = scene_ground_truth(DISTORTED, TILTED, scene)
    assert [len(s["outlines"]) for s in gt["shapes"]] == [1, 2]
    o = gt["shapes"][0]["outlines"][0]
    # corners: the turned rectangle's corners through the camera model
    th = math.radians(10.0)
    loc = np.array([[-0.04, -0.025], [0.04, -0.025], [0.04, 0.025], [-0.04, 0.025]]) @ \
        np.array([[math.cos(th), math.sin(th)], [-math.sin(th), math.cos(th)]]) + [-0.02, 0.0]
    exp = DISTORTED.project(TILTED.to_camera(np.column_stack([loc, np.full(4, -Z_M)])))
    assert np.max(np.abs(np.asarray(o["corners_distorted_px"]) - exp)) < 1e-9
    assert np.max(np.abs(np.asarray(gt["outline"]["distorted_px"]) - exp)) < 1e-9
    # the ring cuts the rectangle's right side: two occlusion points, each on the ring's outer curve
    assert len(o["occlusion_points_distorted_px"]) == 2 and len(o["visible_intervals"]) == 1
    outer = OutlineCurve.of(DISTORTED, TILTED, ring.outlines()[0], 2 * Z_M)
    pts = np.asarray(o["occlusion_points_distorted_px"])
    assert np.max(np.abs(outer.signed_distance(pts[:, 0], pts[:, 1]))) < 2e-3  # the 10 um stand-off apart
    # the top-right corner (0.0237, -0.0177) m lies 0.019 m from the ring's centre (< its 0.025 m radius)
    assert o["corners_visible"] == [True, False, True, True]
    # the ring is on top: fully visible; its inner outline is a conic
    assert gt["shapes"][1]["outlines"][1]["visible_intervals"] == [[0.0, 1.0]]
    assert gt["shapes"][1]["outlines"][1]["conic_board_m"]["a"] == pytest.approx(0.01)
    assert gt["target"]["type"] == "rectangle" and gt["target"]["shape"] == "rectangle"


def test_presets_are_the_fixed_targets():
    from edgetruth.render.scene.target_scene import preset_scene
    from edgetruth.render.scene.targets import TARGETS

    assert set(TARGETS) == {"T1", "T2", "T3", "T4"}
    t4 = preset_scene("T4", 0.13).primary
    assert (t4.type, t4.width_m, t4.material.type, t4.material.alpha, t4.material.eta, t4.material.albedo) == \
        ("rectangle", 0.13, "roughplastic", 0.15, 1.5, 0.03)
    assert TARGETS["T2"] == {"shape": "circle", "material": "black_matte", "reflectance": 0.04}


from tests.support.scenes import GROUP_SPEC as SPEC


@pytest.mark.parametrize("extra, needle", [
    ('shapes = [{ type = "ellipse" }]', "axes_m"),
    ('shapes = [{ type = "ring", inner_diameter_m = 0.2 }]', "inner_diameter_m"),
    ('shapes = [{ type = "circle", width_m = 0.1 }]', "width_m"),
    ('shapes = [{ type = "polygon", vertices_m = [[0, 0], [0.1, 0.1], [0.1, 0], [0, 0.2]] }]', "cross"),
    ('shapes = [{ type = "polygon", vertices_m = [[0, 0], [0.1]] }]', "vertices_m"),
    ('shapes = [{ type = "hexagon" }]', "type"),
    ('shapes = [{ type = "circle", colour = 1 }]', "colour"),
    ('target_material = { type = "diffuse", alpha = 0.2 }', "alpha"),
    ('target_material = { albedo = 1.5 }', "albedo"),
    ('board_material = { type = "roughconductor", albedo = 0.5 }', "albedo"),
    ('lights = [{ type = "spot", beam_deg = 30 }]', "beam_deg"),
    ('lights = [{ type = "point", size_m = 0.1 }]', "size_m"),
    ('lights = [{ position_m = [0, 0, 0.5] }]', "z must be < 0"),
    ('lights = [{ type = "point" }]\nlight_position_m = [0, -0.1, -0.05]', "light_position_m"),
    ('kind = "checkerboard"\nambient = 0.1', "ambient"),
    ('ambient = -1', "ambient"),
])
def test_bad_scene_keys_are_one_line_errors(tmp_path, extra, needle):
    from edgetruth.render.dataset.spec import load_spec

    p = tmp_path / "x.toml"
    p.write_text(SPEC.format(extra=extra))
    with pytest.raises(InputError) as exc:
        load_spec(p)
    msg = str(exc.value)
    assert "\n" not in msg and needle in msg and str(p) in msg, msg


def test_scene_keys_only_change_the_identity_when_used(tmp_path):
    from edgetruth.render.dataset.spec import load_spec

    p = tmp_path / "x.toml"
    p.write_text(SPEC.format(extra='target = "T3"'))
    plain = load_spec(p)
    assert plain.groups[0].target == "T3" and "scene" not in plain.resolved()["groups"][0]
    p.write_text(SPEC.format(extra='target = "T3"\ntarget_material = { albedo = 0.3 }'))
    own = load_spec(p)
    assert own.groups[0].target.primary.material.albedo == 0.3
    assert own.resolved()["groups"][0]["scene"]["shapes"][0]["material"]["albedo"] == 0.3
    assert own.identity_sha256 != plain.identity_sha256


def test_scene_outline_measures_to_the_visible_edges_only():
    """A disk on top of a square's right side: next to the hidden part of the square's side the nearest
    visible edge is the disk's; signs > 0 on the board side (a ring's hole counts as board)."""
    from edgetruth.render.scene.ground_truth import SceneOutline, scene_ground_truth

    sq = Shape("rectangle", width_m=0.1, height_m=0.1)
    disk = Shape("circle", offset_m=(0.05, 0.0), diameter_m=0.04)
    ring = Shape("ring", offset_m=(-0.1, 0.0), outer_diameter_m=0.06, inner_diameter_m=0.03)
    gt = scene_ground_truth(PINHOLE, FRONTAL, TargetScene("custom", (sq, disk, ring)))
    so = SceneOutline.from_ground_truth(gt)
    z = 0.8 - 2 * Z_M
    cx, cy = PINHOLE.principal_point_px
    f = PINHOLE.fx_px
    # on the square's hidden side (x = 0.05 m, y = 0): inside the disk, 0.02 m from its edge
    x0, y0 = cx + f * 0.05 / z, cy
    d = so.signed_distance(np.array([x0]), np.array([y0]))[0]
    assert d == pytest.approx(-f * 0.02 / z, abs=2e-3)
    assert so.outlines[so.edge_index(np.array([x0]), np.array([y0]))[0]] == (1, "outline")
    # the centre of the ring's hole: 0.015 m from its edge, on the board side (> 0)
    zr = 0.8 - 3 * Z_M
    d_hole = so.signed_distance(np.array([cx - f * 0.1 / zr]), np.array([cy]))[0]
    assert d_hole == pytest.approx(f * 0.015 / zr, abs=2e-3)
    # far outside everything: > 0
    assert so.signed_distance(np.array([cx]), np.array([cy - f * 0.08 / z]))[0] > 0


def test_scene_levels_are_their_own_radiance_units_and_power_levels_share_them(tmp_path):
    """albedo x snr: the two albedos render apart; the two power levels of one albedo share one render."""
    from edgetruth.render.dataset.spec import load_spec

    p = tmp_path / "d.toml"
    p.write_text('[spec]\nname = "d"\ncamera_scale = 16\n[design]\nmode = "full"\ncount = 2\n'
                 '[[design.factor]]\nname = "albedo"\nlevels = [{ name = "a04", target_material = { albedo = 0.04 } },'
                 ' { name = "a25", target_material = { albedo = 0.25 } }]\n'
                 '[[design.factor]]\nname = "snr"\nlevels = [{ name = "G1", irradiance_w_m2 = 0.02 },'
                 ' { name = "G2", irradiance_w_m2 = 0.01, sensor = { gain_db = 6.0206 } }]\n')
    spec = load_spec(p)
    units = {g.name: g.radiance_unit for g in spec.groups}
    assert units["a04_G1"] == units["a04_G2"] != units["a25_G1"] == units["a25_G2"]
    assert spec.group("a04_G2").unit_irradiance_w_m2 == 0.02
    p.write_text('[spec]\nname = "e"\n[[group]]\nname = "g"\ntarget = "T2"\nshapes = [{ type = "circle" }]\n')
    with pytest.raises(InputError, match="shapes replace the preset"):
        load_spec(p)
