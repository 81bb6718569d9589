"""Rendering benchmark: images/s per working variant, the wall-time / ``mi.render`` ratio and the
cost of the lens PSF.

``run_bench()`` renders the ``quick`` spec on the best variant into a temporary
directory (wall time includes pose, ground truth, sensor model, EXR/PNG/JSON writes
and hashing; the ratio shows how much of it is spent outside ``mi.render``), then
one full-resolution target image of the default camera with and without its PSF (the frame at
``spp`` and the edge band at ``edge_spp``, medians of 3), a board image path-traced and composited
(``board_mode = "frame"``: ``board_frame_lines``), a user's own spec rendered with the default mode and with
``edge_mode = "path"`` (``default_mode_lines``), then a small window on every other
working variant for a per-variant throughput figure.

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

from edgetruth.render.scene.edge_band import TILE_PX

BENCH_WINDOW = (96, 80)  # px; the other variants (scalar: one Python call per sample) render only this


def _window_throughput(variant: str, spec) -> tuple[float, float]:
    """(seconds per window, samples per second) for one target image window on ``variant``."""
    from edgetruth.render.dataset.image import get_rig, job_pose
    from edgetruth.render.scene.ground_truth import target_outline_local
    from edgetruth.render.variants import choose_variant

    choose_variant(variant, announce=lambda s: None)
    job = next(j for j in spec.jobs if j.kind == "target")
    camera, settings = job.camera, spec.render
    pose = job_pose(job, camera, target_outline_local("square", spec.target_size_m))
    w, h = BENCH_WINDOW
    crop = ((camera.width_px - w) // 2, (camera.height_px - h) // 2, w, h)
    rig = get_rig("target", camera, settings, spec.target_size_m, crop)
    rig.set_state(job.target, pose, job.irradiance_w_m2, job.light_position_m)
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

    from edgetruth.render.optics.camera import load_camera
    from edgetruth.render.scene.edge_band import band_tiles, band_width_px, render_band, tile_rig
    from edgetruth.render.scene.mitsuba_scene import TargetRig
    from edgetruth.render.scene.outline import OutlineCurve
    from edgetruth.render.scene.pose import Pose
    from edgetruth.render.dataset.spec import load_spec

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


def board_frame_lines(spec_name: str = "opencv_left_twin", images: int = 3) -> list[str]:
    """Seconds per board image, path-traced and composited (``board_mode = "frame"``), medians over the spec's first
    ``images`` images in one process after a warm-up of each, and the ratio."""
    from dataclasses import replace

    from edgetruth.render.dataset.image import render_job
    from edgetruth.render.dataset.spec import load_spec

    spec = load_spec(spec_name)
    n = min(images, spec.n_images)
    med = {}
    for mode in ("path", "frame"):
        s = replace(spec, render=replace(spec.render, board_mode=mode))
        render_job(s, s.jobs[0])  # warm-up: rigs, JIT and numba
        med[mode] = _median_s(lambda k: render_job(s, s.jobs[k % n]), repeats=n)
    cam = f"{spec.camera.width_px}x{spec.camera.height_px}"
    return [f"render bench: board image ({spec.name}, {cam}, {spec.render.spp} spp, median of {n}): path-traced "
            f"{med['path']:.2f} s, board_mode = \"frame\" {med['frame']:.2f} s: {med['path'] / med['frame']:.2f}x"]


#: the new user's spec of issue 49: 9 full-resolution T1 images at 0.5 / 1.5 / 2.5 m at the study's settings; no
#: edge_mode key (``{mode}`` adds one)
DEFAULT_MODE_SPEC = """[spec]
name = "own_t1"
camera = "default"
spp = 64
edge_spp = 4096
{mode}
""" + "".join(f"""
[[group]]
name = "z{cm}"
target = "T1"
distance_range_cm = [{cm}, {cm}]
count = 3
lateral_fraction = 0.3
tilt_max_deg = 3
""" for cm in (50, 150, 250))


def _render_cold(spec_path: Path, out: Path) -> tuple[float, float, dict]:
    """``edgetruth render SPEC`` in a fresh process (as a user runs it): (wall s, CPU s of the process and its
    workers, image 0's JSON)."""
    import json
    import os

    t0, c0 = time.perf_counter(), os.times()
    r = subprocess.run([sys.executable, "-m", "edgetruth", "render", str(spec_path), "-o", str(out), "--no-progress"],
                       capture_output=True, text=True)
    wall, c1 = time.perf_counter() - t0, os.times()
    if r.returncode != 0:
        raise RuntimeError(f"render {spec_path} exited {r.returncode}: {r.stderr[-800:]}")
    cpu = (c1.children_user - c0.children_user) + (c1.children_system - c0.children_system)
    first = sorted(out.glob("0000_*.json"))[0]
    return wall, cpu, json.loads(first.read_text())


def default_mode_lines(distances_m=(0.5, 1.5, 2.5), window_px: int = 96) -> list[str]:
    """The same user spec (``DEFAULT_MODE_SPEC``) rendered cold with no ``edge_mode`` key (the default: "frame")
    and with ``edge_mode = "path"``: seconds, the ratio, the mode each image's JSON names, and the Monte-Carlo
    noise of the pixels within 1 px of the outline (``edge_mc_noise``, two seeds, on a ``window_px`` crop across
    a side) per distance, against a quarter of the default sensor's dark noise."""
    from edgetruth.render.dataset.spec import load_spec
    from edgetruth.render.mc_noise import edge_mc_noise
    from edgetruth.render.sensor.linear_model import SensorModel
    from edgetruth.render.variants import choose_variant

    choose_variant(announce=lambda s: None)  # the noise renders run in this process
    res, lines = {}, []
    with tempfile.TemporaryDirectory(prefix="bench-default-mode-", dir=_scratch_dir()) as tmp:
        for label, mode in (("default", ""), ("path", 'edge_mode = "path"')):
            d = Path(tmp) / label
            d.mkdir()
            (d / "own_t1.toml").write_text(DEFAULT_MODE_SPEC.format(mode=mode))
            spec = load_spec(d / "own_t1.toml")
            wall, cpu, gt = _render_cold(d / "own_t1.toml", d / "out")
            named = gt["render"].get("edge_mode", "path"), (gt["render"]["edge_band"] or {}).get("mode")
            dark = SensorModel().dark_noise_e
            noise = [edge_mc_noise(spec.camera, spec.render, z, window_px=window_px)[(0.0, 1.0)][0] / dark
                     for z in distances_m]
            res[label] = wall
            lines.append(f"render bench: own spec, 9 T1 images at {'/'.join(f'{z:g}' for z in distances_m)} m "
                         f"(default camera, spp {spec.render.spp}, edge_spp {spec.render.edge_spp}), "
                         f"{'no edge_mode key' if label == 'default' else mode}: {wall:.1f} s wall ({cpu:.1f} s CPU), "
                         f"JSON render.edge_mode {named[0]!r}, edge_band.mode {named[1]!r}; edge-pixel (|d| < 1 px) "
                         f"MC noise / dark noise {', '.join(f'{v:.3f}' for v in noise)} (goal <= 0.25)")
    lines.append(f"render bench: own spec, default against edge_mode = \"path\": {res['path'] / res['default']:.2f}x "
                 "faster (goal >= 4.5x)")
    return lines

def run_bench(spec_name: str = "quick") -> list[str]:
    """Printable lines: quick-spec images/s and wall/render ratio on the best variant; per-variant
    throughput; the dataset-scale figures and the capacity plan computed from them."""
    from edgetruth.render.dataset.driver import render_spec
    from edgetruth.render.dataset.spec import load_spec
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
        frame_bytes = _image_bytes(Path(tmp)) / max(1, timings.get("n_rendered", 0))
    n = timings.get("n_rendered", 0)
    wall, inside = timings.get("wall_s", total), timings.get("render_s", float("nan"))
    cam = spec_camera_desc(spec)
    lines.append(f"render bench: spec {spec.name!r} ({n} images, {cam}) on {best}: {wall:.1f} s, "
                 f"{n / wall:.2f} images/s")
    lines.append(f"render bench: wall time / time inside mi.render = {wall / inside:.3f} (target <= 1.10); "
                 f"incl. scene loading and JIT warm-up: {total / inside:.3f}")
    lines += psf_cost_lines()
    lines += board_frame_lines()
    lines += default_mode_lines()
    rates = {}
    for v in ORDER:
        ok, reason = probe(v)
        if not ok:
            lines.append(f"render bench: {v}: unavailable ({reason})")
            continue
        dt, sps = _window_throughput(v, spec)
        rates[v] = sps
        full_s = dt * (_pixels(spec) / (BENCH_WINDOW[0] * BENCH_WINDOW[1]))
        lines.append(f"render bench: {v}: {sps / 1e6:.2f} M samples/s on a {BENCH_WINDOW[0]}x{BENCH_WINDOW[1]} window "
                     f"-> ~{1.0 / full_s:.3f} images/s at {cam}")
    choose_variant(best, announce=lambda s: None)
    patches = patch_costs()
    lines += patch_cost_lines(patches)
    million = {w: million_image_run_tmp(w) for w in (1, 2)}
    lines += million_image_lines(million)
    scale = FULL_FRAME[0] * FULL_FRAME[1] / _pixels(spec)  # full-resolution pixels per pixel of this spec
    frames = {"variant": best, "samples_per_s": rates.get(best, float("nan")), "cores": _cores(),
              "overhead_s": (wall - inside) / max(n, 1) * scale, "bytes": frame_bytes * scale}
    frames["compact_us"] = compaction_us_per_entry()
    frames["ray_tasks_per_s"] = ray_tasks_per_s()
    lines += capacity_lines(patches, frames)
    return lines


def compaction_us_per_entry(n: int = 100_000) -> float:
    """Microseconds per entry to compact a journal of ``n`` entries into an empty manifest."""
    import json

    from edgetruth.render.dataset.journal import JOURNAL, JOURNAL_FORMAT, MANIFEST, compact, new_header, write_manifest

    with tempfile.TemporaryDirectory(prefix="bench-compact-", dir=_scratch_dir()) as tmp:
        d, key = Path(tmp), "ab" * 32
        write_manifest(d / MANIFEST, new_header("bench", key, n), [])
        with open(d / JOURNAL, "w") as fh:  # what the driver appends, without syncing every line
            fh.write(json.dumps({"journal": JOURNAL_FORMAT, "spec_sha256": key}) + "\n")
            for i in range(n):
                name = f"{i:06d}_T1"
                files = {k: {"path": f"{name}.{k}", "sha256": f"{i:064x}"} for k in ("exr", "png", "json")}
                entry = {"index": i, "kind": "target", "group": "T1", "seed": 2 ** 30 + i, "variant": "llvm_ad_rgb",
                         "complete": True, "files": files}
                fh.write(json.dumps({"name": name, "entry": entry}) + "\n")
        t0 = time.perf_counter()
        compact(d)
        return 1e6 * (time.perf_counter() - t0) / n


def ray_tasks_per_s(n: int = 3000) -> float | None:
    """Trivial tasks per second through ``RayBackend.map_unordered`` on a local Ray instance (the
    per-task overhead a Ray driver pays); None without Ray."""
    try:
        import ray
    except ImportError:
        return None
    from edgetruth.backends import make_backend

    if ray.is_initialized():
        return None
    with make_backend("ray", workers=2) as be:
        list(be.map_unordered(pow, [(2, i) for i in range(200)]))  # workers started
        t0 = time.perf_counter()
        for _ in be.map_unordered(pow, ((2, i) for i in range(n))):
            pass
        return n / (time.perf_counter() - t0)


def _cores() -> int:
    from edgetruth.backends import default_workers

    return default_workers()


def _image_bytes(d: Path) -> int:
    return sum(p.stat().st_size for p in Path(d).iterdir()
               if p.suffix in (".exr", ".png") or (p.suffix == ".json" and p.name != "manifest.json"))


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
    returns ms per image (wall, everything from the call to the compacted manifest) and per stage,
    bytes per image (files, manifest entry) and the cost of a resume that finds everything done."""
    from edgetruth.render.dataset.driver import render_spec
    from edgetruth.render.testing import write_patch_spec

    spec = write_patch_spec(tmp, n_images, name=f"patches{n_images}")
    out_dir = tmp / spec.stem
    t: dict = {}
    t0 = time.perf_counter()
    render_spec(spec, out_dir, progress=False, timings=t, announce=lambda s: None)
    wall = time.perf_counter() - t0
    n = t["n_rendered"]
    out = {"ms_per_image": 1e3 * wall / n, "n": n}
    out.update({k: 1e3 * t["stage_s"].get(k, 0.0) / n for k in STAGES})
    out["journal"] = 1e3 * t["journal_s"] / n
    out["resume_check_ms"], out["compact_ms"] = 1e3 * t["resume_check_s"], 1e3 * t["compact_s"]
    out["driver_other"] = out["ms_per_image"] - sum(out[k] for k in (*STAGES, "journal"))
    out["image_bytes"] = _image_bytes(out_dir) / n
    out["manifest_bytes"] = (out_dir / "manifest.json").stat().st_size / n
    again: dict = {}
    render_spec(spec, out_dir, progress=False, timings=again, announce=lambda s: None)  # all done: re-hash
    out["resume_us_per_image"] = 1e6 * again["resume_check_s"] / n
    return out


def patch_costs(counts=PATCH_COUNTS) -> dict:
    """``patch_cost`` per count, after a warm-up (scene loading, kernel compilation: once per process)."""
    from edgetruth.render.variants import choose_variant

    choose_variant(announce=lambda s: None)  # the variant probe is not part of an image's cost
    with tempfile.TemporaryDirectory(prefix="bench-patches-", dir=_scratch_dir()) as tmp:
        patch_cost(20, Path(tmp))
        return {n: patch_cost(n, Path(tmp)) for n in counts}


def patch_cost_lines(res: dict) -> list[str]:
    a, b = (res[n] for n in sorted(res)[:2])
    lines = [f"dataset bench: tiny images (40x32 px, 1 spp, one worker): {a['ms_per_image']:.2f} ms/image at "
             f"{a['n']:,}, {b['ms_per_image']:.2f} ms/image at {b['n']:,} (x{b['ms_per_image'] / a['ms_per_image']:.2f}; "
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


def million_image_run_tmp(workers: int) -> dict:
    with tempfile.TemporaryDirectory(prefix="bench-million-", dir=_scratch_dir()) as tmp:
        return million_image_run(Path(tmp), workers=workers)


def million_image_lines(res: dict) -> list[str]:
    lines = []
    for w, r in res.items():
        a, b = r["rss_mb"][200], r["rss_mb"][2000]
        lines.append(f"dataset bench: 1,000,000-image spec, --workers {w}: first image recorded after "
                     f"{r['first_image_s']:.1f} s (target < 10 s); driver RSS {a:.0f} MB after 200 images, "
                     f"{b:.0f} MB after 2,000 ({100 * (b - a) / a:+.1f} %, target within 10 %); "
                     f"{r['images_per_s']:.0f} images/s")
    return lines


FULL_FRAME = (1280, 1024, 64)  # the standard spec's frames: px, px, spp
LINK_BYTES_PER_S = 125e6  # 1 Gbit/s


def capacity_lines(patches: dict, frames: dict) -> list[str]:
    """The capacity plan (docs/cluster.md) from this run's measurements."""
    big = patches[max(patches)]
    ms, fixed_ms = big["ms_per_image"], big["ms_per_image"] - big["mi_render"]
    w, h, spp = FULL_FRAME
    gpu = str(frames["variant"]).startswith("cuda")
    # a CPU variant renders the window on every core; a cuda one on the GPU, whatever the cores
    rate = frames["samples_per_s"] if gpu else frames["samples_per_s"] / frames["cores"]
    frame_s = w * h * spp / rate + frames["overhead_s"]  # the part outside mi.render: one thread
    driver_ms = big["journal"] + big["write"]  # record + write the files sent back, per image
    n = 1_000_000
    if gpu:
        frames_line = (f"capacity: full frames {w}x{h} at {spp} spp on {frames['variant']}: ~{frame_s:.2f} s per frame "
                       f"per GPU ({rate / 1e6:.1f} M samples/s; one worker process) = {3600 / frame_s:.0f} frames/h "
                       "per GPU")
        gpu_render = f"this GPU renders R = {rate / 1e6:.1f} M samples/s (docs/cluster.md's formula)"
    else:
        frames_line = (f"capacity: full frames {w}x{h} at {spp} spp on {frames['variant']}: ~{frame_s:.0f} s per frame "
                       f"per core ({rate / 1e6:.1f} M samples/s per core) = {3600 / frame_s:.0f} frames/h per CPU core")
        gpu_render = "GPU render time not measured: no GPU here"
    return [
        f"capacity: tiny patches: {3.6e6 / ms:,.0f} images/h per CPU worker (one core, {ms:.2f} ms/image); "
        f"1M images = {n * ms / 3.6e6:.1f} CPU-core-hours",
        frames_line,
        f"capacity: a GPU worker still spends the fixed CPU part per image ({fixed_ms:.2f} ms of a tiny patch: "
        f"pose, scene update, sensor, encoding, hashing, writing): at most {3.6e6 / fixed_ms:,.0f} tiny images/h "
        f"per GPU worker process, whatever the GPU ({gpu_render})",
        f"capacity: driver: {driver_ms:.2f} ms per image (journal line {big['journal']:.2f}, synced in the "
        f"background; writing files sent back {big['write']:.2f}) = ~{1e3 / driver_ms:,.0f} images/s per driver"
        + (f"; Ray: {frames['ray_tasks_per_s']:,.0f} trivial tasks/s through one driver (local instance, "
           f"{_cores()} cores)" if frames.get("ray_tasks_per_s") else "") + "; network: "
        f"{big['image_bytes'] / 1e3:.1f} kB per tiny image, {frames['bytes'] / 1e6:.1f} MB per full frame back "
        f"to the driver = {LINK_BYTES_PER_S / big['image_bytes']:,.0f} tiny images/s or "
        f"{LINK_BYTES_PER_S / frames['bytes']:.0f} full frames/s on 1 Gbit/s",
        f"capacity: 1M-image dataset: manifest {big['manifest_bytes'] * n / 1e6:.0f} MB "
        f"({big['manifest_bytes']:.0f} B/image; the journal about as much until compacted), tiny-patch files "
        f"{big['image_bytes'] * n / 1e9:.1f} GB; resume = re-hash every recorded file, "
        f"{big['resume_us_per_image']:.0f} us/image = {big['resume_us_per_image'] * n / 6e7:.1f} min for 1M tiny "
        f"images; compaction {frames['compact_us']:.0f} us/entry = {frames['compact_us'] * n / 1e6:.0f} s for 1M",
    ]


def _pixels(spec) -> int:
    return spec.camera.width_px * spec.camera.height_px


def spec_camera_desc(spec) -> str:
    r = spec.render
    return f"{spec.camera.width_px}x{spec.camera.height_px}, {r.spp} spp (edge band {r.edge_spp}) {r.sampler}"


if __name__ == "__main__":  # pragma: no cover
    for line in run_bench():
        print(line)
