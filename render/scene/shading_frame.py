"""The whole frame without Monte-Carlo edges: ``edge_mode = "frame"``.

A target image is a board and one flat target on it, each smoothly shaded (one small area light,
direct light only).  The analytic band (``edgetruth.render.scene.edge_band``) composites the pixels
near the outline as S_out (1 − c) + S_in c; this mode composites *every* pixel so:

- S_out (the board alone, the target parked) and S_in (the target's material over the whole view)
  render with Mitsuba at ``edge_spp`` on a grid of every ``shading_step_px``-th pixel (the last row
  and column included), as pixel lists (``set_pixels``); S_in only on the nodes that reach the target;
- each is interpolated to every pixel, separably, by the 4-point Lagrange cubic through the nearest
  nodes (exact for cubics; local, so a pixel's value depends on its 4 x 4 nodes only, whatever the
  crop);
- c is the exact lens-weighted coverage on the band's tiles (``edge_coverage.pixel_coverage``) and,
  beyond the kernel's reach, 1 inside the outline and 0 outside.

No full-frame render, and no sample ever meets an edge.  What it leaves out: the shading's variation
between nodes beyond a cubic (irradiance from a light ≥ 0.5 m away varies on the scale of the view,
hundreds of px: the interpolation error is ~ (step / scale)^4, below 1e-6 of the signal at 16 px) and
the shading's variation across a pixel's kernel (as the analytic band: docs/optics.md).  Checked
against full Mitsuba renders in tests/render/scene/test_shading_frame.py.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

#: the default node spacing, px
SHADING_STEP_PX = 16
#: interpolation order: 4-point Lagrange (cubic)
_ORDER = 4


def axis_nodes(n_px: int, step_px: int) -> np.ndarray:
    """The grid's node pixels along an axis of ``n_px`` pixels: every ``step_px``-th, and the last."""
    nodes = np.arange(0, n_px, int(step_px))
    return nodes if nodes[-1] == n_px - 1 else np.append(nodes, n_px - 1)


