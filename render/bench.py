"""Rendering benchmark: images/s per working variant and the wall-time / ``mi.render`` ratio.

``run_bench()`` renders the ``quick`` spec on the best variant into a temporary
directory (wall time includes pose, ground truth, sensor model, EXR/PNG/JSON writes
and hashing; the ratio shows how much of it is spent outside ``mi.render``), then
a small window on every other working variant for a per-variant throughput figure.
"""
from __future__ import annotations

import tempfile
import time

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


def run_bench(spec_name: str = "quick") -> list[str]:
    """Printable lines: quick-spec images/s and wall/render ratio on the best variant; per-variant throughput."""
    from edgetruth.render.driver import render_spec
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
    return f"{spec.camera.width_px}x{spec.camera.height_px}, {spec.render.spp} spp"


if __name__ == "__main__":  # pragma: no cover
    for line in run_bench():
        print(line)
