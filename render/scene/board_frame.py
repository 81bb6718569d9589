"""A board image without Monte-Carlo edges: ``board_mode = "frame"``.

A board image (kind ``checkerboard``, ``squares`` or ``circles_grid``) is a white plate with dark squares (or
circles: their exact outlines, ``circles_grid.CirclesGrid.dark_curves``) printed on it
(10 µm in front of it), both diffuse, lit by one small area light, in a black room.  A diffuse surface's
radiance is its reflectance times the irradiance it gets over π, so the squares' radiance is the
plate's times ρ_s / ρ_b where they lie, and every pixel is

    S (c_plate − (1 − ρ_s / ρ_b) c_squares)

- S is the plate's shading alone: the plate enlarged (per image) until every node the interpolation
  reads lies on it, its squares as white as the plate, rendered with Mitsuba on a grid of every
  ``shading_step_px``-th pixel and interpolated by 4-point Lagrange cubics, as ``shading_frame`` does
  for target images;
- c_plate and c_squares are the exact lens-weighted coverages (``edge_coverage.pixel_coverage``) of the
  plate's outline and of each square's (the squares are disjoint, and coverage is linear in the
  region, so theirs add), on the pixels within the kernel's reach of each outline, and the pixel
  centre's inside test beyond it.

No sample meets an edge, and none lands in a dark square: the darks carry no Monte-Carlo noise (in the
path-traced image the diffraction tail's samples that land on the white around them do).  Left out:
what ``shading_frame`` leaves out (the shading's variation beyond a cubic between nodes and across a
pixel's kernel).  The squares, 10 µm in front of the plate, would shadow a sliver 10 µm · tan θ wide
beside them (θ the light's angle from the board's normal); the path tracer shows none either (on Zhang's
twin, light at 32°: the squares' far sides agree with the composite to 1e-4 of the white, where the
sliver would make 1.5e-2), and the two agree within the reference's Monte-Carlo error
(tests/render/scene/test_board_frame.py).  Flat boards and a static camera only (a curled board's
mesh is faceted: its path-traced image is the reference there).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: the enlarged plate's extent beyond the farthest node it must hold (relative)
PLATE_GROWTH = 1.25


@dataclass(frozen=True)
class PlateOnly:
    """``board`` with its squares as white as its plate: the shading rig's board (``CheckerRig``)."""

    board: object

    @property
    def half_size_m(self) -> tuple[float, float]:
        return self.board.half_size_m

    @property
    def board_reflectance(self) -> float:
        return reflectances(self.board)[1]

    @property
    def square_reflectance(self) -> float:
        return reflectances(self.board)[1]

    def black_quads_local(self, z_m: float) -> np.ndarray:
        return self.board.black_quads_local(z_m)

    def plate_corners_local(self) -> np.ndarray:
        return self.board.plate_corners_local()


def reflectances(board) -> tuple[float, float]:
    """(the squares', the plate's) diffuse reflectance of a ``Checkerboard`` or ``SquareBoard``, as ``CheckerRig``
    renders them."""
    from edgetruth.render.scene.targets import BOARD_REFLECTANCE, CHECKER_BLACK_REFLECTANCE

    return (float(getattr(board, "square_reflectance", CHECKER_BLACK_REFLECTANCE)),
            float(getattr(board, "board_reflectance", BOARD_REFLECTANCE)))


def plate_half_size_m(camera, pose, board, xs: np.ndarray, ys: np.ndarray) -> tuple[float, float]:
    """The half sides (m) of a plate, centred as ``board``'s, that holds where the rays of pixels (``xs``, ``ys``)
    meet the board's plane (with ``PLATE_GROWTH`` to spare), and at least the board's own plate."""
    d = camera.rays(np.column_stack([np.ravel(xs), np.ravel(ys)]))
    r, t = pose.rotation, pose.translation_m
    n = r[:, 2]
    denom = d @ n
    s = np.where(np.abs(denom) > 1e-9, float(n @ t) / np.where(denom == 0.0, 1.0, denom), -1.0)
    hit = s > 0.0
    if not np.all(hit):
        raise ValueError("board_mode = 'frame': a node near the board looks past the board's plane (a board seen "
                         "edge-on); use board_mode = 'path'")
    local = (s[:, None] * d - t) @ r  # R^T (X - t)
    hx, hy = board.half_size_m
    ext = PLATE_GROWTH * np.max(np.abs(local[:, :2]), axis=0)
    return max(hx, float(ext[0])), max(hy, float(ext[1]))


