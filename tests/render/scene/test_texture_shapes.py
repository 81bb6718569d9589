"""Printed textures on every shape (circle, ellipse, ring, polygon, grid cells) and in a ring's hole: the image
fills the shape's bounding box in its own frame (``Shape.texture_frame``), turned and moved with it, and shows
only inside the shape.  A frontal pinhole render is checked texel by texel against the prediction from the
truth's recorded placement alone."""
from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from edgetruth.render.optics.camera import Camera
from edgetruth.render.scene.ground_truth import scene_ground_truth
from edgetruth.render.scene.lights import Light
from edgetruth.render.scene.materials import Material, with_texture_file
from edgetruth.render.scene.pose import Pose
from edgetruth.render.scene.shapes import Shape
from edgetruth.render.scene.target_scene import TargetScene

CAM = Camera(width_px=240, height_px=160, pitch_um=30.0, focal_length_mm=8.0, f_number=0.0, focus_distance_m=0.6,
             diffraction_wavelength_nm=0.0, natural_vignetting=False)  # fx = 266.7 px, no distortion, no PSF
POSE = Pose(0.6, 0.0, 0.0, 0.0, 0.0, 0.0)
LIGHT = Light("point", position_m=(0.0, -0.1, -0.05))
TEX_SHAPE = (3, 4)  # rows x columns of each printed image: texels of 5-9 px
#: every shape type but the rectangle (tests/render/scene/test_texture.py), turned where that shows
SHAPES = {
    "circle": dict(type="circle", offset_m=(-0.14, -0.06), rotation_deg=25.0, diameter_m=0.07),
    "ellipse": dict(type="ellipse", offset_m=(0.0, -0.06), rotation_deg=30.0, axes_m=(0.09, 0.055)),
    "ring": dict(type="ring", offset_m=(0.14, -0.06), outer_diameter_m=0.08, inner_diameter_m=0.04),
    "polygon": dict(type="polygon", offset_m=(-0.14, 0.07), rotation_deg=15.0,
                    vertices_m=((-0.04, -0.03), (0.05, -0.035), (0.01, 0.0), (0.045, 0.035), (-0.035, 0.03))),
    "grid_squares": dict(type="grid", offset_m=(0.0, 0.07), rotation_deg=-10.0, rows=2, cols=3, element="square",
                         element_size_m=0.026, pitch_m=(0.03, 0.032)),
    "grid_circles": dict(type="grid", offset_m=(0.14, 0.07), rotation_deg=20.0, rows=2, cols=2, element="circle",
                         element_size_m=0.03, pitch_m=(0.034, 0.034)),
}


def _texture(folder, name, seed, shape=TEX_SHAPE):
    levels = np.random.default_rng(seed).integers(0, 65536, shape).astype(np.uint16)
    cv2.imwrite(str(folder / name), levels)
    return levels


def _scene(tmp_path):
    levels, shapes = {}, []
    for k, (name, kw) in enumerate(SHAPES.items()):
        levels[name] = _texture(tmp_path, f"{name}.png", k)
        mat = with_texture_file(Material("diffuse", albedo=0.9, texture=f"{name}.png"), tmp_path, name)
        shapes.append(Shape(**kw, material=mat))
    levels["board"] = _texture(tmp_path, "board.png", 99, (300, 360))  # 1 cm texels: the ring's hole spans several
    board = with_texture_file(Material("diffuse", albedo=0.8, texture="board.png"), tmp_path, "board")
    return TargetScene("custom", tuple(shapes), board=board, lights=(LIGHT,)), levels


def _texel(corners, size_px, xy):
    """(row, column) of the texel under board points (N, 2) from the placement's corners alone (a
    parallelogram here: bilinear = affine), and whether they lie on the image."""
    tl, tr, _, bl = np.asarray(corners, float)
    a = np.column_stack([tr - tl, bl - tl])
    uv = np.linalg.solve(a, (xy - tl).T).T  # in [0, 1]^2 on the image
    w, h = size_px
    return np.floor(uv[:, 1] * h).astype(int), np.floor(uv[:, 0] * w).astype(int), np.all((uv > 0) & (uv < 1), 1)


