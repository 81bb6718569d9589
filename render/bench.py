"""Rendering benchmark: images/s per working variant, the wall-time / ``mi.render`` ratio and the
cost of the lens PSF.

``run_bench()`` renders the ``quick`` spec on the best variant into a temporary
directory (wall time includes pose, ground truth, sensor model, EXR/PNG/JSON writes
and hashing; the ratio shows how much of it is spent outside ``mi.render``), then
one full-resolution target image of the default camera with and without its PSF (the frame at
``spp`` and the edge band at ``edge_spp``, medians of 3), then a small window on every other
working variant for a per-variant throughput figure.
"""
from __future__ import annotations

import tempfile
import time

from edgetruth.render.edge_band import TILE_PX

BENCH_WINDOW = (96, 80)  # px; the other variants (scalar: one Python call per sample) render only this


def _window_throughput(variant: str, spec) -> tuple[float, float]:
    """(seconds per window, samples per second) for one target image window on ``variant``."""
    from edgetruth.render.dataset import get_rig, job_pose
    from edgetruth.render.ground_truth import target_outline_local
    from edgetruth.render.variants import choose_variant

    choose_variant(variant, announce=lambda s: None)
    job = next(j for j in spec.jobs if j.kind == "target")
    camera, settings = job.camera, spec.render
    pose = job_pose(job, camera, target_outline_local("square", spec.target_size_m))
    w, h = BENCH_WINDOW
    crop = ((camera.width_px - w) // 2, (camera.height_px - h) // 2, w, h)
    rig = get_rig("target", camera, settings, spec.target_size_m, crop)
    rig.set_state(job.target, pose, job.irradiance_w_m2)
    rig.render(1)  # warm-up (JIT compilation)
    t0 = time.perf_counter()
    rig.render(2)
    dt = time.perf_counter() - t0
    return dt, w * h * settings.spp / dt


def _median_s(fn, repeats: int = 3) -> float:
    times = []
    for k in range(repeats):
        t0 = time.perf_counter()
        fn(k)
        times.append(time.perf_counter() - t0)
    return sorted(times)[len(times) // 2]


def psf_cost_lines(distance_m: float = 1.0) -> list[str]:
    """Seconds for one full-resolution T1 image of the default camera with and without its PSF."""
    from dataclasses import replace

    from edgetruth.render.camera import load_camera
    from edgetruth.render.edge_band import band_tiles, band_width_px, render_band, tile_rig
    from edgetruth.render.mitsuba_scene import TargetRig
    from edgetruth.render.outline import OutlineCurve
    from edgetruth.render.pose import Pose
    from edgetruth.render.spec import load_spec

    settings = load_spec("study").render  # the shipped full-resolution settings
    pose = Pose(distance_m, 0.02, -0.01, 2.0, -1.5)
    out, cost = [], {}
    for label, cam in (("with PSF", load_camera()), ("without PSF", load_camera().ideal_optics())):
        rig = TargetRig(cam, replace(settings, edge_spp=0))
        rig.set_state("T1", pose, 1.2)
        rig.render(0)  # JIT warm-up
        frame_s = _median_s(lambda k: rig.render(k + 1))
        poly = OutlineCurve(cam, pose, "square", 0.13).polyline()
        width = band_width_px(cam, float(cam.defocus_radius_px(distance_m)))
        tiles = band_tiles([poly], (0, 0, cam.width_px, cam.height_px), width)
        trig = tile_rig(cam, replace(settings, spp=settings.edge_spp), 0.13)
        trig.set_state("T1", pose, 1.2)
        img = rig.render(9)
        render_band(img, (0, 0), trig, tiles[:1], 0)  # warm-up
        band_s = _median_s(lambda k: render_band(img, (0, 0), trig, tiles, k))
        cost[label] = frame_s + band_s
        out.append(f"render bench: {cam.width_px}x{cam.height_px} T1 at {distance_m} m {label}: frame "
                   f"({settings.spp} spp {settings.sampler}) {frame_s:.2f} s + edge band ({len(tiles)} tiles of "
                   f"{TILE_PX}x{TILE_PX}, {settings.edge_spp} spp, band {width:.1f} px) {band_s:.2f} s = "
                   f"{frame_s + band_s:.2f} s")
    out.append(f"render bench: PSF cost: {cost['with PSF'] / cost['without PSF']:.2f} x the render without it")
    return out


def run_bench(spec_name: str = "quick") -> list[str]:
    """Printable lines: quick-spec images/s and wall/render ratio on the best variant; per-variant throughput."""
    from edgetruth.render.dataset import render_spec
    from edgetruth.render.spec import load_spec
    from edgetruth.render.variants import ORDER, choose_variant, probe

    spec = load_spec(spec_name)
    lines: list[str] = []
    chosen: list[str] = []
    best = choose_variant(announce=chosen.append)
    lines += chosen
    with tempfile.TemporaryDirectory(prefix="edgetruth-bench-") as tmp:
        timings: dict = {}
        t0 = time.perf_counter()
        render_spec(spec, tmp, variant=best, progress=False, timings=timings, announce=lambda s: None)
        total = time.perf_counter() - t0
    n = timings.get("n_rendered", 0)
    wall, inside = timings.get("wall_s", total), timings.get("render_s", float("nan"))
    cam = spec_camera_desc(spec)
    lines.append(f"render bench: spec {spec.name!r} ({n} images, {cam}) on {best}: {wall:.1f} s, "
                 f"{n / wall:.2f} images/s")
    lines.append(f"render bench: wall time / time inside mi.render = {wall / inside:.3f} (target <= 1.10); "
                 f"incl. scene loading and JIT warm-up: {total / inside:.3f}")
    lines += psf_cost_lines()
    for v in ORDER:
        ok, reason = probe(v)
        if not ok:
            lines.append(f"render bench: {v}: unavailable ({reason})")
            continue
        dt, sps = _window_throughput(v, spec)
        full_s = dt * (_pixels(spec) / (BENCH_WINDOW[0] * BENCH_WINDOW[1]))
        lines.append(f"render bench: {v}: {sps / 1e6:.2f} M samples/s on a {BENCH_WINDOW[0]}x{BENCH_WINDOW[1]} window "
                     f"-> ~{1.0 / full_s:.3f} images/s at {cam}")
    choose_variant(best, announce=lambda s: None)
    return lines


def _pixels(spec) -> int:
    return spec.camera.width_px * spec.camera.height_px


def spec_camera_desc(spec) -> str:
    r = spec.render
    return f"{spec.camera.width_px}x{spec.camera.height_px}, {r.spp} spp (edge band {r.edge_spp}) {r.sampler}"


if __name__ == "__main__":  # pragma: no cover
    for line in run_bench():
        print(line)