def lagrange_weights(nodes: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(first node index (N,), weights (N, k)) of the k-point Lagrange interpolation at ``x`` through the
    k nodes nearest its interval (k = 4, fewer when there are fewer nodes): value = Σ_j w_j f(node_{i0+j})."""
    nodes = np.asarray(nodes, np.float64)
    x = np.asarray(x, np.float64)
    k = min(_ORDER, len(nodes))
    i = np.clip(np.searchsorted(nodes, x, side="right") - 1, 0, len(nodes) - 1)
    i0 = np.clip(i - (k // 2 - 1), 0, len(nodes) - k)
    g = nodes[i0[:, None] + np.arange(k)]  # (N, k)
    w = np.ones((len(x), k))
    for j in range(k):
        for m in range(k):
            if m != j:
                w[:, j] *= (x - g[:, m]) / (g[:, j] - g[:, m])
    return i0, w


def interpolate(values: np.ndarray, y_nodes: np.ndarray, x_nodes: np.ndarray, rows: np.ndarray,
                cols: np.ndarray) -> np.ndarray:
    """``values`` (len(y_nodes), len(x_nodes)) on the node grid -> (len(rows), len(cols)) at those pixels."""
    iy, wy = lagrange_weights(y_nodes, rows)
    ix, wx = lagrange_weights(x_nodes, cols)
    along_x = np.zeros((values.shape[0], len(cols)))
    for j in range(wx.shape[1]):
        along_x += values[:, ix + j] * wx[:, j]
    out = np.zeros((len(rows), len(cols)))
    for j in range(wy.shape[1]):
        out += along_x[iy + j, :] * wy[:, j, None]
    return out


def nodes_for(nodes: np.ndarray, lo: int, hi: int) -> slice:
    """The slice of ``nodes`` that interpolating pixels lo .. hi − 1 reads."""
    i0, w = lagrange_weights(nodes, np.array([lo, hi - 1], np.float64))
    return slice(int(i0[0]), int(i0[1]) + w.shape[1])


#: the films of the node lists: ``ANALYTIC_TILE_PX``² pixels, and the remainder in films of ``SMALL_FILM_PX``²
#: when fewer of those cost less (a render call's fixed cost against the padded pixels' samples)
SMALL_FILM_PX = 16
#: a render call's fixed cost in samples (~15 ms at ~20 M samples/s on 2 cores, llvm)
_CALL_SAMPLES = 300_000


def _film_plan(n: int, big: int, small: int, spp: int) -> list[int]:
    """Film sizes (pixels) that hold ``n`` listed pixels: whole big films, then the remainder in small films
    where ceil(rest / small) of them cost fewer samples (padding included) than one more big film."""
    plan = [big] * (n // big)
    rest = n - len(plan) * big
    if rest:
        k = -(-rest // small)
        fixed = _CALL_SAMPLES / max(spp, 1)  # in pixels
        plan += [small] * k if k * (small + fixed) < big + fixed else [big]
    return plan


def _render_grid(rigs: tuple, xn: np.ndarray, yn: np.ndarray, seed: int, which: str) -> tuple[np.ndarray, float]:
    """The shading at the nodes ``xn`` x ``yn`` (frame pixels): ``rigs`` = (big, small) pixel-list rigs (small may
    be None); film k has seed ``pixel_chunk_seed(seed, k, which)``; (values (len(yn), len(xn)), s in renders)."""
    from edgetruth.render.scene.edge_band import render_pixel_list

    big, small = rigs
    gx, gy = np.meshgrid(xn.astype(np.float64), yn.astype(np.float64))
    xs, ys = gx.ravel(), gy.ravel()
    n_big = int(big.window[0] * big.window[1])
    n_small = int(small.window[0] * small.window[1]) if small is not None else n_big
    plan = _film_plan(len(xs), n_big, n_small, big.settings.spp)
    out, render_s = render_pixel_list([big if size == n_big else small for size in plan], xs, ys, seed, which)
    return out.reshape(len(yn), len(xn)), render_s


def _posed_rigs(camera, shading, size_m: float, target: str, pose, irradiance_w_m2: float, light_position_m,
                park: bool) -> tuple:
    """The (big, small) pixel-list rigs of the board alone (``park``) or of the target's material, posed."""
    from edgetruth.render.scene.edge_band import ANALYTIC_TILE_PX, _park_active, tile_rig

    rigs = (tile_rig(camera, shading, size_m, ANALYTIC_TILE_PX), tile_rig(camera, shading, size_m, SMALL_FILM_PX))
    for rig in rigs:
        rig.set_state(target, pose, irradiance_w_m2, light_position_m)
        if park:
            _park_active(rig, target)
    return rigs


def inside_mask(outline_px: np.ndarray, x0: int, y0: int, w: int, h: int) -> np.ndarray:
    """(h, w) bool: pixel centres (x0 + c, y0 + r) inside the closed polyline ``outline_px`` (N, 2), by
    rasterisation -- exact except within ~1 px of the outline, where the band's own coverage replaces it."""
    import cv2

    mask = np.zeros((h, w), np.uint8)
    shift = 8
    pts = np.round((np.asarray(outline_px, np.float64) - (x0, y0)) * (1 << shift)).astype(np.int32)
    cv2.fillPoly(mask, [pts.reshape(-1, 1, 2)], 1, lineType=cv2.LINE_8, shift=shift)
    return mask.astype(bool)


def render_shading_frame(camera, settings, target: str, pose, size_m: float, outline_px: np.ndarray,
                         band_px: float, frame: tuple[int, int, int, int], seed: int, irradiance_w_m2: float,
                         light_position_m=None) -> tuple[np.ndarray, dict]:
    """The radiance (h, w) float32 of ``frame`` = (x0, y0, w, h) as S_out (1 − c) + S_in c over every pixel;
    returns it and {render_s, coverage_s, pixels (fractional c), nodes_out, nodes_in, tiles}."""
    import time

    from edgetruth.render.scene.edge_band import ANALYTIC_TILE_PX, BIG_TARGET_M, band_coverage, band_tiles

    fx0, fy0, fw, fh = (int(v) for v in frame)
    step = int(getattr(settings, "shading_step_px", SHADING_STEP_PX))
    shading = replace(settings, spp=settings.edge_spp)
    xn_all, yn_all = axis_nodes(camera.width_px, step), axis_nodes(camera.height_px, step)
    cols, rows = np.arange(fx0, fx0 + fw), np.arange(fy0, fy0 + fh)
    sx, sy = nodes_for(xn_all, fx0, fx0 + fw), nodes_for(yn_all, fy0, fy0 + fh)
    xn, yn = xn_all[sx], yn_all[sy]

    out_rigs = _posed_rigs(camera, shading, size_m, target, pose, irradiance_w_m2, light_position_m, park=True)
    s_out, render_s = _render_grid(out_rigs, xn, yn, seed, "frame-out")
    radiance = interpolate(s_out, yn, xn, rows, cols)

    # the target's box in the frame: its outline and the kernel's reach around it
    t0 = time.perf_counter()
    tiles = band_tiles([outline_px], frame, band_px, ANALYTIC_TILE_PX)
    lo = np.floor(np.asarray(outline_px).min(0) - band_px - 1).astype(int)
    hi = np.ceil(np.asarray(outline_px).max(0) + band_px + 2).astype(int)
    bx0, by0 = max(lo[0], fx0), max(lo[1], fy0)
    bx1, by1 = min(hi[0], fx0 + fw), min(hi[1], fy0 + fh)
    n_frac, n_in = 0, 0
    if bx1 > bx0 and by1 > by0:
        c = inside_mask(outline_px, bx0, by0, bx1 - bx0, by1 - by0).astype(np.float64)
        rr, cc, cv = band_coverage(camera, target, pose, size_m, frame, tiles, ANALYTIC_TILE_PX)
        rr, cc = rr + fy0 - by0, cc + fx0 - bx0  # frame-relative -> box-relative
        ok = (rr >= 0) & (rr < by1 - by0) & (cc >= 0) & (cc < bx1 - bx0)
        c[rr[ok], cc[ok]] = cv[ok]
        n_frac = int(np.count_nonzero((cv > 0.0) & (cv < 1.0)))
        coverage_s = time.perf_counter() - t0
        if np.any(c > 0.0):
            in_rigs = _posed_rigs(camera, shading, BIG_TARGET_M, target, pose, irradiance_w_m2, light_position_m,
                                  park=False)
            ix, iy = nodes_for(xn_all, bx0, bx1), nodes_for(yn_all, by0, by1)
            s_in, t_in = _render_grid(in_rigs, xn_all[ix], yn_all[iy], seed, "frame-in")
            render_s += t_in
            n_in = s_in.size
            s_in_px = interpolate(s_in, yn_all[iy], xn_all[ix], np.arange(by0, by1), np.arange(bx0, bx1))
            box = radiance[by0 - fy0:by1 - fy0, bx0 - fx0:bx1 - fx0]
            box *= 1.0 - c
            box += s_in_px * c
    else:
        coverage_s = time.perf_counter() - t0
    return radiance.astype(np.float32), {"render_s": render_s, "coverage_s": coverage_s, "pixels": n_frac,
                                         "nodes_out": int(s_out.size), "nodes_in": int(n_in), "tiles": len(tiles)}


def render_target_frame(camera, settings, job, pose, gt: dict, crop, irradiance_w_m2: float) -> tuple[np.ndarray, dict]:
    """A target job's radiance (the frame or ``crop``) in ``edge_mode = "frame"``, and the JSON's
    ``edge_band`` block plus ``render_s`` (its renders and coverage)."""
    from edgetruth.render.scene.edge_band import ANALYTIC_TILE_PX, band_width_px

    if not settings.edge_spp:
        settings = replace(settings, edge_spp=settings.spp)
    width = band_width_px(camera, gt["defocus_radius_px"])
    frame = tuple(crop) if crop else (0, 0, camera.width_px, camera.height_px)
    outline = np.asarray(gt["outline"]["polyline_distorted_px"], np.float64)
    radiance, res = render_shading_frame(camera, settings, job.target, pose, float(gt["target"]["size_m"]), outline,
                                         width, frame, job.render_seed, irradiance_w_m2,
                                         getattr(job, "light_position_m", None))
    step = int(getattr(settings, "shading_step_px", SHADING_STEP_PX))
    return radiance, {
        "mode": "frame", "render_s": res["render_s"] + res["coverage_s"], "spp": settings.edge_spp,
        "shading_step_px": step, "band_px": width, "tile_px": ANALYTIC_TILE_PX, "tiles": res["tiles"],
        "pixels": res["pixels"], "fractional_pixels": res["pixels"],
        "shading_nodes": {"out": res["nodes_out"], "in": res["nodes_in"]},
        "meaning": "every pixel is S_out (1 - c) + S_in c: S_out the board alone and S_in the target's material "
                   "alone, rendered at spp on every shading_step_px-th pixel (and the last row and column) and "
                   "interpolated by 4-point Lagrange cubics; c the exact lens-weighted coverage of the target "
                   "(edgetruth.render.scene.edge_coverage) on the tiles within band_px of the outline, 1 inside "
                   "and 0 outside beyond them; no full-frame render"}