def _inside(shape, xy):
    inside = shape.covers(xy)
    if shape.type == "ring":  # its hole shows the board
        cx, cy, a, _, _ = shape.outlines()[1].conic
        inside &= np.hypot(xy[:, 0] - cx, xy[:, 1] - cy) > a
    return inside


def test_every_shape_shows_its_texture_where_the_truth_places_it(tmp_path, fast_variant):
    """A pixel whose 9 x 9 sub-points (its corners among them) all lie inside one shape (or the ring's hole) and in one texel shows
    E / pi x albedo x level / 65535 (E: the point light's irradiance averaged over the pixel) to 1e-4 of
    the brightest prediction (measured <= 3.5e-5: E varies by ~1e-3 across a pixel, sampled at 16 spp); the
    texels are seen whole (all but one under the ring's hole and one beside the polygon's notch)."""
    import mitsuba as mi

    from edgetruth.render.scene.mitsuba_scene import RenderSettings, TargetRig

    mi.set_variant(fast_variant)
    scene, levels = _scene(tmp_path)
    rig = TargetRig(CAM, RenderSettings(spp=16, sampler="multijitter"))
    rig.set_state(scene, POSE, 1.0)
    img = rig.render(3).astype(np.float64)
    gt = scene_ground_truth(CAM, POSE, scene)
    cx, cy = CAM.principal_point_px
    v, u = np.mgrid[0:CAM.height_px, 0:CAM.width_px].astype(float)
    sub = np.linspace(-0.5, 0.5, 9)  # sub-points over the whole pixel, corners included (centre: the integer)
    su, sv = np.meshgrid(sub, sub)
    z = 0.6
    pix_u = u.ravel()[:, None] + su.ravel()[None]
    pix_v = v.ravel()[:, None] + sv.ravel()[None]
    xy = np.stack([(pix_u - cx) * z / CAM.fx_px, (pix_v - cy) * z / CAM.fy_px], axis=-1)  # (P, 81, 2)
    centre = xy[:, 40]  # (P, 2): each pixel's centre on the board

    def irradiance(idx, z_m):  # the light's irradiance averaged over each pixel of idx, at depth z_m
        p = xy[idx].reshape(-1, 2) * z_m / z
        return LIGHT.irradiance_at(1.0, POSE, np.column_stack([p, np.full(len(p), z_m)])).reshape(len(idx), -1).mean(1)

    def whole(idx, corners, size_px):  # pixels of idx wholly in one texel: (kept indices, texel row, column, mask)
        pts = xy[idx].reshape(-1, 2)
        i, j, on = (a.reshape(len(idx), -1) for a in _texel(corners, size_px, pts))
        keep = on.all(1) & (i == i[:, :1]).all(1) & (j == j[:, :1]).all(1)
        return keep, i[:, 0], j[:, 0], pts

    worst, seen = {}, {}
    for k, (name, s) in enumerate(zip(SHAPES, scene.shapes)):
        tex = gt["shapes"][k]["texture"]
        assert tex["file"] == f"{name}.png" and tex["size_px"] == [TEX_SHAPE[1], TEX_SHAPE[0]]
        # the placement is the shape's bounding box in its own frame, turned and moved with it
        assert np.allclose(tex["corners_board_m"], s.texture_corners(), atol=0, rtol=0)
        c = np.asarray(tex["corners_board_m"])
        idx = np.flatnonzero(np.all((centre > c.min(0)) & (centre < c.max(0)), axis=1))  # pixels over the print
        keep, i, j, pts = whole(idx, c, tex["size_px"])
        keep &= _inside(s, pts).reshape(len(idx), -1).all(1)
        ok, ii, jj = idx[keep], i[keep], j[keep]
        pred = irradiance(ok, z - (k + 1) * 10e-6) / math.pi * 0.9 * levels[name][ii, jj] / 65535.0  # its stand-off
        worst[name] = float(np.max(np.abs(img.ravel()[ok] - pred)) / np.max(pred))
        seen[name] = len(set(zip(ii, jj)))
    # the ring's hole shows the board's own print (the board's image over the whole board)
    ring = scene.shapes[list(SHAPES).index("ring")]
    btex = gt["board"]["texture"]
    cxr, cyr, a, _, _ = ring.outlines()[1].conic
    idx = np.flatnonzero(np.hypot(centre[:, 0] - cxr, centre[:, 1] - cyr) < a)
    keep, i, j, pts = whole(idx, btex["corners_board_m"], btex["size_px"])
    keep &= (np.hypot(pts[:, 0] - cxr, pts[:, 1] - cyr) < a).reshape(len(idx), -1).all(1)
    ok, ii, jj = idx[keep], i[keep], j[keep]
    assert len(ok) >= 20 and len(set(zip(ii, jj))) >= 2  # the hole spans board texels
    # the hole's disk: half a stand-off in front of the ring (shape 2)
    pred = irradiance(ok, z - 3.5 * 10e-6) / math.pi * 0.8 * levels["board"][ii, jj] / 65535.0
    worst["ring_hole"] = float(np.max(np.abs(img.ravel()[ok] - pred)) / np.max(pred))
    assert all(w < 1e-4 for w in worst.values()), worst
    # every texel is seen whole somewhere (a ring: one lies wholly under its hole; a polygon: one off its
    # notch; a grid: its elements show parts of its image)
    need = {"circle": 12, "ellipse": 12, "ring": 11, "polygon": 11, "grid_squares": 12, "grid_circles": 12}
    assert all(seen[n] >= need[n] for n in need), seen


