"""The edge band: the pixels near a target's outline, rendered again at ``edge_spp``.

Monte-Carlo noise lives at edges: on the flat board the direct integrator's light sample is
almost deterministic (< 0.1 e⁻ at 49 spp), but a pixel whose kernel (pixel ⊗ PSF ⊗ defocus
disk ⊗ motion path) an edge crosses averages a step, and its error falls only like
spp^-0.5 ... spp^-0.75.  So the whole frame renders at ``spp`` and the tiles of ``TILE_PX`` x
``TILE_PX`` pixels that come within ``band_px`` -- the kernel's reach -- of the outline (at any
time of the exposure) render again at ``edge_spp`` and replace those pixels.  Outside the band
no sample can cross an edge: those pixels carry only the light sample's noise.

A tile is a small film whose place in the frame the sensor plugin moves (``set_window``), so
one compiled kernel serves every tile; each tile has its own seed (a hash of the image seed and
the tile's position), so the image is still a pure function of the job.

``edge_mode = "analytic"`` (``render_analytic_band``) computes the exact lens-weighted coverage c of
the target (``edgetruth.render.scene.edge_coverage``) on the band's tiles (``ANALYTIC_TILE_PX`` wide)
and renders only the pixels whose kernel meets the outline (0 < c < 1) again, twice and without any
edge, at ``edge_spp``: the board with the target parked (S_out) and the target's material over the
whole band (the active target scaled up about its centre to ``BIG_TARGET_M``: S_in); each becomes
S_out (1 − c) + S_in c.  No sample crosses an edge, so those pixels carry only the smooth shading's
Monte-Carlo noise; a pixel with c = 0 or 1 keeps the frame's value, whose kernel no edge reaches
either.  The pixels render as lists (``set_pixels``: film pixel k images the k-th listed pixel), a
film of ``ANALYTIC_TILE_PX``² pixels per render: 2-5x fewer samples than whole tiles, whose pixels
beyond the kernel's reach need none.  "path" (the default) is the reference.
"""
from __future__ import annotations

import collections
import functools
import hashlib
import math
from dataclasses import replace

import numpy as np

TILE_PX = 16
EDGE_MODES = ("path", "analytic", "frame")  # frame: edgetruth.render.scene.shading_frame
#: the analytic band's tiles: its renders are cheap (a few spp, no edge), so bigger windows -- fewer
#: render calls, whose fixed cost (~40 ms each on 2 cores) dominates at 16 x 16
ANALYTIC_TILE_PX = 64
#: S_in's target side (or diameter): the active target scaled up until it covers the board's extent
BIG_TARGET_M = 4.0
_rigs: dict = {}


@functools.lru_cache(maxsize=64)
def _kernel_reach_px(params) -> float:
    from edgetruth.render.optics.psf import psf_table

    table = psf_table(params)
    return math.sqrt(0.5) if table is None else table.half_width_px + table.step_px


def band_width_px(camera, defocus_px: float, motion_px: float = 0.0) -> float:
    """Half-width of the band around the outline: the sampled kernel's reach (pixel ⊗ PSF, the
    table's half-width; the pixel box alone without a PSF), plus the defocus disk and the motion
    path, plus 1 px."""
    from edgetruth.render.optics.psf import psf_params

    return _kernel_reach_px(psf_params(camera)) + float(defocus_px) + float(motion_px) + 1.0


def tile_seed(seed: int, x0: int, y0: int) -> int:
    digest = hashlib.sha256(f"edgetruth/edge-band/{int(seed)}/{int(x0)}/{int(y0)}".encode()).digest()
    return int.from_bytes(digest[:4], "little") & 0x7FFFFFFF


