"""The catalogue's grid (rows x cols squares or circles, as on Zhang's board): per-element exact outline
truth against the analytic elements, covering by later shapes, the spec keys' one-line errors, and a render
whose every pixel matches the coverage the truth predicts."""
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
from edgetruth.render.scene.shapes import Shape, shape_from_dict
from edgetruth.render.scene.target_scene import TargetScene

DISTORTED = Camera(width_px=320, height_px=240, pitch_um=20.0, focal_length_mm=8.0, f_number=0.0,
                   focus_distance_m=0.8, distortion=(-0.25, 0.12, 1e-3, -8e-4, 0.0))
TILTED = Pose(0.8, 0.02, -0.01, 12.0, -8.0, 20.0)
Z_M = 10e-6


def _grid(**kw):
    d = {"type": "grid", "rows": 3, "cols": 4, "element_size_m": 0.012, "pitch_m": [0.02, 0.025],
         "offset_m": [0.01, -0.005], "rotation_deg": 25.0, **kw}
    return shape_from_dict(d, 0.13, "test")


def test_grid_elements_are_the_analytic_squares_through_the_lens():
    g = _grid()
    gt = scene_ground_truth(DISTORTED, TILTED, TargetScene("custom", (g,)))
    outs = gt["shapes"][0]["outlines"]
    assert [o["name"] for o in outs] == [f"r{r}c{c}" for r in range(3) for c in range(4)]
    th = math.radians(25.0)
    rot = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
    h = 0.006
    for r in range(3):
        for c in range(4):
            centre = rot @ [(c - 1.5) * 0.02, (r - 1) * 0.025] + [0.01, -0.005]
            loc = np.array([[-h, -h], [h, -h], [h, h], [-h, h]]) @ rot.T + centre
            exp = DISTORTED.project(TILTED.to_camera(np.column_stack([loc, np.full(4, -Z_M)])))
            o = outs[4 * r + c]
            assert np.max(np.abs(np.asarray(o["corners_distorted_px"]) - exp)) < 1e-9
            assert o["visible_intervals"] == [[0.0, 1.0]] and all(o["corners_visible"])
    assert gt["target"]["type"] == "grid" and gt["target"]["size_m"] == pytest.approx(3 * 0.02 + 0.012)
    assert gt["shapes"][0]["rows"] == 3 and gt["shapes"][0]["element"] == "square"


def test_circle_grid_distances_and_a_covering_disk():
    """Frontal pinhole: each element images to a circle; a disk laid over element r0c0 hides it and cuts
    r0c1; the reader's distances are those to the visible analytic circles."""
    cam = Camera(width_px=320, height_px=240, pitch_um=20.0, focal_length_mm=8.0, f_number=0.0,
                 focus_distance_m=0.8)
    pose = Pose(0.8, 0.0, 0.0, 0.0, 0.0, 0.0)
    g = _grid(element="circle", rotation_deg=0.0, offset_m=[0.0, 0.0], rows=2, cols=3)
    cover = Shape("circle", offset_m=(-0.02, -0.0125), diameter_m=0.03)  # r0c0's centre; reaches into r0c1
    gt = scene_ground_truth(cam, pose, TargetScene("custom", (g, cover)))
    vis = {o["name"]: o["visible_intervals"] for o in gt["shapes"][0]["outlines"]}
    assert vis["r0c0"] == [] and len(vis["r0c1"]) == 1 and vis["r1c2"] == [[0.0, 1.0]]
    so = SceneOutline.from_ground_truth(gt)
    cx, cy = cam.principal_point_px
    f = cam.fx_px
    circles = [((c - 1) * 0.02, (r - 0.5) * 0.025, 0.006, 1) for r in range(2) for c in range(3)]
    rng = np.random.default_rng(4)
    q = rng.uniform([cx - f * 0.05 / 0.8, cy - f * 0.04 / 0.8], [cx + f * 0.05 / 0.8, cy + f * 0.04 / 0.8],
                    (3000, 2))

    def centre_px(x0, y0, k):  # (centre px, px per m) of a board point of shape layer k
        z = 0.8 - k * Z_M
        return np.array([cx + f * x0 / z, cy + f * y0 / z]), f / z

    def circ(x0, y0, r_m, k):
        c, s = centre_px(x0, y0, k)
        return np.linalg.norm(q - c, axis=1) - s * r_m

    # r0c1's visible arc: the cover (centre 0.02 m to its left, radius 0.015 m) cuts it at x = -a from its
    # centre, y = +-sqrt(r^2 - a^2); where a point's radial foot is hidden, its nearest arc point is a cut end
    r, big, dd = 0.006, 0.015, 0.02
    a = (r ** 2 - big ** 2 + dd ** 2) / (2 * dd)
    c1, s1 = centre_px(0.0, -0.0125, 1)
    ends = np.array([c1 + s1 * np.array([-a, -math.sqrt(r * r - a * a)]),
                     c1 + s1 * np.array([-a, math.sqrt(r * r - a * a)])])
    c_cov, s_cov = centre_px(-0.02, -0.0125, 2)
    q = np.concatenate([q, ends[rng.integers(0, 2, 1000)] + rng.normal(0, 1.5, (1000, 2))])  # round the cuts
    cov = circ(-0.02, -0.0125, 0.015, 2)
    d = [circ(x0, y0, r_m, k) for x0, y0, r_m, k in circles]
    foot = c1 + s1 * r * (q - c1) / np.linalg.norm(q - c1, axis=1, keepdims=True)
    foot_hidden = np.linalg.norm(foot - c_cov, axis=1) < s_cov * big
    to_end = np.min(np.linalg.norm(q[:, None] - ends[None], axis=2), axis=1)
    arc = np.where(foot_hidden, np.sign(d[1]) * to_end, d[1])
    cand = np.stack([cov, arc] + d[2:])  # r0c0 (d[0]) is hidden under the cover
    ranked = np.sort(np.abs(cand), axis=0)
    i = np.argmin(np.abs(cand), axis=0)
    exact = cand[i, np.arange(len(q))]
    ok = ranked[1] - ranked[0] > 1e-2  # not a tie between two edges (their signs may differ there)
    got = so.signed_distance(q[:, 0], q[:, 1])
    # (a cut end is never strictly nearest: the cover's circle passes through it too; but next to the ends a
    # visible piece running on into the cover, or stopping short, would show)
    assert ok.mean() > 0.95 and ok[-1000:].sum() > 900
    assert np.max(np.abs(got[ok] - exact[ok])) < 1.1e-3
    assert set(so.shape_at(q[:, 0], q[:, 1]).tolist()) == {-1, 0, 1}


