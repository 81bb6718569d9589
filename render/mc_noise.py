"""Monte-Carlo noise of a render, measured: two renders with different seeds, (a − b)/√2.

``edge_mc_noise`` renders a black matte square (T1) with the given camera and render settings
around its outline and reports the Monte-Carlo noise in electrons (default sensor) in bands of
distance from the true distorted outline, next to the sensor's own temporal noise there.  The
edge band (``edge_spp``) is rendered as ``render_job`` does, in either ``edge_mode`` ("path": the
band path-traced at ``edge_spp``; "analytic": the board and the target's material at ``edge_spp``,
composited with the exact coverage; "frame": that composite over the whole crop, the shading on a grid).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

BANDS_PX = ((0.0, 1.0), (1.0, 3.0), (3.0, 5.0), (5.0, 10.0), (10.0, 20.0), (20.0, 1e9))


def edge_mc_noise(camera, settings, distance_m: float, sensor=None, irradiance_w_m2: float = 1.2,
                  roll_deg: float = 7.0, seeds=(11, 12), window_px: int | None = None, at: float = 0.375,
                  counts: bool = False) -> dict:
    """{band: (MC noise e-, sensor temporal noise e-)} for |d| bands around a T1 square's outline.

    ``window_px``: only a ``window_px`` x ``window_px`` crop around the outline point at curve
    parameter ``at`` (0.375: the middle of a side; corners at 0, ¼, ½, ¾), on the band's tile grid,
    instead of the whole outline -- the same statistics on fewer pixels, at a fraction of the renders.
    ``counts``: each value gets the band's pixel count as a third entry (the estimate's own spread: an
    RMS over N pixels of Gaussian noise has relative standard error 1/√(2N))."""
    from edgetruth.render.scene.edge_band import (ANALYTIC_TILE_PX, band_tiles, band_width_px, render_analytic_band,
                                           render_band, tile_rig)
    from edgetruth.render.scene.mitsuba_scene import TargetRig
    from edgetruth.render.scene.outline import OutlineCurve
    from edgetruth.render.scene.pose import Pose
    from edgetruth.render.sensor.linear_model import SensorModel

    sensor = sensor or SensorModel()
    pose = Pose(distance_m, 0.02, -0.01, 2.0, -1.5, roll_deg=roll_deg)
    curve = OutlineCurve(camera, pose, "square", 0.13)
    poly = curve.polyline()
    if window_px:  # on the band's tile grid: the window's band is whole tiles (no tile renders for a sliver)
        from edgetruth.render.scene.edge_band import TILE_PX

        centre = curve.points(np.array([at]))[0]
        x0, y0 = (np.round((centre - 0.5 * window_px) / TILE_PX) * TILE_PX).astype(int)
        x1, y1 = x0 + window_px, y0 + window_px
    else:
        x0, y0 = (np.floor(poly.min(0)) - 24).astype(int)
        x1, y1 = (np.ceil(poly.max(0)) + 24).astype(int)
    crop = (int(x0), int(y0), int(x1 - x0), int(y1 - y0))
    frame_mode = getattr(settings, "edge_mode", "path") == "frame"
    if not frame_mode:
        base = TargetRig(camera, replace(settings, edge_spp=0), crop=crop)
        base.set_state("T1", pose, irradiance_w_m2)
    imgs = []
    for seed in seeds:
        if frame_mode:  # the whole crop is the composite (``edgetruth.render.scene.shading_frame``)
            from edgetruth.render.scene.shading_frame import render_shading_frame

            width = band_width_px(camera, float(camera.defocus_radius_px(distance_m)))
            img, _ = render_shading_frame(camera, settings, "T1", pose, 0.13, poly, width, crop, seed,
                                          irradiance_w_m2)
            imgs.append(img.astype(np.float64))
            continue
        img = base.render(seed).astype(np.float64)
        if settings.edge_spp:
            width = band_width_px(camera, float(camera.defocus_radius_px(distance_m)))
            tiles = band_tiles([poly], crop, width)
            if getattr(settings, "edge_mode", "path") == "analytic":
                render_analytic_band(img, crop, camera, settings, "T1", pose, 0.13,
                                     band_tiles([poly], crop, width, ANALYTIC_TILE_PX), seed, irradiance_w_m2,
                                     tile_px=ANALYTIC_TILE_PX)
            else:
                trig = tile_rig(camera, replace(settings, spp=settings.edge_spp), 0.13)
                trig.set_state("T1", pose, irradiance_w_m2)
                render_band(img, crop[:2], trig, tiles, seed)
        imgs.append(img)
    e_per_rad = sensor.qe * sensor.photons_per_radiance(camera.f_number, camera.pitch_um)
    diff = (imgs[0] - imgs[1]) / np.sqrt(2.0) * e_per_rad
    mean = 0.5 * (imgs[0] + imgs[1]) * e_per_rad
    temporal = np.sqrt(sensor.dark_noise_e ** 2 + mean)
    ys, xs = np.mgrid[y0:y1, x0:x1]
    d = np.abs(curve.signed_distance(xs.astype(float), ys.astype(float)))
    out = {}
    for lo, hi in BANDS_PX:
        m = (d >= lo) & (d < hi)
        out[(lo, hi)] = (float(np.sqrt(np.mean(diff[m] ** 2))), float(np.sqrt(np.mean(temporal[m] ** 2))))
        if counts:
            out[(lo, hi)] += (int(np.count_nonzero(m)),)
    return out


def convergence_table(distances_m=(1.0, 1.5), edge_spps=(256, 1024, 2304, 4096), camera=None, spp: int = 25,
                      sampler: str = "multijitter") -> list[str]:
    """Lines: MC noise per |d| band for each edge_spp (frame at ``spp``), and the spp extrapolated
    (power law through the two largest) to reach a quarter of the dark noise."""
    from edgetruth.render.optics.camera import load_camera
    from edgetruth.render.scene.mitsuba_scene import RenderSettings
    from edgetruth.render.sensor.linear_model import SensorModel

    camera = camera or load_camera()
    target = SensorModel().dark_noise_e / 4
    lines = []
    for z in distances_m:
        rows = {n: edge_mc_noise(camera, RenderSettings(spp=spp, edge_spp=n, sampler=sampler), z)
                for n in edge_spps}
        for n, r in rows.items():
            lines.append(f"{z} m edge_spp {n:5d}: " + "; ".join(f"|d| {lo:g}-{hi:g} px {mc:.1f} e-"
                                                              for (lo, hi), (mc, _) in r.items()))
        a, b = edge_spps[-2], edge_spps[-1]
        for band in BANDS_PX[:4]:
            ya, yb = rows[a][band][0], rows[b][band][0]
            slope = np.log(yb / ya) / np.log(b / a)
            need = b * (target / yb) ** (1.0 / slope) if slope < 0 and yb > target else b
            lines.append(f"{z} m |d| {band[0]:g}-{band[1]:g} px: noise ~ spp^{slope:.2f}; "
                         f"{target:.1f} e- (1/4 dark noise) needs ~{need:,.0f} spp")
    return lines


def band_cost(camera, distance_m: float, path_spp: int = 4096, analytic_spp: int = 64,
              irradiance_w_m2: float = 1.2, roll_deg: float = 7.0, seed: int = 11) -> dict:
    """Seconds to render the edge band of one T1 image (the ``edge_mc_noise`` pose, full frame), path-
    traced at ``path_spp`` and analytic at ``analytic_spp`` (each after a warm-up render of one tile):
    {"path_s", "analytic_render_s", "analytic_coverage_s", "tiles", "fractional_pixels"}."""
    import time

    from edgetruth.render.scene.edge_band import (ANALYTIC_TILE_PX, band_tiles, band_width_px, render_analytic_band,
                                           render_band, tile_rig)
    from edgetruth.render.scene.mitsuba_scene import RenderSettings
    from edgetruth.render.scene.outline import OutlineCurve
    from edgetruth.render.scene.pose import Pose

    pose = Pose(distance_m, 0.02, -0.01, 2.0, -1.5, roll_deg=roll_deg)
    poly = OutlineCurve(camera, pose, "square", 0.13).polyline()
    frame = (0, 0, camera.width_px, camera.height_px)
    width = band_width_px(camera, float(camera.defocus_radius_px(distance_m)))
    tiles = band_tiles([poly], frame, width)
    big = band_tiles([poly], frame, width, ANALYTIC_TILE_PX)
    img = np.zeros((camera.height_px, camera.width_px), np.float32)
    analytic = RenderSettings(spp=64, edge_spp=analytic_spp, edge_mode="analytic")
    render_analytic_band(img, frame, camera, analytic, "T1", pose, 0.13, big[:1], seed, irradiance_w_m2,
                         tile_px=ANALYTIC_TILE_PX)  # warm-up
    t0 = time.perf_counter()
    res = render_analytic_band(img, frame, camera, analytic, "T1", pose, 0.13, big, seed, irradiance_w_m2,
                               tile_px=ANALYTIC_TILE_PX)
    analytic_s = time.perf_counter() - t0
    trig = tile_rig(camera, RenderSettings(spp=path_spp, edge_spp=path_spp), 0.13)
    trig.set_state("T1", pose, irradiance_w_m2)
    render_band(img, (0, 0), trig, tiles[:1], seed)
    t0 = time.perf_counter()
    render_band(img, (0, 0), trig, tiles, seed)
    path_s = time.perf_counter() - t0
    return {"path_s": path_s, "analytic_s": analytic_s, "analytic_render_s": res["render_s"],
            "analytic_coverage_s": res["coverage_s"], "tiles": len(tiles), "analytic_tiles": len(big),
            "fractional_pixels": res["fractional"]}


def analytic_table(distances_m=(0.5, 1.5, 2.5), camera=None, spp: int = 64, edge_spps=(16, 64),
                   path_spp: int = 4096, path_noise: bool = True) -> list[str]:
    """Lines: MC noise per |d| band of the analytic band (shading at each of ``edge_spps``) and of the
    path-traced one at ``path_spp``, and the band's cost per image in both modes."""
    from edgetruth.render.optics.camera import load_camera
    from edgetruth.render.scene.edge_band import ANALYTIC_TILE_PX
    from edgetruth.render.scene.mitsuba_scene import RenderSettings

    camera = camera or load_camera()
    lines = []
    for z in distances_m:
        for mode, n in [("analytic", k) for k in edge_spps] + [("path", path_spp)] * path_noise:
            r = edge_mc_noise(camera, RenderSettings(spp=spp, edge_spp=n, edge_mode=mode), z)
            lines.append(f"{z} m {mode} edge_spp {n:5d}: " + "; ".join(
                f"|d| {lo:g}-{hi:g} px {mc:.2f} e- ({mc / tp:.3f} of temporal)" for (lo, hi), (mc, tp) in r.items()))
        c = band_cost(camera, z, path_spp=path_spp, analytic_spp=edge_spps[-1])
        lines.append(f"{z} m band cost: path {c['path_s']:.1f} s, analytic {c['analytic_s']:.1f} s (renders "
                     f"{c['analytic_render_s']:.1f} s, coverage {c['analytic_coverage_s']:.1f} s), {c['tiles']} tiles "
                     f"({c['analytic_tiles']} of {ANALYTIC_TILE_PX} px), "
                     f"{c['fractional_pixels']} fractional pixels")
    return lines


