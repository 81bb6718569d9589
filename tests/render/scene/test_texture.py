"""Printed textures: an image file on a rectangle shape or the board (nearest texel, reflectance = albedo x
gray level / full scale); its placement in the truth; the file checked at load with one-line errors.  The
other shapes' prints: test_texture_shapes.py."""
from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from edgetruth.errors import InputError
from edgetruth.render.optics.camera import Camera
from edgetruth.render.scene.ground_truth import scene_ground_truth
from edgetruth.render.scene.lights import Light
from edgetruth.render.scene.materials import Material, with_texture_file
from edgetruth.render.scene.pose import Pose
from edgetruth.render.scene.shapes import Shape
from edgetruth.render.scene.target_scene import TargetScene
from edgetruth.render.scene.targets import BOARD_HALF_SIZE_M

CAM = Camera(width_px=96, height_px=64, pitch_um=30.0, focal_length_mm=8.0, f_number=0.0, focus_distance_m=0.6,
             diffraction_wavelength_nm=0.0, natural_vignetting=False)  # fx = 266.7 px, no distortion, no PSF
POSE = Pose(0.6, 0.0, 0.0, 0.0, 0.0, 0.0)
Z_M = 10e-6


def _texture(tmp_path, name="t.png", shape=(6, 8), seed=0):
    levels = np.random.default_rng(seed).integers(0, 65536, shape).astype(np.uint16)
    cv2.imwrite(str(tmp_path / name), levels)
    return levels


def test_printed_rectangle_shows_each_texel_at_its_recorded_place(tmp_path, fast_variant):
    """Frontal pinhole: a pixel wholly inside a texel shows E/pi x albedo x level / 65535 (E: the point
    light's irradiance there); the texel is found from the truth's corners alone."""
    import mitsuba as mi

    from edgetruth.render.scene.mitsuba_scene import RenderSettings, TargetRig

    mi.set_variant(fast_variant)
    levels = _texture(tmp_path)
    mat = with_texture_file(Material("diffuse", albedo=0.9, texture="t.png"), tmp_path, "test")
    rect = Shape("rectangle", offset_m=(0.01, -0.005), width_m=0.12, height_m=0.08, material=mat)
    scene = TargetScene("custom", (rect,), lights=(Light("point", position_m=(0.0, -0.1, -0.05)),))
    rig = TargetRig(CAM, RenderSettings(spp=16, sampler="multijitter"))
    rig.set_state(scene, POSE, 1.0)
    img = rig.render(5).astype(np.float64)
    tex = scene_ground_truth(CAM, POSE, scene)["shapes"][0]["texture"]
    assert tex["size_px"] == [8, 6] and tex["file"] == "t.png"
    tl, tr, br, bl = np.asarray(tex["corners_distorted_px"])
    # frontal: the quad is an axis-aligned rectangle in the image; texel (i, j) from the pixel centre
    v, u = np.mgrid[0:64, 0:96].astype(float)
    fu, fv = (u - tl[0]) / (tr[0] - tl[0]) * 8, (v - tl[1]) / (bl[1] - tl[1]) * 6
    half_u, half_v = 0.5 / (tr[0] - tl[0]) * 8, 0.5 / (bl[1] - tl[1]) * 6  # half a pixel in texels
    inner = (fu - half_u > 0) & (fu + half_u < 8) & (fv - half_v > 0) & (fv + half_v < 6) & \
        (np.floor(fu - half_u) == np.floor(fu + half_u)) & (np.floor(fv - half_v) == np.floor(fv + half_v))
    assert inner.sum() > 48 * 10  # every texel has whole pixels inside it
    i, j = np.floor(fv[inner]).astype(int), np.floor(fu[inner]).astype(int)
    assert len(set(zip(i, j))) == 48
    cx, cy = CAM.principal_point_px
    z = 0.6 - Z_M
    pts = np.column_stack([(u[inner] - cx) * z / CAM.fx_px, (v[inner] - cy) * z / CAM.fx_px, np.full(inner.sum(), z)])
    e = scene.lights[0].irradiance_at(1.0, POSE, pts)
    pred = e / math.pi * 0.9 * levels[i, j] / 65535.0
    assert np.max(np.abs(img[inner] - pred)) < 1e-4 * np.max(pred)
    # the recorded corners are the rectangle's, through the camera
    exp = CAM.project(POSE.to_camera(np.column_stack([np.asarray(rect.outlines()[0].vertices), np.full(4, -Z_M)])))
    assert np.max(np.abs(np.asarray(tex["corners_distorted_px"]) - exp)) < 1e-9


def test_board_texture_placement_and_identity(tmp_path):
    _texture(tmp_path, "b.png", (3, 5))
    board = with_texture_file(Material("diffuse", albedo=0.8, texture="b.png"), tmp_path, "test")
    gt = scene_ground_truth(CAM, POSE, TargetScene("custom", (Shape("circle", diameter_m=0.02),), board=board))
    tex = gt["board"]["texture"]
    hx, hy = BOARD_HALF_SIZE_M
    assert tex["corners_board_m"] == [[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]] and tex["size_px"] == [5, 3]
    d = board.to_dict()
    assert d["texture"] == "b.png" and len(d["texture_sha256"]) == 64
    assert "texture" not in Material("diffuse", 0.8).to_dict()  # plain materials keep their description


from tests.support.scenes import GROUP_SPEC as SPEC


@pytest.mark.parametrize("extra, make, needle", [
    ('board_material = { texture = "missing.png" }', None, "no such file"),
    ('board_material = { texture = "big.png" }', ("big.png", (2, 9000)), "at most 8192"),
    ('board_material = { texture = "bad.png" }', ("bad.png", None), "bad.png"),
    ('target_material = { type = "roughplastic", texture = "t.png" }', ("t.png", (4, 4)), "texture"),
    ('clutter = [{ type = "box", size_m = [0.1, 0.1, 0.1], material = { texture = "t.png" } }]', ("t.png", (4, 4)),
     "not printed"),
])
def test_bad_textures_are_one_line_errors(tmp_path, extra, make, needle):
    from edgetruth.render.dataset.spec import load_spec

    if make is not None:
        name, shape = make
        if shape is None:
            (tmp_path / name).write_bytes(b"not an image")
        else:
            _texture(tmp_path, name, shape)
    p = tmp_path / "x.toml"
    p.write_text(SPEC.format(extra=extra))
    with pytest.raises(InputError) as exc:
        load_spec(p)
    msg = str(exc.value)
    assert "\n" not in msg and needle in msg, msg


def test_bad_texture_exits_2_with_one_line(tmp_path, capsys):
    from edgetruth.cli import main

    p = tmp_path / "x.toml"
    p.write_text(SPEC.format(extra='board_material = { texture = "missing.png" }'))
    assert main(["render", str(p), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "missing.png" in err


def test_texture_is_relative_to_the_spec_and_keys_the_identity(tmp_path):
    from edgetruth.render.dataset.spec import load_spec

    (tmp_path / "a").mkdir()
    _texture(tmp_path / "a", "t.png", (4, 4), seed=1)
    p = tmp_path / "a" / "x.toml"
    p.write_text(SPEC.format(extra='board_material = { texture = "t.png" }'))
    one = load_spec(p)
    assert one.groups[0].target.board.texture == str((tmp_path / "a" / "t.png").resolve())
    _texture(tmp_path / "a", "t.png", (4, 4), seed=2)  # new content, same name
    assert load_spec(p).identity_sha256 != one.identity_sha256
