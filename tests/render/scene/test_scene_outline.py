"""The reader's truth of every visible edge of a multi-shape scene (``SceneOutline``, ``Sample.outline``):
signed distance to the nearest visible edge, corner distance, which edge / shape a point belongs to, each
against the analytic curves; single-outline images keep ``OutlineEdge`` and its numbers."""
from __future__ import annotations

import numpy as np
import pytest

from edgetruth.render.scene.ground_truth import SceneOutline, scene_ground_truth, target_ground_truth
from edgetruth.render.scene.outline import OutlineCurve
from edgetruth.render.scene.shapes import Shape
from edgetruth.render.scene.target_scene import TargetScene

from tests.support.scenes import DISTORTED, FRONTAL, PINHOLE, TILTED, Z_M
H, R = 0.05, 0.02  # the square's half side, the disk's radius (the disk sits on the square's right side)
RING = (-0.1, 0.0, 0.03, 0.015)  # centre x, y, outer and inner radius (m)
# chord error of the circles' polylines (<= 1e-3 px, recorded) plus rounding
TOL_PX = 1.1e-3


def _scene():
    sq = Shape("rectangle", width_m=2 * H, height_m=2 * H)
    disk = Shape("circle", offset_m=(H, 0.0), diameter_m=2 * R)
    ring = Shape("ring", offset_m=RING[:2], outer_diameter_m=2 * RING[2], inner_diameter_m=2 * RING[3])
    return TargetScene("custom", (sq, disk, ring))


def _px(xy_m, k):
    """Frontal pinhole image of board points of shape k (at (k + 1) x 10 um in front of the board)."""
    z = 0.8 - (k + 1) * Z_M
    cx, cy = PINHOLE.principal_point_px
    return np.column_stack([cx + PINHOLE.fx_px * xy_m[:, 0] / z, cy + PINHOLE.fy_px * xy_m[:, 1] / z])


def _seg_dist(q, a, b):
    d = b - a
    u = np.clip(((q - a) @ d) / (d @ d), 0, 1)
    return np.linalg.norm(q - (a + u[:, None] * d), axis=1)


def _analytic(q):
    """(signed distance, outline index, corners) of the analytic visible edges: the square's sides less the
    part of its right side under the disk, the disk's circle, the ring's two circles."""
    sq = _px(np.array([[-H, -H], [H, -H], [H, H], [-H, H], [H, -R], [H, R]]), 0)
    tl, tr, br, bl, cut0, cut1 = sq
    d_sq = np.min([_seg_dist(q, tl, tr), _seg_dist(q, tr, cut0), _seg_dist(q, cut1, br), _seg_dist(q, br, bl),
                   _seg_dist(q, bl, tl)], axis=0)
    inside_sq = (q[:, 0] > tl[0]) & (q[:, 0] < tr[0]) & (q[:, 1] > tl[1]) & (q[:, 1] < bl[1])
    s_sq = np.where(inside_sq, -d_sq, d_sq)
    c_d = _px(np.array([[H, 0.0]]), 1)[0]
    r_d = PINHOLE.fx_px * R / (0.8 - 2 * Z_M)
    s_d = np.linalg.norm(q - c_d, axis=1) - r_d
    c_r = _px(np.array([RING[:2]]), 2)[0]
    f3 = PINHOLE.fx_px / (0.8 - 3 * Z_M)
    rr = np.linalg.norm(q - c_r, axis=1)
    s_o, s_i = rr - f3 * RING[2], f3 * RING[3] - rr  # the hole is board: > 0 inside it
    cand = np.stack([s_sq, s_d, s_o, s_i])
    i = np.argmin(np.abs(cand), axis=0)
    return cand[i, np.arange(len(q))], i, np.array([tl, tr, br, bl, cut0, cut1]), np.sort(np.abs(cand), axis=0)


def _near_points(gt, rng, n=300, spread_px=3.0):
    pts = []
    for s in gt["shapes"]:
        for o in s["outlines"]:
            p = np.asarray(o["polyline_distorted_px"])
            pts.append(p[rng.integers(0, len(p), n)])
    p = np.concatenate(pts)
    return p + rng.normal(0, spread_px, p.shape)


def test_signed_distance_edge_and_corners_against_the_analytic_curves():
    rng = np.random.default_rng(7)
    gt = scene_ground_truth(PINHOLE, FRONTAL, _scene())
    so = SceneOutline.from_ground_truth(gt)
    q = np.concatenate([_near_points(gt, rng), rng.uniform([0, 0], [320, 240], (2000, 2))])
    exact, idx, corners, ranked = _analytic(q)
    got = so.signed_distance(q[:, 0], q[:, 1])
    assert np.max(np.abs(got - exact)) < TOL_PX
    # which edge: where the two nearest analytic edges are not within the tolerance of each other
    clear = ranked[1] - ranked[0] > 1e-2
    assert clear.mean() > 0.95
    assert np.array_equal(so.edge_index(q[clear, 0], q[clear, 1]), idx[clear])
    assert np.array_equal(so.edge_shape(q[clear, 0], q[clear, 1]), np.array([0, 1, 2, 2])[idx[clear]])
    assert so.outlines == [(0, "outline"), (1, "outline"), (2, "outer"), (2, "inner")]
    # corners: the square's four (the disk covers none) and the two points where the disk cuts its side
    assert len(so.corners_px) == 6
    exp_c = np.min(np.linalg.norm(q[:, None] - corners[None], axis=2), axis=1)
    assert np.max(np.abs(so.corner_distance(q[:, 0], q[:, 1]) - exp_c)) < 1e-6  # occlusion ends: 1e-13 in t
    # a grid keeps its shape
    xx, yy = np.meshgrid(np.arange(0.5, 320, 40), np.arange(0.5, 240, 40))
    assert so.signed_distance(xx, yy).shape == xx.shape == so.corner_distance(xx, yy).shape