def _shading_rigs(camera, settings, board) -> tuple:
    """The (big, small) pixel-list rigs of the plate alone (process-wide, re-posed per image)."""
    import mitsuba as mi

    from edgetruth.render.scene.edge_band import ANALYTIC_TILE_PX, _rigs
    from edgetruth.render.scene.mitsuba_scene import CheckerRig
    from edgetruth.render.scene.shading_frame import SMALL_FILM_PX

    out = []
    for px in (ANALYTIC_TILE_PX, SMALL_FILM_PX):
        key = ("board-frame", mi.variant(), camera, settings, PlateOnly(board), px)
        if key not in _rigs:
            _rigs[key] = CheckerRig(camera, settings, board=PlateOnly(board), window=(px, px))
        out.append(_rigs[key])
    return tuple(out)


def polygon_coverage(camera, curve, x0: int, y0: int, w: int, h: int, reach_px: float) -> np.ndarray:
    """(h, w): the exact lens-weighted coverage of the polygon ``curve`` (an ``OutlineCurve``) at pixel centres
    (x0 + col, y0 + row): ``pixel_coverage`` within ``reach_px`` (+ 2 px) of its outline, the rasterised
    inside test beyond (``shading_frame.inside_mask``: exact there)."""
    import cv2

    from edgetruth.render.scene.edge_coverage import pixel_coverage
    from edgetruth.render.scene.shading_frame import inside_mask

    poly = curve.polyline()
    c = inside_mask(poly, x0, y0, w, h).astype(np.float64)
    band = np.zeros((h, w), np.uint8)
    shift = 8
    pts = np.round((np.asarray(poly, np.float64) - (x0, y0)) * (1 << shift)).astype(np.int32)
    cv2.polylines(band, [pts.reshape(-1, 1, 2)], True, 1, thickness=2 * int(math.ceil(reach_px)) + 5,
                  lineType=cv2.LINE_8, shift=shift)
    rr, cc = np.nonzero(band)
    if len(rr):
        c[rr, cc] = pixel_coverage(camera, curve, (cc + x0).astype(float), (rr + y0).astype(float))
    return c


def _box(points_px: np.ndarray, pad: float, frame) -> tuple[int, int, int, int] | None:
    """(x0, y0, x1, y1) of ``points_px`` padded by ``pad`` px, within ``frame``; None when empty."""
    fx0, fy0, fw, fh = frame
    lo = np.floor(np.asarray(points_px).min(0) - pad).astype(int)
    hi = np.ceil(np.asarray(points_px).max(0) + pad + 1).astype(int)
    x0, y0 = max(int(lo[0]), fx0), max(int(lo[1]), fy0)
    x1, y1 = min(int(hi[0]), fx0 + fw), min(int(hi[1]), fy0 + fh)
    return (x0, y0, x1, y1) if x1 > x0 and y1 > y0 else None


def _dark_outlines(camera, pose, board):
    """(curve, points (n, 2) px whose box bounds it) per dark print: a square's polygon and its projected corners;
    a circle grid's exact circles (``dark_curves``) and their polylines."""
    from edgetruth.render.scene.outline import OutlineCurve
    from edgetruth.render.scene.shapes import TARGET_STANDOFF_M

    if hasattr(board, "dark_curves"):
        for curve in board.dark_curves(camera, pose, -TARGET_STANDOFF_M):
            yield curve, curve.polyline()
        return
    for quad in board.black_quads_local(-TARGET_STANDOFF_M):
        yield OutlineCurve.polygon(camera, pose, quad), camera.project(pose.to_camera(quad))