def band_tiles(outlines: list[np.ndarray], frame: tuple[int, int, int, int], band_px: float,
               tile_px: int = TILE_PX) -> list[tuple[int, int]]:
    """Top-left pixels of the frame-aligned tiles that come within ``band_px`` of any polyline in
    ``outlines`` ((N, 2) px, closed) and overlap ``frame`` = (x0, y0, width, height)."""
    from scipy.spatial import cKDTree

    fx0, fy0, fw, fh = frame
    pts = np.concatenate([np.asarray(o, float) for o in outlines])
    lo = np.floor((pts.min(0) - band_px - tile_px) / tile_px).astype(int)
    hi = np.ceil((pts.max(0) + band_px) / tile_px).astype(int)
    gx, gy = np.meshgrid(np.arange(lo[0], hi[0] + 1) * tile_px, np.arange(lo[1], hi[1] + 1) * tile_px)
    corners = np.column_stack([gx.ravel(), gy.ravel()])
    centres = corners + 0.5 * (tile_px - 1)
    # polyline spacing <= 2 px: the nearest vertex is within 1 px of the nearest curve point
    dist, _ = cKDTree(pts).query(centres)
    near = dist <= band_px + tile_px * math.sqrt(0.5) + 1.0
    inside = ((corners[:, 0] + tile_px > fx0) & (corners[:, 0] < fx0 + fw)
              & (corners[:, 1] + tile_px > fy0) & (corners[:, 1] < fy0 + fh))
    return [(int(x), int(y)) for x, y in corners[near & inside]]


def tile_rig(camera, settings, target_size_m: float, tile_px: int = TILE_PX):
    """The process-wide window rig for the band (loaded once, re-posed per image)."""
    import mitsuba as mi

    from edgetruth.render.scene.mitsuba_scene import TargetRig

    key = (mi.variant(), camera, settings, target_size_m, tile_px)
    if key not in _rigs:
        _rigs[key] = TargetRig(camera, settings, target_size_m, window=(tile_px, tile_px))
    return _rigs[key]


def render_band(radiance: np.ndarray, frame_origin: tuple[int, int], rig, tiles: list[tuple[int, int]],
                seed: int) -> tuple[int, float]:
    """Render ``tiles`` with ``rig`` (a posed window rig) and paste them into ``radiance`` (whose pixel
    (0, 0) is frame pixel ``frame_origin``).  Returns (pixels replaced, seconds inside the renders)."""
    import time

    t = rig.window[0]
    h, w = radiance.shape
    ox, oy = frame_origin
    n, render_s = 0, 0.0
    for x0, y0 in tiles:
        t0 = time.perf_counter()
        tile = rig.render(tile_seed(seed, x0, y0), window_at=(x0, y0))
        render_s += time.perf_counter() - t0
        xa, ya = max(x0, ox), max(y0, oy)
        xb, yb = min(x0 + t, ox + w), min(y0 + t, oy + h)
        if xb <= xa or yb <= ya:
            continue
        radiance[ya - oy:yb - oy, xa - ox:xb - ox] = tile[ya - y0:yb - y0, xa - x0:xb - x0]
        n += (xb - xa) * (yb - ya)
    return n, render_s


def pixel_chunk_seed(seed: int, k: int, which: str) -> int:
    """The seed of the k-th film of an analytic band's pixel list (``which``: "in" or "out")."""
    digest = hashlib.sha256(f"edgetruth/edge-band/{which}/pixels/{int(seed)}/{int(k)}".encode()).digest()
    return int.from_bytes(digest[:4], "little") & 0x7FFFFFFF


def render_pixel_list(rigs, xs: np.ndarray, ys: np.ndarray, seed: int, which: str) -> tuple[np.ndarray, float]:
    """Frame pixels (xs, ys) rendered film by film: film k by ``rigs[k]`` (a window rig in pixel-list mode),
    holding the next ``width x height`` listed pixels (the last film padded with its own last pixel), with
    seed ``pixel_chunk_seed(seed, k, which)``; (values, seconds in renders)."""
    import time

    out = np.empty(len(xs), np.float64)
    render_s, a = 0.0, 0
    for k, rig in enumerate(rigs):
        size = int(rig.window[0] * rig.window[1])
        px, py = xs[a:a + size], ys[a:a + size]
        m = len(px)
        if m < size:
            px = np.concatenate([px, np.full(size - m, px[-1])])
            py = np.concatenate([py, np.full(size - m, py[-1])])
        t0 = time.perf_counter()
        film = rig.render(pixel_chunk_seed(seed, k, which), pixels=(px, py))
        render_s += time.perf_counter() - t0
        out[a:a + m] = film.ravel()[:m]
        a += m
    return out, render_s