def test_shape_at_against_the_analytic_regions():
    rng = np.random.default_rng(8)
    so = SceneOutline.from_ground_truth(scene_ground_truth(PINHOLE, FRONTAL, _scene()))
    q = rng.uniform([0, 0], [320, 240], (20000, 2))
    _, _, _, ranked = _analytic(q)
    q = q[ranked[0] > 1e-2]  # clear of every edge
    sq = _px(np.array([[-H, -H], [H, H]]), 0)
    in_sq = (q[:, 0] > sq[0, 0]) & (q[:, 0] < sq[1, 0]) & (q[:, 1] > sq[0, 1]) & (q[:, 1] < sq[1, 1])
    in_d = np.linalg.norm(q - _px(np.array([[H, 0.0]]), 1)[0], axis=1) < PINHOLE.fx_px * R / (0.8 - 2 * Z_M)
    rr = np.linalg.norm(q - _px(np.array([RING[:2]]), 2)[0], axis=1)
    f3 = PINHOLE.fx_px / (0.8 - 3 * Z_M)
    in_ring = (rr < f3 * RING[2]) & (rr > f3 * RING[3])
    in_hole = rr <= f3 * RING[3]
    exp = np.where(in_ring, 2, np.where(in_hole, -1, np.where(in_d, 1, np.where(in_sq, 0, -1))))
    got = so.shape_at(q[:, 0], q[:, 1])
    assert np.array_equal(got, exp)
    assert {0, 1, 2, -1} <= set(got.tolist())


def test_through_the_lens_distance_is_the_nearest_exact_curve():
    """Distorted and tilted, a rectangle and a ring apart (nothing covered): the distance to the nearest
    visible edge is the smallest exact-curve distance (golden-section refinement on the curve itself)."""
    rng = np.random.default_rng(9)
    rect = Shape("rectangle", offset_m=(-0.06, 0.0), rotation_deg=15.0, width_m=0.06, height_m=0.04)
    ring = Shape("ring", offset_m=(0.05, 0.01), outer_diameter_m=0.06, inner_diameter_m=0.025)
    scene = TargetScene("custom", (rect, ring))
    gt = scene_ground_truth(DISTORTED, TILTED, scene)
    so = SceneOutline.from_ground_truth(gt)
    q = _near_points(gt, rng, n=200)
    curves = [OutlineCurve.of(DISTORTED, TILTED, o, (k + 1) * Z_M)
              for k, s in enumerate(scene.shapes) for o in s.outlines()]
    sd = np.stack([c.signed_distance(q[:, 0], q[:, 1], exact=True) for c in curves])
    sd[2] = -sd[2]  # the ring's hole is on the board side
    i = np.argmin(np.abs(sd), axis=0)
    exact = sd[i, np.arange(len(q))]
    assert np.max(np.abs(so.signed_distance(q[:, 0], q[:, 1]) - exact)) < TOL_PX
    assert len(so.corners_px) == 4  # the rectangle's corners; conics have none


def _sample(gt):
    from edgetruth.render.dataset.reader import Sample

    return Sample(dataset=None, name="0000_x", index=0, kind="target", group="g", _truth=gt)


def test_reader_gives_every_visible_edge_for_a_scene_and_the_old_outline_for_one():
    from edgetruth.render.edge_truth import OutlineEdge

    # presets: OutlineEdge with today's numbers (a square's 4 corners, a circle's none)
    gt1 = target_ground_truth(DISTORTED, TILTED, "T1", 0.13)
    e1 = _sample(gt1).outline
    assert isinstance(e1, OutlineEdge) and e1.shape == "square"
    assert np.array_equal(e1.corners_px, np.asarray(gt1["outline"]["distorted_px"])[:4])
    assert np.array_equal(e1.polyline_px, np.asarray(gt1["outline"]["polyline_distorted_px"]))
    gt2 = target_ground_truth(DISTORTED, TILTED, "T2", 0.13)
    e2 = _sample(gt2).outline
    assert isinstance(e2, OutlineEdge) and e2.corners_px is None
    # one catalogue shape with one outline: OutlineEdge, a polygon's corners are its vertices
    pent = Shape("polygon", vertices_m=((-0.04, -0.03), (0.05, -0.02), (0.0, 0.0), (0.04, 0.04), (-0.03, 0.03)))
    ep = _sample(scene_ground_truth(DISTORTED, TILTED, TargetScene("custom", (pent,)))).outline
    assert isinstance(ep, OutlineEdge) and len(ep.corners_px) == 5
    # a ring alone (two edges) and a multi-shape scene: every visible edge
    ring = Shape("ring", outer_diameter_m=0.08, inner_diameter_m=0.03)
    gtr = scene_ground_truth(DISTORTED, TILTED, TargetScene("custom", (ring,)))
    er = _sample(gtr).outline
    assert isinstance(er, SceneOutline) and er.outlines == [(0, "outer"), (0, "inner")]
    inner = np.asarray(gtr["shapes"][0]["outlines"][1]["polyline_distorted_px"])
    centre = inner.mean(axis=0)  # inside the hole: > 0 (board); OutlineEdge of the outer edge said < 0
    assert er.signed_distance(centre[:1], centre[1:])[0] > 0
    assert isinstance(_sample(scene_ground_truth(PINHOLE, FRONTAL, _scene())).outline, SceneOutline)
    from edgetruth.render.dataset.reader import Sample

    assert Sample(dataset=None, name="c", index=0, kind="checkerboard", group="g", _truth={}).outline is None
