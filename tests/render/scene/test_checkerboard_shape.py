"""The catalogue's checkerboard shape and the board's size (issue 18).

- The shipped preset ``assets/targets.toml [checkerboard]`` is the board of ``kind = "checkerboard"`` groups:
  its dark squares are ``Checkerboard``'s mesh quads to the bit (the kind's renders stay byte-identical).
- Exact truth: every dark square's outline and the inner corners through the lens, against the analytic
  squares; ``SceneOutline`` distances at the inner corners and inside the squares.
- A render (in focus, matte, distorted, tilted): every side of every dark square within 0.01 px of its exact
  outline (a line fit per side, as ``test_shapes_edges``), the inner corners by ``cv2.cornerSubPix`` within
  0.08 px of the truth (its own limit on a sharp image: 0.052 px measured here; mean 0.007 px), and the edge
  of a ``board_size_m`` board where the truth puts it (0.01 px); a printed checkerboard's dark squares.
- One-line errors for the new keys; ``board_size_m`` as a design factor.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from edgetruth.errors import InputError
from edgetruth.render.optics.camera import Camera
from edgetruth.render.scene.ground_truth import SceneOutline, scene_ground_truth
from edgetruth.render.scene.lights import Light
from edgetruth.render.scene.outline import OutlineCurve
from edgetruth.render.scene.pose import Pose
from edgetruth.render.scene.shapes import BOARD_HALF_SIZE_M, Shape, shape_from_dict
from edgetruth.render.scene.target_scene import PRESETS, TargetScene, checkerboard_preset, scene_from_group
from edgetruth.render.scene.targets import CHECKER_BLACK_REFLECTANCE, TARGETS, Checkerboard
from tests.render.scene.test_shapes_edges import measure_piece

DISTORTED = Camera(width_px=320, height_px=240, pitch_um=20.0, focal_length_mm=8.0, f_number=0.0,
                   focus_distance_m=0.8, distortion=(-0.25, 0.12, 1e-3, -8e-4, 0.0))
TILTED = Pose(0.8, 0.02, -0.01, 12.0, -8.0, 20.0)
Z_M = 10e-6


def _checker(**kw) -> Shape:
    d = {"type": "checkerboard", "rows": 5, "cols": 6, "square_m": 0.02, "offset_m": [0.01, -0.005],
         "rotation_deg": 25.0, **kw}
    return shape_from_dict(d, 0.13, "test")


# --- the preset is the kind's board --------------------------------------------------------------------
def _legacy_black_quads(cols: int, rows: int, s: float, z_m: float) -> np.ndarray:
    """``Checkerboard.black_quads_local`` as it was before the catalogue held the squares (the reference)."""
    quads = []
    for j in range(rows):
        for i in range(cols):
            if (i + j) % 2 == 0:
                x0 = (i - cols / 2) * s
                y0 = (j - rows / 2) * s
                quads.append([[x0, y0, z_m], [x0 + s, y0, z_m], [x0 + s, y0 + s, z_m], [x0, y0 + s, z_m]])
    return np.asarray(quads, dtype=np.float64)


@pytest.mark.parametrize("cols,rows,s", [(10, 7, 0.03), (9, 6, 0.0254), (3, 4, 0.017)])
def test_checkerboard_kind_mesh_is_the_catalogue_shape_to_the_bit(cols, rows, s):
    board = Checkerboard(cols=cols, rows=rows, square_m=s)
    z = -Z_M
    legacy = _legacy_black_quads(cols, rows, s, z)
    assert board.black_quads_local(z).tobytes() == legacy.tobytes()
    # the catalogue shape (unturned, at the origin) has the same corners, bit for bit, in the same order
    shape_quads = np.asarray([o.vertices for o in board.shape().outlines()])
    assert shape_quads.tobytes() == np.ascontiguousarray(legacy[..., :2]).tobytes()
    xs, ys = (np.arange(1, cols) - cols / 2) * s, (np.arange(1, rows) - rows / 2) * s
    gx, gy = np.meshgrid(xs, ys)
    assert board.inner_corners_local(0.0)[:, :2].tobytes() == np.column_stack([gx.ravel(), gy.ravel()]).tobytes()


def test_shipped_preset_is_the_calibration_board():
    shape, margin = checkerboard_preset()
    assert "checkerboard" in PRESETS and "checkerboard" not in TARGETS  # not a fixed-scene target id
    assert (shape.cols, shape.rows, shape.square_m, margin) == (10, 7, 0.03, 0.03)
    assert Checkerboard() == Checkerboard(cols=10, rows=7, square_m=0.03, margin_m=0.03)
    assert shape.material.type == "diffuse" and CHECKER_BLACK_REFLECTANCE == shape.material.albedo == 0.04
    assert Checkerboard().pattern_size == (9, 6)


# --- exact truth ------------------------------------------------------------------------------------------
def test_dark_square_outlines_and_inner_corners_through_the_lens():
    sh = _checker()
    gt = scene_ground_truth(DISTORTED, TILTED, TargetScene("custom", (sh,)))
    s0 = gt["shapes"][0]
    outs = s0["outlines"]
    dark = [(r, c) for r in range(5) for c in range(6) if (r + c) % 2 == 0]
    assert [o["name"] for o in outs] == [f"r{r}c{c}" for r, c in dark]
    th = math.radians(25.0)
    rot = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
    off = np.array([0.01, -0.005])
    for o, (r, c) in zip(outs, dark):
        x0, y0 = (c - 3) * 0.02, (r - 2.5) * 0.02
        loc = np.array([[x0, y0], [x0 + 0.02, y0], [x0 + 0.02, y0 + 0.02], [x0, y0 + 0.02]]) @ rot.T + off
        exp = DISTORTED.project(TILTED.to_camera(np.column_stack([loc, np.full(4, -Z_M)])))
        assert np.max(np.abs(np.asarray(o["corners_distorted_px"]) - exp)) < 1e-9
        assert o["visible_intervals"] == [[0.0, 1.0]] and all(o["corners_visible"])
    ic = s0["inner_corners"]
    assert ic["pattern_size"] == [5, 4] and len(ic["distorted_px"]) == 20 and all(ic["visible"])
    gx, gy = np.meshgrid((np.arange(1, 6) - 3) * 0.02, (np.arange(1, 5) - 2.5) * 0.02)
    loc = np.column_stack([gx.ravel(), gy.ravel()]) @ rot.T + off
    cam = TILTED.to_camera(np.column_stack([loc, np.full(len(loc), -Z_M)]))
    assert np.max(np.abs(np.asarray(ic["distorted_px"]) - DISTORTED.project(cam))) < 1e-9
    assert np.max(np.abs(np.asarray(ic["undistorted_px"]) - DISTORTED.project(cam, distorted=False))) < 1e-9
    # each inner corner is a corner of exactly two dark squares (they touch there): the outline is split per square
    sq_corners = np.concatenate([np.asarray(o["corners_distorted_px"]) for o in outs])
    for p in np.asarray(ic["distorted_px"]):
        assert np.sum(np.linalg.norm(sq_corners - p, axis=1) < 1e-9) == 2
    assert gt["target"]["type"] == "checkerboard" and gt["target"]["size_m"] == pytest.approx(0.12)
    # the reader: corner distance 0 at the inner corners; inside a dark square negative, a light one positive
    so = SceneOutline(gt)
    p = np.asarray(ic["distorted_px"])
    assert np.max(so.corner_distance(p[:, 0], p[:, 1])) < 1e-9
    centres = {}
    for r in range(5):
        for c in range(6):
            xy = rot @ [(c - 2.5) * 0.02, (r - 2) * 0.02] + off
            centres[(r, c)] = DISTORTED.project(TILTED.to_camera(np.array([[*xy, -Z_M]])))[0]
    d = {k: float(so.signed_distance(v[0], v[1])) for k, v in centres.items()}
    assert all((d[k] < -3) == ((k[0] + k[1]) % 2 == 0) and abs(d[k]) > 3 for k in d), d


def test_a_later_shape_hides_inner_corners_and_light_squares_show_what_lies_below():
    sh = _checker(rotation_deg=0.0, offset_m=[0.0, 0.0])
    cover = Shape("circle", offset_m=(-0.02, -0.01), diameter_m=0.015)  # over the inner corner at (-0.02, -0.01)
    ic = scene_ground_truth(DISTORTED, TILTED, TargetScene("custom", (sh, cover)))["shapes"][0]["inner_corners"]
    hidden = [tuple(np.round(xy, 9)) for xy, v in zip(ic["board_m"], ic["visible"]) if not v]
    assert hidden == [(-0.02, -0.01)]
    # covers(): the dark squares only (the light squares are not printed)
    assert sh.covers(np.array([[-0.05, -0.04], [-0.03, -0.04], [0.0, 0.0], [0.07, 0.0]])).tolist() == \
        [True, False, False, False]


# --- keys -------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("d,msg", [
    ({"type": "checkerboard", "rows": 3, "cols": 4}, "needs square_m"),
    ({"type": "checkerboard", "rows": 1, "cols": 4, "square_m": 0.02}, "rows >= 2 and cols >= 2"),
    ({"type": "checkerboard", "rows": 3, "cols": 4, "square_m": 0.02, "element": "circle"}, "does not apply"),
    ({"type": "checkerboard", "rows": 3, "cols": 4, "square_m": 0.02, "pitch_m": [0.1, 0.1]}, "does not apply"),
    ({"type": "rectangle", "square_m": 0.02}, "does not apply"),
])
def test_checkerboard_key_errors(d, msg):
    with pytest.raises(InputError, match=msg) as e:
        shape_from_dict(d, 0.13, "spec group 'g' shapes[0]")
    assert "\n" not in str(e.value)


def test_board_size_key(tmp_path):
    from edgetruth.render.dataset.spec import load_spec

    def spec(extra: str) -> Path:
        p = tmp_path / "s.toml"
        p.write_text('[spec]\nname = "s"\n[[group]]\nname = "g"\n' + extra)
        return p

    sp = load_spec(spec('board_size_m = [0.5, 0.4]\nshapes = [{ type = "checkerboard", rows = 3, cols = 4, '
                        'square_m = 0.05 }]\n'))
    sc = sp.groups[0].target
    assert sc.board_half_size_m == (0.25, 0.2) and sc.resolved()["board_half_size_m"] == [0.25, 0.2]
    assert load_spec(spec('target = "T2"\n')).groups[0].target == "T2"  # no scene key: the fixed scene
    default = scene_from_group({"target": "T1", "board_material": {}}, {"board_material": {}}, 0.13,
                               (0.0, -0.15, -0.05), "g")
    assert default.board_half_size_m == BOARD_HALF_SIZE_M and "board_half_size_m" not in default.resolved()
    # a design factor: a level sets it; its cells render apart (separate radiance units)
    (tmp_path / "d.toml").write_text('[spec]\nname = "d"\n[design]\nkind = "target"\n[[design.factor]]\n'
                                     'name = "board"\nlevels = [{ name = "default" }, '
                                     '{ name = "small", board_size_m = [0.5, 0.4] }]\n')
    base, small = load_spec(tmp_path / "d.toml").groups
    assert base.target == "T1" and small.target.board_half_size_m == (0.25, 0.2)
    assert base.radiance_unit != small.radiance_unit
    for extra, msg in [('board_size_m = [0.1, 0.1]\n', "reaches past the board"),  # T1's 13 cm square
                       ('board_size_m = [0.5]\n', "board_size_m"),
                       ('board_size_m = [0.0, 0.5]\n', "board_size_m"),
                       ('kind = "checkerboard"\nboard_size_m = [1, 1]\n', "applies to kind")]:
        with pytest.raises(InputError, match=msg) as e:
            load_spec(spec(extra))
        assert "\n" not in str(e.value)


# --- a render: edges, inner corners and the board's edge where the truth puts them ----------------------
TOL_PX = 0.01
#: cv2.cornerSubPix's own accuracy on a sharp, pixel-integrated X-junction (gradients at pixel centres,
#: bilinear window sampling): measured 0.052 px worst of 12, mean offset (0.006, -0.005) px, after a
#: sigma 1 px Gaussian (symmetric: it keeps a junction's point symmetry, so the saddle stays put)
CORNER_TOL_PX = 0.08
CORNER_BIAS_PX = 0.02
RCAM = Camera(width_px=240, height_px=180, pitch_um=24.0, focal_length_mm=8.0, f_number=0.0,
              focus_distance_m=0.6, distortion=(-0.08, 0.03, 2e-4, -1e-4, 0.0), diffraction_wavelength_nm=0.0,
              natural_vignetting=False)
RPOSE = Pose(0.6, 0.0, 0.0, 4.0, -3.0, 0.0)
# 40 mm squares (~22 px): a measuring window (+-10 px across a side) holds one edge
RSHAPE = shape_from_dict({"type": "checkerboard", "rows": 4, "cols": 5, "square_m": 0.04, "rotation_deg": 8.0,
                          "offset_m": [0.005, 0.0]}, 0.13, "test")
RSCENE = TargetScene("custom", (RSHAPE,), lights=(Light("point", position_m=(0.0, -0.1, -0.05)),),
                     board_half_size_m=(0.17, 0.125))


@pytest.fixture(scope="module")
def rendered(fast_variant):
    import mitsuba as mi

    from edgetruth.render.scene.mitsuba_scene import RenderSettings, TargetRig

    mi.set_variant(fast_variant)
    rig = TargetRig(RCAM, RenderSettings(spp=1024, sampler="multijitter"))
    rig.set_state(RSCENE, RPOSE, 1.0)
    return rig.render(11).astype(np.float64), scene_ground_truth(RCAM, RPOSE, RSCENE)


def test_rendered_checkerboard_sides_on_exact_outline(rendered):
    img, _ = rendered
    curves = [OutlineCurve.of(RCAM, RPOSE, o, Z_M) for o in RSHAPE.outlines()]
    dense = [c.points(np.linspace(0, 1, 4000)) for c in curves]
    board = OutlineCurve.of(RCAM, RPOSE, _board_outline(), 0.0).points(np.linspace(0, 1, 4000))
    fitted = []
    for q, curve in enumerate(curves):
        for j in range(4):
            t0, t1 = j / 4 + 1e-6, (j + 1) / 4 - 1e-6
            rest = curve.points(np.linspace(t1 + 1e-5, t0 + 1 - 1e-5, 4000))
            others = [d for k, d in enumerate(dense) if k != q] + [rest, board]
            pos, r = measure_piece(img, curve, t0, t1, others)
            if len(r) < 4:
                continue
            b, a = np.polyfit(pos, r, 1)
            fitted.append((RSHAPE.outlines()[q].name, j, len(r), max(abs(a - b), abs(a + b))))
    assert len(fitted) >= 38, fitted  # of the 40 sides (40 measured here)
    assert max(f[3] for f in fitted) <= TOL_PX, [f for f in fitted if f[3] > TOL_PX]


def test_rendered_inner_corners_at_the_truth(rendered):
    import cv2

    img, gt = rendered
    ic = np.asarray(gt["shapes"][0]["inner_corners"]["distorted_px"], float)
    g = cv2.GaussianBlur((img / img.max()).astype(np.float32), (0, 0), 1.0)
    start = (ic + np.array([0.6, -0.4])).astype(np.float32).reshape(-1, 1, 2)  # off by 0.72 px
    found = cv2.cornerSubPix(g, start, (7, 7), (-1, -1),
                             (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 100, 1e-5)).reshape(-1, 2)
    err = np.linalg.norm(found - ic, axis=1)
    assert len(ic) == 12 and np.max(err) <= CORNER_TOL_PX, err.round(4)
    assert np.all(np.abs(np.mean(found - ic, axis=0)) <= CORNER_BIAS_PX), np.mean(found - ic, axis=0)


def _board_outline():
    from edgetruth.render.scene.shapes import Outline

    hx, hy = RSCENE.board_half_size_m
    return Outline("board", "polygon", vertices=((-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy)))


def test_rendered_board_edge_where_the_truth_puts_it(rendered):
    img, gt = rendered
    assert gt["board"]["half_size_m"] == [0.17, 0.125]
    truth = gt["board"]["outline"][0]
    curve = OutlineCurve.of(RCAM, RPOSE, _board_outline(), 0.0)
    assert np.max(np.abs(np.asarray(truth["polyline_distorted_px"]) - curve.points(curve.parameters()))) < 1e-9
    squares = [OutlineCurve.of(RCAM, RPOSE, o, Z_M).points(np.linspace(0, 1, 4000)) for o in RSHAPE.outlines()]
    fitted = []
    for j in range(4):
        t0, t1 = j / 4 + 1e-6, (j + 1) / 4 - 1e-6
        rest = curve.points(np.linspace(t1 + 1e-5, t0 + 1 - 1e-5, 4000))
        pos, r = measure_piece(img, curve, t0, t1, squares + [rest])
        if len(r) >= 4:
            b, a = np.polyfit(pos, r, 1)
            fitted.append((j, len(r), max(abs(a - b), abs(a + b))))
    assert len(fitted) == 4 and max(f[2] for f in fitted) <= TOL_PX, fitted
    # the reader counts the board's edge: beyond it (the black background) the signed distance is negative
    so = SceneOutline(gt)
    mid = curve.points(np.array([0.125]))[0]  # the top side's middle
    inward = curve.points(np.array([0.625]))[0] - mid  # towards the bottom side's middle
    inward /= np.linalg.norm(inward)
    d_in, d_out = (float(so.signed_distance(*(mid + s * 3.0 * inward))) for s in (1, -1))
    assert d_in == pytest.approx(3.0, abs=0.05) and d_out == pytest.approx(-3.0, abs=0.05)
    assert img[1, 1] == 0.0 and img[int(mid[1]) + 6, int(mid[0])] > 0.1  # background black, board lit


# --- a printed checkerboard: its dark squares show the image that fills the whole board of squares ------------
def test_printed_checkerboard_shows_the_rectangles_print_in_its_dark_squares(tmp_path, fast_variant):
    """A printed checkerboard's image spans its cols x rows squares (``texture_frame``), like a rectangle of
    that size turned and moved with it (whose print tests/render/scene/test_texture.py checks): pixels wholly
    inside a dark square match the rectangle's render to 1e-5 relative; the light squares show the board."""
    import cv2
    import mitsuba as mi

    from edgetruth.render.scene.materials import Material, with_texture_file
    from edgetruth.render.scene.mitsuba_scene import RenderSettings, TargetRig

    mi.set_variant(fast_variant)
    cv2.imwrite(str(tmp_path / "t.png"), np.random.default_rng(5).integers(0, 65536, (4, 5)).astype(np.uint16))
    mat = with_texture_file(Material("diffuse", albedo=0.9, texture="t.png"), tmp_path, "t")
    cam = Camera(width_px=160, height_px=120, pitch_um=24.0, focal_length_mm=8.0, f_number=0.0,
                 focus_distance_m=0.6, diffraction_wavelength_nm=0.0, natural_vignetting=False)
    pose = Pose(0.6, 0.0, 0.0, 0.0, 0.0, 0.0)
    light = (Light("point", position_m=(0.0, -0.1, -0.05)),)
    checker = Shape("checkerboard", rows=4, cols=5, square_m=0.03, rotation_deg=12.0, offset_m=(0.004, -0.003),
                    material=mat)
    rect = Shape("rectangle", width_m=0.15, height_m=0.12, rotation_deg=12.0, offset_m=(0.004, -0.003), material=mat)
    assert checker.texture_frame() == pytest.approx(rect.texture_frame(), abs=1e-15)
    imgs = []
    for sh in (checker, rect):
        rig = TargetRig(cam, RenderSettings(spp=16, sampler="multijitter"))
        rig.set_state(TargetScene("custom", (sh,), lights=light), pose, 1.0)
        imgs.append(rig.render(2).astype(np.float64))
    cx, cy = cam.principal_point_px
    v, u = np.mgrid[0:cam.height_px, 0:cam.width_px].astype(float)
    sub = np.linspace(-0.5, 0.5, 5)
    su, sv = np.meshgrid(sub, sub)
    xy = np.stack([(u.ravel()[:, None] + su.ravel() - cx) * 0.6 / cam.fx_px,
                   (v.ravel()[:, None] + sv.ravel() - cy) * 0.6 / cam.fy_px], axis=-1)
    dark = checker.covers(xy.reshape(-1, 2)).reshape(len(xy), -1).all(1)
    inside = rect.covers(xy.reshape(-1, 2)).reshape(len(xy), -1).all(1)
    light_sq = inside & ~checker.covers(xy.reshape(-1, 2)).reshape(len(xy), -1).any(1)
    a, b = imgs[0].ravel(), imgs[1].ravel()
    assert dark.sum() > 1000 and light_sq.sum() > 1000
    assert np.max(np.abs(a[dark] - b[dark])) <= 1e-5 * np.max(b[dark])
    # the light squares: the white board (albedo 0.8), not the print (0.9 x a level that varies per texel)
    pts = xy[light_sq].reshape(-1, 2)
    e = light[0].irradiance_at(1.0, pose, np.column_stack([pts, np.full(len(pts), 0.6)])).reshape(-1, len(sub) ** 2)
    pred = e.mean(1) / math.pi * 0.8
    assert np.max(np.abs(a[light_sq] / pred - 1)) < 1e-3, np.max(np.abs(a[light_sq] / pred - 1))
    assert np.std(b[light_sq] / pred) > 0.1  # the rectangle prints there