def frame_table(distances_m=(0.5, 1.5, 2.5), camera=None, edge_spps=(256, 1024), step_px: int = 16) -> list[str]:
    """Lines: MC noise per |d| band of ``edge_mode = "frame"`` (the shading grid at each of ``edge_spps``)."""
    from edgetruth.render.optics.camera import load_camera
    from edgetruth.render.scene.mitsuba_scene import RenderSettings

    camera = camera or load_camera()
    lines = []
    for z in distances_m:
        for n in edge_spps:
            r = edge_mc_noise(camera, RenderSettings(spp=64, edge_spp=n, edge_mode="frame", shading_step_px=step_px), z)
            lines.append(f"{z} m frame edge_spp {n:5d} step {step_px} px: " + "; ".join(
                f"|d| {lo:g}-{hi:g} px {mc:.2f} e- ({mc / tp:.3f} of temporal)" for (lo, hi), (mc, tp) in r.items()))
    return lines


if __name__ == "__main__":  # pragma: no cover
    import sys

    from edgetruth.render.variants import choose_variant

    choose_variant()
    lines = (analytic_table(path_noise="--no-path-noise" not in sys.argv) if "--analytic" in sys.argv
             else frame_table() if "--frame" in sys.argv else convergence_table())
    for line in lines:
        print(line, flush=True)
