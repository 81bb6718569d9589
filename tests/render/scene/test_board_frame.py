"""``board_mode = "frame"``: a board image as S (c_plate − (1 − ρ_s/ρ_b) c_squares), the plate's shading
rendered on a grid and interpolated, the plate's and the squares' coverage exact
(``edgetruth.render.scene.board_frame``).

Without Mitsuba: the coverage image is ``pixel_coverage`` wherever it is not 0 or 1; the enlarged plate holds
every node's ray; a board seen edge-on is refused.  Against Mitsuba (llvm): crops across square corners, a
chessboard's inner corner and the plate's own corner, in focus and defocused, flat and tilted, against the
plain path tracer at 16,384 spp, within its Monte-Carlo error; the darks carry the white's relative noise
only (the path tracer's carry more); a spec through ``render_job``.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from edgetruth.render.optics.camera import load_camera
from edgetruth.render.scene import board_frame as bf
from edgetruth.render.scene.pose import Pose
from edgetruth.render.scene.targets import Checkerboard, SquareBoard


def _squares() -> SquareBoard:
    return SquareBoard.pattern(cols=5, rows=4, side_m=0.02, pitch_m=0.035, margin_m=0.012)


def test_coverage_image_is_the_exact_coverage_wherever_it_is_fractional():
    """``polygon_coverage`` computes ``pixel_coverage`` on a band around the outline and the inside test
    beyond it: over a whole box the two agree to rounding, and the band holds every fractional pixel."""
    from edgetruth.render.scene.edge_band import band_width_px
    from edgetruth.render.scene.edge_coverage import pixel_coverage
    from edgetruth.render.scene.outline import OutlineCurve

    cam = load_camera()
    pose = Pose(0.6, 0.02, -0.01, 12.0, -8.0, roll_deg=17.0)  # defocused (focus 1.5 m), tilted, turned
    quad = _squares().black_quads_local(-1e-5)[7]
    curve = OutlineCurve.polygon(cam, pose, quad)
    poly = curve.polyline()
    reach = band_width_px(cam, float(cam.defocus_radius_px(0.6)))
    x0, y0 = (np.floor(poly.min(0)) - reach - 6).astype(int)
    x1, y1 = (np.ceil(poly.max(0)) + reach + 6).astype(int)
    c = bf.polygon_coverage(cam, curve, x0, y0, x1 - x0, y1 - y0, reach)
    ys, xs = np.mgrid[y0:y1, x0:x1]
    exact = pixel_coverage(cam, curve, xs.ravel().astype(float), ys.ravel().astype(float)).reshape(c.shape)
    assert np.max(np.abs(c - exact)) < 1e-12
    frac = (exact > 1e-12) & (exact < 1 - 1e-12)
    assert frac.sum() > 200 and np.any(exact == 1.0) and np.any(exact == 0.0)


def test_the_enlarged_plate_holds_every_node_and_an_edge_on_board_is_refused():
    cam = load_camera()
    board = Checkerboard()
    pose = Pose(0.8, 0.05, 0.0, 30.0, -10.0, roll_deg=5.0)
    xs, ys = np.meshgrid(np.arange(0, cam.width_px, 64.0), np.arange(0, cam.height_px, 64.0))
    hx, hy = bf.plate_half_size_m(cam, pose, board, xs, ys)
    assert hx >= board.half_size_m[0] and hy >= board.half_size_m[1]
    # the enlarged plate's corners project outside every node (the whole view lies on it)
    big = np.array([[-hx, -hy, 0.0], [hx, -hy, 0.0], [hx, hy, 0.0], [-hx, hy, 0.0]])
    from edgetruth.render.scene.shading_frame import inside_mask

    corners = cam.project(pose.to_camera(big), distorted=False)
    und = cam.undistort_pixels(np.column_stack([xs.ravel(), ys.ravel()]))
    x0, y0 = int(np.floor(und[:, 0].min())) - 1, int(np.floor(und[:, 1].min())) - 1
    mask = inside_mask(corners, x0, y0, int(und[:, 0].max()) - x0 + 2, int(und[:, 1].max()) - y0 + 2)
    r, c = np.round(und[:, 1]).astype(int) - y0, np.round(und[:, 0]).astype(int) - x0
    assert mask[r, c].all()
    with pytest.raises(ValueError, match="edge-on"):
        bf.plate_half_size_m(cam, Pose(0.8, 0.0, 0.0, 89.9, 0.0), board, xs, ys)


def _reference(cam, board, pose, crop, spp: int, seeds=(11, 12)) -> tuple[np.ndarray, np.ndarray]:
    """The plain path tracer's crop: the mean of two seeds and its per-pixel Monte-Carlo error |a - b| / 2."""
    from edgetruth.render.scene.mitsuba_scene import CheckerRig, RenderSettings

    rig = CheckerRig(cam, RenderSettings(spp=spp), board=board, crop=crop)
    rig.set_state(pose, 1.2)
    a, b = (rig.render(s).astype(np.float64) for s in seeds)
    return 0.5 * (a + b), np.abs(a - b) / 2.0


def _composite(cam, board, pose, crop, spp: int = 256, seed: int = 5) -> np.ndarray:
    from edgetruth.render.scene.mitsuba_scene import RenderSettings

    rad, info = bf.render_board_frame(cam, RenderSettings(spp=spp), board, pose, crop, seed, 1.2)
    return rad.astype(np.float64), info


def _crop_at(cam, pose, point_local, size: int = 48) -> tuple[int, int, int, int]:
    x, y = cam.project(pose.to_camera(np.asarray(point_local, float)[None]))[0]
    return int(round(x)) - size // 2, int(round(y)) - size // 2, size, size