def test_texture_frame_per_shape():
    """The printed box of each shape type, in its own frame (before turn and offset)."""
    assert Shape("circle", diameter_m=0.06).texture_frame() == (-0.03, -0.03, 0.03, 0.03)
    assert Shape("ellipse", axes_m=(0.08, 0.04)).texture_frame() == (-0.04, -0.02, 0.04, 0.02)
    assert Shape("ring", outer_diameter_m=0.1, inner_diameter_m=0.02).texture_frame() == (-0.05, -0.05, 0.05, 0.05)
    assert Shape("polygon", vertices_m=((0.0, -0.01), (0.03, 0.0), (0.01, 0.02))).texture_frame() == \
        (0.0, -0.01, 0.03, 0.02)
    g = Shape("grid", rows=2, cols=3, element_size_m=0.01, pitch_m=(0.02, 0.03))
    assert g.texture_frame() == pytest.approx((-0.025, -0.02, 0.025, 0.02), abs=1e-15)
    r = Shape("rectangle", offset_m=(0.01, 0.02), rotation_deg=30.0, width_m=0.05, height_m=0.03)
    assert np.array_equal(r.texture_corners(), np.asarray(r.outlines()[0].vertices))  # as before: its corners
    c = Shape("circle", offset_m=(0.01, 0.0), rotation_deg=90.0, diameter_m=0.02)
    assert np.allclose(c.texture_corners(), [[0.02, -0.01], [0.02, 0.01], [0.0, 0.01], [0.0, -0.01]], atol=1e-15)


def test_textured_shapes_load_from_a_spec(tmp_path):
    from edgetruth.render.dataset.spec import load_spec
    from tests.support.scenes import GROUP_SPEC

    _texture(tmp_path, "t.png", 1, (4, 4))
    p = tmp_path / "x.toml"
    p.write_text(GROUP_SPEC.format(extra='shapes = [{ type = "circle", material = { albedo = 1.0, texture = "t.png" } },'
                                         ' { type = "ring", inner_diameter_m = 0.05, offset_m = [0.2, 0],'
                                         ' material = { texture = "t.png" } }]'))
    sc = load_spec(p).groups[0].target
    assert [s.material.texture for s in sc.shapes] == [str((tmp_path / "t.png").resolve())] * 2