def render_board_frame(camera, settings, board, pose, frame: tuple[int, int, int, int], seed: int,
                       irradiance_w_m2: float, light_position_m=None) -> tuple[np.ndarray, dict]:
    """The radiance (h, w) float32 of ``frame`` = (x0, y0, w, h) of ``board`` (a flat ``Checkerboard`` or
    ``SquareBoard``) at ``pose`` as the module docstring's composite (``settings.spp`` at the shading nodes);
    returns it and {render_s, coverage_s, pixels (fractional c), nodes, squares, plate_half_size_m}."""
    import time

    from edgetruth.render.scene.edge_band import band_width_px
    from edgetruth.render.scene.outline import OutlineCurve
    from edgetruth.render.scene.shading_frame import SHADING_STEP_PX, _render_grid, axis_nodes, interpolate, \
        nodes_for

    if camera.moving:
        raise ValueError("board_mode = 'frame' needs a static camera (a moving outline sweeps); use 'path'")
    fx0, fy0, fw, fh = (int(v) for v in frame)
    radiance = np.zeros((fh, fw), np.float64)
    plate = OutlineCurve.polygon(camera, pose, board.plate_corners_local())
    corners = pose.to_camera(board.plate_corners_local())
    reach = band_width_px(camera, float(np.max(camera.defocus_radius_px(corners[:, 2]))))
    plate_px = plate.polyline()
    box = _box(plate_px, reach + 2.0, (fx0, fy0, fw, fh))
    info = {"render_s": 0.0, "coverage_s": 0.0, "pixels": 0, "nodes": 0, "squares": 0, "plate_half_size_m": None}
    if box is None:  # the plate is out of this frame: the black room
        return radiance.astype(np.float32), info
    bx0, by0, bx1, by1 = box
    step = int(getattr(settings, "shading_step_px", SHADING_STEP_PX))
    xn_all, yn_all = axis_nodes(camera.width_px, step), axis_nodes(camera.height_px, step)
    xn, yn = xn_all[nodes_for(xn_all, bx0, bx1)], yn_all[nodes_for(yn_all, by0, by1)]
    gx, gy = np.meshgrid(xn.astype(np.float64), yn.astype(np.float64))
    half = plate_half_size_m(camera, pose, board, gx, gy)
    rigs = _shading_rigs(camera, settings, board)
    for rig in rigs:
        rig.set_state(pose, irradiance_w_m2, light_position_m)
        rig.set_plate_half_size(pose, half)
    nodes, render_s = _render_grid(rigs, xn, yn, seed, "board-frame")
    shading = interpolate(nodes, yn, xn, np.arange(by0, by1), np.arange(bx0, bx1))

    t0 = time.perf_counter()
    w, h = bx1 - bx0, by1 - by0
    c = polygon_coverage(camera, plate, bx0, by0, w, h, reach)
    rho_s, rho_b = reflectances(board)
    dark = 1.0 - rho_s / rho_b
    n_sq = 0
    for curve, extent_px in _dark_outlines(camera, pose, board):
        sb = _box(extent_px, reach + 2.0, (bx0, by0, w, h))
        if sb is None:
            continue
        sx0, sy0, sx1, sy1 = sb
        c[sy0 - by0:sy1 - by0, sx0 - bx0:sx1 - bx0] -= dark * polygon_coverage(camera, curve, sx0, sy0, sx1 - sx0,
                                                                              sy1 - sy0, reach)
        n_sq += 1
    coverage_s = time.perf_counter() - t0
    radiance[by0 - fy0:by1 - fy0, bx0 - fx0:bx1 - fx0] = shading * c
    frac = int(np.count_nonzero((c > 1e-12) & (c < 1.0 - 1e-12) & (np.abs(c - (1.0 - dark)) > 1e-12)))
    info.update(render_s=render_s, coverage_s=coverage_s, pixels=frac, nodes=int(nodes.size), squares=n_sq,
                plate_half_size_m=[round(half[0], 6), round(half[1], 6)])
    return radiance.astype(np.float32), info


def render_board_job(camera, settings, board, pose, crop, seed: int, irradiance_w_m2: float,
                     light_position_m=None) -> tuple[np.ndarray, dict]:
    """A board job's radiance (the frame or ``crop``) in ``board_mode = "frame"``, and the JSON's ``edge_band``
    block plus ``render_s`` (its renders and coverage)."""
    from edgetruth.render.scene.shading_frame import SHADING_STEP_PX

    frame = tuple(crop) if crop else (0, 0, camera.width_px, camera.height_px)
    radiance, res = render_board_frame(camera, settings, board, pose, frame, seed, irradiance_w_m2,
                                       light_position_m)
    return radiance, {
        "mode": "board-frame", "render_s": res["render_s"] + res["coverage_s"], "spp": settings.spp,
        "shading_step_px": int(getattr(settings, "shading_step_px", SHADING_STEP_PX)),
        "fractional_pixels": res["pixels"], "shading_nodes": res["nodes"], "squares": res["squares"],
        "shading_plate_half_size_m": res["plate_half_size_m"],
        "meaning": "every pixel is S (c_plate - (1 - rho_s / rho_b) c_squares): S the plate's shading alone "
                   "(enlarged beyond the view, its squares white), rendered at spp on every shading_step_px-th "
                   "pixel and interpolated by 4-point Lagrange cubics; c_plate and c_squares the exact "
                   "lens-weighted coverages of the plate and of the squares (edgetruth.render.scene.edge_coverage); "
                   "no full-frame render, no Monte-Carlo noise at edges or in the squares "
                   "(edgetruth.render.scene.board_frame)"}