def _render_pixels(rig, xs: np.ndarray, ys: np.ndarray, seed: int, which: str) -> tuple[np.ndarray, float]:
    """Frame pixels (xs, ys) rendered with ``rig``, one film per ``width x height`` of them."""
    n_film = int(rig.window[0] * rig.window[1])
    return render_pixel_list([rig] * -(-len(xs) // n_film), xs, ys, seed, which)


def _park_active(rig, target: str) -> None:
    """Move the active target of a posed preset rig out of sight (the board alone)."""
    from edgetruth.render.scene.mitsuba_scene import _PARKED, _SHAPE_KEY

    rig._set_transform(f"{_SHAPE_KEY[target]}.to_world", _PARKED)
    rig.params.update()


#: the last few ``band_coverage`` results of this process, by their inputs (the outline's shape, not the target's
#: material): the cells of a paired design slot whose targets share a shape (T1, T3 and T4 are the same square at
#: the same pose) compute the coverage once.  The same inputs give the same bits, so a hit changes nothing.
_COVERAGE_CACHE: collections.OrderedDict = collections.OrderedDict()
COVERAGE_CACHE_SIZE = 4


def band_coverage(camera, target: str, pose, size_m: float, frame: tuple[int, int, int, int], tiles,
                  tile_px: int = TILE_PX) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(rows, cols, c): every pixel of ``tiles`` within ``frame`` = (x0, y0, width, height), frame-relative,
    and the exact lens-weighted coverage c of preset target ``target`` there (read-only arrays: the last
    ``COVERAGE_CACHE_SIZE`` results are kept for the next image of the same outline)."""
    from edgetruth.render.scene.targets import TARGETS

    if not isinstance(target, str) or target not in TARGETS:
        raise ValueError(f"edge_mode = 'analytic' covers the preset targets {', '.join(TARGETS)}; "
                         f"got {target!r}: use edge_mode = 'path'")
    if camera.moving:
        raise ValueError("edge_mode = 'analytic' needs a static camera (a moving outline sweeps); use 'path'")
    key = (camera, TARGETS[target]["shape"], pose, float(size_m), tuple(int(v) for v in frame),
           tuple((int(x), int(y)) for x, y in tiles), int(tile_px))
    hit = _COVERAGE_CACHE.get(key)
    if hit is None:
        hit = _band_coverage(camera, target, pose, size_m, frame, tiles, tile_px)
        for a in hit:
            a.setflags(write=False)
        _COVERAGE_CACHE[key] = hit
        while len(_COVERAGE_CACHE) > COVERAGE_CACHE_SIZE:
            _COVERAGE_CACHE.popitem(last=False)
    else:
        _COVERAGE_CACHE.move_to_end(key)
    return hit


def _band_coverage(camera, target: str, pose, size_m: float, frame: tuple[int, int, int, int], tiles,
                   tile_px: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    from edgetruth.render.scene.edge_coverage import outline_curve, pixel_coverage

    fx0, fy0, fw, fh = frame
    inside = np.zeros((fh, fw), bool)
    for x0, y0 in tiles:
        inside[max(y0 - fy0, 0):max(y0 + tile_px - fy0, 0), max(x0 - fx0, 0):max(x0 + tile_px - fx0, 0)] = True
    rr, cc = np.nonzero(inside)
    c = pixel_coverage(camera, outline_curve(camera, pose, target, size_m), (cc + fx0).astype(float),
                       (rr + fy0).astype(float))
    return rr, cc, c


def render_analytic_band(radiance: np.ndarray, frame: tuple[int, int, int, int], camera, settings, target: str,
                         pose, size_m: float, tiles, seed: int, irradiance_w_m2: float,
                         light_position_m=None, tile_px: int = TILE_PX) -> dict:
    """Replace the pixels of ``tiles`` whose kernel meets the outline (0 < c < 1) in ``radiance`` (whose
    pixel (0, 0) is frame pixel ``frame[:2]``) by S_out (1 − c) + S_in c; returns {pixels (those
    replaced), render_s, coverage_s, fractional (the same count)}."""
    import time

    fx0, fy0 = frame[:2]
    t0 = time.perf_counter()
    rr, cc, c = band_coverage(camera, target, pose, size_m, frame, tiles, tile_px)
    coverage_s = time.perf_counter() - t0
    mixed = (c > 0.0) & (c < 1.0)  # the rest: no kernel sample meets the outline, the frame's value holds
    rr, cc, c = rr[mixed], cc[mixed], c[mixed]
    render_s = 0.0
    if len(rr):
        shading = replace(settings, spp=settings.edge_spp)
        out_rig = tile_rig(camera, shading, size_m, tile_px)
        out_rig.set_state(target, pose, irradiance_w_m2, light_position_m)
        _park_active(out_rig, target)
        xs, ys = (cc + fx0).astype(np.float64), (rr + fy0).astype(np.float64)
        s_out, t_out = _render_pixels(out_rig, xs, ys, seed, "out")
        in_rig = tile_rig(camera, shading, BIG_TARGET_M, tile_px)
        in_rig.set_state(target, pose, irradiance_w_m2, light_position_m)
        s_in, t_in = _render_pixels(in_rig, xs, ys, seed, "in")
        radiance[rr, cc] = (s_out * (1.0 - c) + s_in * c).astype(radiance.dtype)
        render_s = t_out + t_in
    return {"pixels": int(len(rr)), "render_s": render_s, "coverage_s": coverage_s, "fractional": int(len(rr))}


def scene_outlines(gt: dict) -> list[np.ndarray]:
    """Every outline of a scene's shapes and clutter items beyond shape 0's (``gt["outline"]``): their edges
    need the band as much (empty for a preset target)."""
    items = list(gt.get("shapes", ())) + list(gt.get("clutter", ()))
    return [np.asarray(o["polyline_distorted_px"], float) for item in items for o in item.get("outlines", ())
            if len(o.get("polyline_distorted_px", ())) >= 2]


def render_edge_band(radiance, camera, settings, job, pose, gt, crop, irradiance_w_m2) -> dict | None:
    """Re-render the pixels near the target's outline at ``settings.edge_spp`` (in place; the tiles'
    seeds come from ``job.render_seed``); returns the JSON's ``edge_band`` block plus ``render_s``
    (None, and nothing rendered, when ``edge_spp`` is 0)."""
    if settings.edge_spp <= 0:
        return None
    outlines = [np.asarray(gt["outline"]["polyline_distorted_px"])] + scene_outlines(gt)
    motion_px = 0.0
    if "motion" in gt:
        start, end = (np.asarray(gt["motion"][k]) for k in ("outline_start_distorted_px", "outline_end_distorted_px"))
        outlines += [start, end]
        motion_px = float(np.max(np.linalg.norm(end - start, axis=1)))
    width = band_width_px(camera, gt["defocus_radius_px"], motion_px)
    frame = tuple(crop) if crop else (0, 0, camera.width_px, camera.height_px)
    tiles = band_tiles(outlines, frame, width)
    mode = getattr(settings, "edge_mode", "path")
    if mode == "analytic":
        tiles = band_tiles(outlines, frame, width, ANALYTIC_TILE_PX)
        res = render_analytic_band(radiance, frame, camera, settings, job.target, pose, float(gt["target"]["size_m"]),
                                   tiles, job.render_seed, irradiance_w_m2, getattr(job, "light_position_m", None),
                                   ANALYTIC_TILE_PX)
        return {"mode": mode, "render_s": res["render_s"] + res["coverage_s"], "spp": settings.edge_spp,
                "band_px": width, "tile_px": ANALYTIC_TILE_PX, "tiles": len(tiles), "pixels": res["pixels"],
                "fractional_pixels": res["fractional"],
                "meaning": "the pixels of the tiles within band_px of the outline whose kernel meets it (0 < c < 1, "
                           "c the exact lens-weighted coverage of the target: edgetruth.render.scene.edge_coverage): "
                           "S_out (1 - c) + S_in c, S_out the board alone and S_in the target's material alone, "
                           "rendered at spp as pixel lists in films of tile_px x tile_px pixels with their own seeds; "
                           "the rest of the frame at render.spp"}
    trig = tile_rig(camera, replace(settings, spp=settings.edge_spp), float(gt["target"]["size_m"]))
    trig.set_state(job.target, pose, irradiance_w_m2, getattr(job, "light_position_m", None))
    n, render_s = render_band(radiance, frame[:2], trig, tiles, job.render_seed)
    return {"mode": mode, "render_s": render_s, "spp": settings.edge_spp, "band_px": width, "tile_px": TILE_PX,
            "tiles": len(tiles), "pixels": n, "meaning": "pixels within band_px of the outline (at any time of the exposure) rendered at spp, "
                       "in tiles with their own seeds; the rest of the frame at render.spp"}