@pytest.mark.parametrize("extra,needle", [
    ({"pitch_m": [0.01, 0.02]}, "must exceed element_size_m"),
    ({"element_size_m": None}, "needs element_size_m"),
    ({"element": "hexagon"}, "element"),
    ({"rows": 0}, "rows"),
])
def test_bad_grid_keys_are_one_line_errors(extra, needle):
    d = {"type": "grid", "rows": 2, "cols": 2, "element_size_m": 0.012, "pitch_m": [0.02, 0.02], **extra}
    d = {k: v for k, v in d.items() if v is not None}
    with pytest.raises(InputError) as e:
        shape_from_dict(d, 0.13, "group 'g' shapes[0]")
    assert needle in str(e.value) and "\n" not in str(e.value)


def test_grid_keys_on_another_type_are_refused():
    with pytest.raises(InputError, match="rows does not apply"):
        shape_from_dict({"type": "rectangle", "rows": 2}, 0.13, "group 'g' shapes[0]")


def test_rendered_grid_matches_the_truths_coverage(fast_variant):
    """Box filter, no PSF, matte: each pixel is rho_b E/pi on the board and rho_t E/pi on an element, mixed
    by the share of the pixel each covers; the share from the truth (SceneOutline.shape_at on 16 x 16
    sub-pixel points) predicts every pixel to within the sub-sampling's error."""
    import mitsuba as mi

    from edgetruth.render.scene.mitsuba_scene import RenderSettings, TargetRig

    mi.set_variant(fast_variant)
    cam = Camera(width_px=96, height_px=64, pitch_um=30.0, focal_length_mm=8.0, f_number=0.0,
                 focus_distance_m=0.6, diffraction_wavelength_nm=0.0, natural_vignetting=False)
    pose = Pose(0.6, 0.0, 0.0, 0.0, 0.0, 0.0)
    black = Material("diffuse", albedo=0.04)
    squares = Shape("grid", offset_m=(-0.035, 0.0), rotation_deg=15.0, rows=3, cols=3, pitch_m=(0.02, 0.02),
                    element="square", element_size_m=0.012, material=black)
    circles = Shape("grid", offset_m=(0.045, 0.0), rows=3, cols=2, pitch_m=(0.02, 0.02), element="circle",
                    element_size_m=0.013, material=black)
    scene = TargetScene("custom", (squares, circles), lights=(Light("point", position_m=(0.0, -0.1, -0.05)),))
    rig = TargetRig(cam, RenderSettings(spp=256, sampler="multijitter"))
    rig.set_state(scene, pose, 1.0)
    img = rig.render(3).astype(np.float64)
    so = SceneOutline.from_ground_truth(scene_ground_truth(cam, pose, scene))
    v, u = np.mgrid[0:64, 0:96]
    sd = so.signed_distance(u.astype(float), v.astype(float))
    edge = np.abs(sd) < 0.75  # beyond half a pixel's diagonal from every edge: the pixel is all one side
    frac_board = (sd > 0).astype(float)
    n = 16
    sub = (np.arange(n) + 0.5) / n - 0.5
    sx, sy = np.meshgrid(sub, sub)
    xs = (u[edge][:, None] + sx.ravel()).ravel()
    ys = (v[edge][:, None] + sy.ravel()).ravel()
    frac_board[edge] = (so.shape_at(xs, ys) == -1).reshape(-1, n * n).mean(axis=1)
    cx, cy = cam.principal_point_px
    board = np.column_stack([(u.ravel() - cx) * 0.6 / cam.fx_px, (v.ravel() - cy) * 0.6 / cam.fx_px,
                             np.full(u.size, 0.6)])
    e = scene.lights[0].irradiance_at(1.0, pose, board).reshape(64, 96)
    pred = e / math.pi * (0.04 + (0.8 - 0.04) * frac_board)
    contrast = e / math.pi * 0.76
    err = (img - pred) / contrast
    assert edge.sum() > 300 and (sd < -0.75).sum() > 15 * 6  # 15 elements, each with inner pixels
    assert np.max(np.abs(err[~edge])) < 1e-4  # flat: no Monte-Carlo noise, float rounding only (4e-6)
    # edge pixels: 16 x 16 sub-sampling is exact to ~1/32 of the contrast per pixel, MC (256 spp) ~1/50
    assert np.max(np.abs(err[edge])) < 0.06
    assert abs(np.mean(err[edge])) < 3e-3  # no bias: the edges lie where the truth puts them