@pytest.mark.parametrize("case", [
    "squares corner, 0.6 m defocused, tilted",
    pytest.param("chessboard inner corner, 1.5 m in focus", marks=pytest.mark.slow),
    pytest.param("plate corner, 1.0 m, tilted", marks=pytest.mark.slow)])
@pytest.mark.slow
def test_composite_agrees_with_the_path_tracer(fast_variant, case):
    """Mean of two 16,384-spp path renders against the composite (256 spp at 16-px nodes): the difference is
    the two renders' Monte-Carlo error and no more, its mean below 1e-4 of the white."""
    cam = load_camera()
    if case.startswith("squares"):
        board, pose = _squares(), Pose(0.6, 0.01, 0.02, 14.0, -9.0, roll_deg=11.0)
        point = board.black_quads_local(0.0)[8][2]
    elif case.startswith("chessboard"):
        board, pose = Checkerboard(), Pose(1.5, -0.02, 0.01, -6.0, 4.0, roll_deg=3.0)
        point = board.inner_corners_local()[20]
    else:
        board, pose = _squares(), Pose(1.0, 0.03, -0.02, -20.0, 10.0, roll_deg=-7.0)
        point = board.plate_corners_local()[1]
    crop = _crop_at(cam, pose, point)
    ref, err = _reference(cam, board, pose, crop, 16384)
    comp, info = _composite(cam, board, pose, crop)
    white = float(np.percentile(ref, 99))
    diff = comp - ref
    expected = float(np.mean(err ** 2))
    print(f"{case}: white {white:.4g}, rms diff {math.sqrt(np.mean(diff ** 2)) / white:.3g}, expected "
          f"{math.sqrt(expected) / white:.3g}, mean {diff.mean() / white:.3g}, fractional px {info['pixels']}")
    assert info["pixels"] > 100 and np.ptp(ref) > 0.5 * white  # the crop holds an edge
    assert np.mean(diff ** 2) <= 3.0 * expected + (1e-4 * white) ** 2  # + the composite's own shading noise
    assert abs(diff.mean()) <= 1e-4 * white


def test_darks_carry_only_the_whites_relative_noise(fast_variant):
    """Two seeds of a crop over a dark square and the white around it at 64 spp: in the composite a dark
    pixel is its place's white shading times ρ_s/ρ_b, so its relative noise is the white's (both are the
    shading's); the path tracer's darks carry the PSF tail's samples on the white, far more."""
    from edgetruth.render.scene.mitsuba_scene import CheckerRig, RenderSettings

    cam = load_camera()
    board, pose = _squares(), Pose(1.2, 0.0, 0.0, 5.0, -3.0)
    crop = _crop_at(cam, pose, board.black_quads_local(0.0)[6].mean(0), 64)
    a, b = (_composite(cam, board, pose, crop, spp=64, seed=s)[0] for s in (1, 2))
    rho_s, rho_b = bf.reflectances(board)
    white = float(np.percentile(a, 99))
    dark, light = a < 1.5 * rho_s / rho_b * white, a > 0.98 * white

    def rel(x, y, m):
        return float(np.std((x - y)[m]) / np.mean(x[m]))

    assert dark.sum() > 100 and light.sum() > 100
    frame_dark, frame_light = rel(a, b, dark), rel(a, b, light)
    rig = CheckerRig(cam, RenderSettings(spp=64), board=board, crop=crop)
    rig.set_state(pose, 1.2)
    pa, pb = (rig.render(s).astype(np.float64) for s in (1, 2))
    path_dark = rel(pa, pb, dark)
    print(f"relative noise: composite dark {frame_dark:.2e}, white {frame_light:.2e}; path dark {path_dark:.2e}")
    assert frame_dark <= 1.2 * frame_light + 1e-6
    assert path_dark > 3.0 * frame_dark


@pytest.mark.slow
def test_board_mode_in_a_spec(tmp_path, fast_variant):
    """``board_mode = "frame"``: the checkerboard image agrees with the path-traced one to the latter's noise, its
    JSON says how it was made, the target images are untouched; a curled board is refused (exit 2 in the CLI)."""
    from edgetruth.errors import InputError
    from edgetruth.render.dataset.image import render_job
    from edgetruth.render.dataset.spec import load_spec
    from edgetruth.render.testing import tiny_spec_pair

    frame, reference = tiny_spec_pair(tmp_path, 'board_mode = "frame"\nshading_step_px = 8', spp=4096, edge_spp=64)
    path = reference.path
    text = path.read_text()
    assert frame.render.to_dict()["board_mode"] == "frame" and "board_mode" not in reference.render.to_dict()
    assert frame.identity_sha256 != reference.identity_sha256
    rad_f, _, gt_f = render_job(frame, frame.jobs[2])
    rad_p, _, gt_p = render_job(reference, reference.jobs[2])
    assert gt_f["kind"] == "checkerboard" and gt_p["render"]["edge_band"] is None
    band = gt_f["render"]["edge_band"]
    assert band["mode"] == "board-frame" and band["shading_step_px"] == 8 and band["fractional_pixels"] > 20
    scale = float(np.percentile(rad_p, 99))
    assert np.max(np.abs(rad_f - rad_p)) < 0.03 * scale
    assert abs(float(np.mean(rad_f - rad_p))) < 1e-3 * scale
    # the target images render as before
    np.testing.assert_array_equal(render_job(frame, frame.jobs[0])[0], render_job(reference, reference.jobs[0])[0])
    # a curled board is not flat: refused, named
    path.write_text(text.replace('board_mode = "path"', 'board_mode = "frame"', 1).replace(
        'kind = "checkerboard"', 'kind = "checkerboard"\nboard_bend_mm = [1.0, 0.0, 0.5]', 1))
    with pytest.raises(InputError, match="board_mode"):
        load_spec(path)
