"""Rendering benchmark: images/s per working variant and the wall-time / ``mi.render`` ratio.

``run_bench()`` renders the ``quick`` spec on the best variant into a temporary
directory (wall time includes pose, ground truth, sensor model, EXR/PNG/JSON writes
and hashing; the ratio shows how much of it is spent outside ``mi.render``), then
a small window on every other working variant for a per-variant throughput figure.

Then the dataset-scale figures: the fixed cost of a tiny image (40x32 px, 1 spp, one
worker) at 500 and 3,000 images with its breakdown per stage (``patch_cost``), and a
1,000,000-image spec started in a subprocess (``million_image_run``): seconds until
its first image is recorded and the driver's memory after 200 and 2,000 images.
"""
from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path

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
    lines += patch_cost_lines()
    lines += million_image_lines()
    return lines


# --- dataset scale ------------------------------------------------------------------------
PATCH_COUNTS = (500, 3000)
STAGES = ("scene_sensor_truth", "mi_render", "exr", "png", "json", "sha256", "write")


def _scratch_dir() -> Path:
    """Datasets are written under ./runs; a bench measures there too (file creation under /tmp can
    cost 10x more on a busy shared disk)."""
    from edgetruth.resources import default_runs_dir

    d = default_runs_dir()
    d.mkdir(parents=True, exist_ok=True)
    return d


def patch_cost(n_images: int, tmp: Path) -> dict:
    """Render an ``n_images`` spec of tiny patches (40x32 px, 1 spp) in this process (one worker);
    returns ms per image (wall, everything from the call to the compacted manifest) and per stage."""
    from edgetruth.render.driver import render_spec
    from edgetruth.render.testing import write_patch_spec

    spec = write_patch_spec(tmp, n_images, name=f"patches{n_images}")
    t: dict = {}
    t0 = time.perf_counter()
    render_spec(spec, tmp / spec.stem, progress=False, timings=t, announce=lambda s: None)
    wall = time.perf_counter() - t0
    n = t["n_rendered"]
    out = {"ms_per_image": 1e3 * wall / n, "n": n}
    out.update({k: 1e3 * t["stage_s"].get(k, 0.0) / n for k in STAGES})
    out["journal"] = 1e3 * t["journal_s"] / n
    out["resume_check_ms"], out["compact_ms"] = 1e3 * t["resume_check_s"], 1e3 * t["compact_s"]
    out["driver_other"] = out["ms_per_image"] - sum(out[k] for k in (*STAGES, "journal"))
    return out


def patch_cost_lines(counts=PATCH_COUNTS) -> list[str]:
    from edgetruth.render.variants import choose_variant

    choose_variant(announce=lambda s: None)  # the variant probe is not part of an image's cost
    with tempfile.TemporaryDirectory(prefix="bench-patches-", dir=_scratch_dir()) as tmp:
        patch_cost(20, Path(tmp))  # scene loading and kernel compilation, once per process
        res = {n: patch_cost(n, Path(tmp)) for n in counts}
    a, b = (res[n] for n in counts)
    lines = [f"dataset bench: tiny images (40x32 px, 1 spp, one worker): {a['ms_per_image']:.2f} ms/image at "
             f"{counts[0]:,}, {b['ms_per_image']:.2f} ms/image at {counts[1]:,} (x{b['ms_per_image'] / a['ms_per_image']:.2f}; "
             "targets <= 12 ms on an idle machine, <= x1.25)"]
    for n, r in res.items():
        parts = ", ".join(f"{k} {r[k]:.2f}" for k in (*STAGES, "journal", "driver_other"))
        lines.append(f"dataset bench:   ms/image at {n:,}: {parts}; resume check {r['resume_check_ms']:.0f} ms, "
                     f"compaction {r['compact_ms']:.0f} ms")
    return lines


def _rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def _journal_lines(path: Path) -> int:
    try:
        return max(0, path.read_bytes().count(b"\n") - 1)  # minus the header line
    except OSError:
        return 0


def million_image_run(tmp: Path, n_images: int = 1_000_000, workers: int = 1, checkpoints=(200, 2000),
                      timeout_s: float = 600.0) -> dict:
    """``edgetruth render`` of an ``n_images`` patch spec in a subprocess, killed after the last
    checkpoint: {"first_image_s": seconds from the start to the first recorded image,
    "rss_mb": {checkpoint: driver RSS (MB) when the journal first holds that many images},
    "images_per_s": between the first and the last checkpoint}.  Linux (/proc)."""
    from edgetruth.render.testing import write_patch_spec

    spec = write_patch_spec(tmp, n_images, name=f"million{workers}")
    out = tmp / spec.stem
    journal = out / "journal.jsonl"
    cmd = [sys.executable, "-m", "edgetruth", "render", str(spec), "-o", str(out), "--no-progress",
           "--workers", str(workers)]
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    res: dict = {"rss_mb": {}, "first_image_s": None}
    when: dict = {}
    try:
        pending = sorted(checkpoints)
        while pending:
            if proc.poll() is not None:
                raise RuntimeError(f"render exited early ({proc.returncode}): {proc.stderr.read().decode()[-400:]}")
            if time.perf_counter() - t0 > timeout_s:
                raise TimeoutError(f"{n_images:,}-image render: checkpoints {pending} not reached in {timeout_s:.0f} s")
            n = _journal_lines(journal)
            if n and res["first_image_s"] is None:
                res["first_image_s"] = time.perf_counter() - t0
            while pending and n >= pending[0]:
                res["rss_mb"][pending[0]] = _rss_mb(proc.pid)
                when[pending.pop(0)] = time.perf_counter()
            time.sleep(0.01)
    finally:
        proc.kill()
        proc.wait()
        proc.stderr.close()
    lo, hi = min(checkpoints), max(checkpoints)
    res["images_per_s"] = (hi - lo) / (when[hi] - when[lo])
    return res


def million_image_lines(workers_list=(1, 2)) -> list[str]:
    lines = []
    with tempfile.TemporaryDirectory(prefix="bench-million-", dir=_scratch_dir()) as tmp:
        for w in workers_list:
            r = million_image_run(Path(tmp), workers=w)
            a, b = r["rss_mb"][200], r["rss_mb"][2000]
            lines.append(f"dataset bench: 1,000,000-image spec, --workers {w}: first image recorded after "
                         f"{r['first_image_s']:.1f} s (target < 10 s); driver RSS {a:.0f} MB after 200 images, "
                         f"{b:.0f} MB after 2,000 ({100 * (b - a) / a:+.1f} %, target within 10 %); "
                         f"{r['images_per_s']:.0f} images/s")
    return lines


def _pixels(spec) -> int:
    return spec.camera.width_px * spec.camera.height_px


def spec_camera_desc(spec) -> str:
    return f"{spec.camera.width_px}x{spec.camera.height_px}, {spec.render.spp} spp"


if __name__ == "__main__":  # pragma: no cover
    for line in run_bench():
        print(line)
