"""Render a spec into a dataset directory, resumably; read images back.

Per image ``NAME``: ``NAME.exr`` (linear radiance, float32), ``NAME.png`` (sensor
image, 16-bit, raw DN) and ``NAME.json`` (ground truth).  ``manifest.json`` lists
every image with the SHA-256 of each file; an image counts as done only when its
manifest entry says so *and* its files still hash to the recorded values.
"""
from __future__ import annotations

import hashlib
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

from edgetruth import __version__, console
from edgetruth.errors import InputError
from edgetruth.fileio import atomic_write_bytes, is_temporary, make_output_dir, read_json, sha256_file, write_json
from edgetruth.render.camera import Camera
from edgetruth.render.files import encode_exr, encode_png16
from edgetruth.render.ground_truth import checker_ground_truth, outline_in_view, target_ground_truth, target_outline_local
from edgetruth.render.mitsuba_scene import CheckerRig, RenderSettings, TargetRig
from edgetruth.render.pose import Pose
from edgetruth.render.reader import MANIFEST
from edgetruth.render.sensor import make_rng
from edgetruth.render.spec import Job, Spec, load_spec
from edgetruth.render.targets import TARGETS

FORMAT_VERSION = 1
POSE_STREAM, SENSOR_STREAM = 1, 2
VIEW_MARGIN_PX = 12.0  # full-size frames; small test frames use 2 % of their width
_rigs: dict = {}
_radiance_cache: dict = {}  # the last design-slot radiance this process rendered (its cells reuse it)


# --- scene objects ----------------------------------------------------------------
def get_rig(kind: str, camera: Camera, settings: RenderSettings, extra=None, crop=None):
    """The process-wide scene for (kind, camera, settings, ...): loaded once, re-posed per image."""
    import mitsuba as mi

    key = (mi.variant(), kind, camera, settings, extra, crop)
    if key not in _rigs:
        if kind == "target":
            _rigs[key] = TargetRig(camera, settings, target_size_m=extra, crop=crop)
        else:
            _rigs[key] = CheckerRig(camera, settings, board=extra, crop=crop)
    return _rigs[key]


def _half_view_m(camera: Camera, distance_m: float) -> np.ndarray:
    return np.array([camera.width_px, camera.height_px]) / 2.0 / camera.fx_px * distance_m


def job_pose(job: Job, camera: Camera, outline_local: np.ndarray) -> Pose:
    """The pose of a job: distance from the spec, lateral offset and tilts drawn from the job seed,
    redrawn (deterministically) until the outline lies inside the image."""
    rng = make_rng(job.pose_seed, POSE_STREAM)
    d = job.distance_cm / 100.0
    extent = float(np.max(np.abs(outline_local[:, :2])))
    for attempt in range(200):
        shrink = 1.0 if attempt < 100 else 0.0  # after 100 misses: centred
        room = np.maximum(_half_view_m(camera, d) - extent * 1.2, 0.0)
        ox, oy = job.lateral_fraction * shrink * room * rng.uniform(-1, 1, 2)
        tx, ty = job.tilt_max_deg * shrink * rng.uniform(-1, 1, 2)
        roll = job.roll_max_deg * shrink * rng.uniform(-1, 1)
        pose = Pose(d, float(ox), float(oy), float(tx), float(ty), float(roll))
        margin = min(VIEW_MARGIN_PX, max(1.0, 0.02 * camera.width_px))
        if outline_in_view(camera, pose.to_camera(outline_local), margin):
            return pose
    raise InputError(f"image {job.name}: the board does not fit in the image at {d:.2f} m; "
                     "move it further away or use a smaller board")


def versions(variant: str) -> dict:
    import cv2
    import drjit
    import mitsuba

    return {"edgetruth": __version__, "mitsuba": mitsuba.__version__, "drjit": drjit.__version__,
            "variant": variant, "numpy": np.__version__, "opencv": cv2.__version__,
            "python": platform.python_version()}


# --- one image ----------------------------------------------------------------------
def render_job(spec: Spec, job: Job, crop=None, timings: dict | None = None):
    """Render one job -> (radiance float32 (H, W), DN uint16 (H, W), ground-truth dict)."""
    import mitsuba as mi

    camera = job.camera
    settings = spec.render
    sensor = job.sensor
    # a design cell renders its unit's radiance at the unit's irradiance and scales it (light transport
    # is linear in emitted power): every cell of a unit shares one render, whatever order they come in
    e_render = job.unit_irradiance_w_m2 if job.unit_irradiance_w_m2 is not None else job.irradiance_w_m2
    if job.kind == "target":
        size_m = spec.target_size_m
        # paired cells share the pose whatever the target: the view check uses the square (it bounds the circle)
        shape = "square" if job.slot is not None else TARGETS[job.target]["shape"]
        pose = job_pose(job, camera, target_outline_local(shape, size_m))
        rig = get_rig("target", camera, settings, size_m, crop)
        le = rig.set_state(job.target, pose, e_render)
        gt = target_ground_truth(camera, pose, job.target, size_m)
    else:
        board = spec.checkerboard
        pose = job_pose(job, camera, board.plate_corners_local())
        rig = get_rig("checkerboard", camera, settings, board, crop)
        le = rig.set_state(pose, e_render)
        gt = checker_ground_truth(camera, pose, board)
    key = (spec.identity_sha256, job.radiance_unit, job.slot, crop)
    t0 = time.perf_counter()
    if job.slot is not None and _radiance_cache.get("key") == key:
        radiance = _radiance_cache["radiance"]
        reused = True
    else:
        radiance = rig.render(job.render_seed)
        reused = False
        if job.slot is not None:
            _radiance_cache.update(key=key, radiance=radiance)
    if timings is not None:
        timings["render_s"] = timings.get("render_s", 0.0) + time.perf_counter() - t0
        timings["reused"] = timings.get("reused", 0) + int(reused)
    scale = job.irradiance_w_m2 / e_render
    if scale != 1.0:
        radiance = (radiance * np.float32(scale)).astype(np.float32)
        le *= scale
    dn = sensor.expose(radiance, camera.f_number, camera.pitch_um, make_rng(job.seed, SENSOR_STREAM))
    full = {
        "format": FORMAT_VERSION,
        "name": job.name, "index": job.index, "spec": spec.name, "group": job.group, "kind": job.kind,
        "seed": job.seed,
        "seeds": {"mitsuba": job.render_seed, "pose_rng": [job.pose_seed, POSE_STREAM],
                  "sensor_rng": [job.seed, SENSOR_STREAM], "rng": "numpy PCG64 seeded with [seed, stream]"},
        "design": None if job.slot is None else {
            "slot": job.slot, "levels": job.levels, "base_levels": job.base_levels, "radiance_unit": job.radiance_unit,
            "unit_irradiance_w_m2": job.unit_irradiance_w_m2, "radiance_scale": scale,
            "pairing": "every cell of the spec's design renders pose slot `slot` (same seed, same pose); cells "
                       "of one radiance unit share one render, scaled by irradiance / unit irradiance"},
        "conventions": "pixel coordinates: OpenCV (pixel (r, c) centre at x=c, y=r); lengths in metres; "
                       "camera frame x right, y down, z forward",
        "camera": camera.ground_truth(),
        "pose": pose.to_dict(),
        **gt,
        "illumination": rig.light_ground_truth(pose, le, job.irradiance_w_m2),
        "sensor": sensor.to_dict(),
        "photons_per_radiance": sensor.photons_per_radiance(camera.f_number, camera.pitch_um),
        "render": {**settings.to_dict(), "integrator": "direct (emitter sampling only)", "rfilter": "box",
                   "film": "hdrfilm float32", "crop": list(crop) if crop else None,
                   "distortion": "exact, per-ray inverse Brown-Conrady in a Python sensor plugin"},
        "versions": versions(mi.variant()),
    }
    return radiance, dn, full


# --- datasets -----------------------------------------------------------------------
def _entry_complete(out_dir: Path, entry: dict | None) -> bool:
    if not entry or not entry.get("complete"):
        return False
    for f in entry["files"].values():
        p = out_dir / f["path"]
        if not p.is_file() or sha256_file(p) != f["sha256"]:
            return False
    return True


def _new_manifest(spec: Spec) -> dict:
    return {"format": FORMAT_VERSION, "spec": spec.name, "spec_sha256": spec.identity_sha256,
            "n_images": spec.n_images, "images": {}}


def _encode_json(obj) -> bytes:
    return (json.dumps(obj, indent=1, sort_keys=False) + "\n").encode()


def init_worker(variant: str, threads: int | None = None) -> None:
    """Once per worker process: activate ``variant`` and share the cores among the workers."""
    import edgetruth.render.variants  # noqa: F401  (points Dr.Jit at the pip libLLVM before it is imported)
    import mitsuba as mi

    if mi.variant() != variant:
        mi.set_variant(variant)
    if threads and variant.startswith("llvm"):
        import drjit as dr

        dr.set_thread_count(int(threads))


def render_task(spec: Spec, index: int, variant: str, out_dir: str | None) -> dict:
    """Render image ``index`` of ``spec``: a pure function of (spec, index) (its seed is
    ``image_seed(spec.name, index)``).  With ``out_dir`` the files are written there, each
    atomically; otherwise their bytes come back in ``payload`` for the driver to write.
    Returns the image's manifest entry (with SHA-256 of every file) -- the driver records it."""
    import mitsuba as mi

    if mi.variant() != variant:
        init_worker(variant)
    job = spec.jobs[index]
    timings: dict = {}
    radiance, dn, gt = render_job(spec, job, timings=timings)
    name = job.name
    gt["files"] = {"exr": f"{name}.exr", "png": f"{name}.png"}
    data = {"exr": encode_exr(radiance), "png": encode_png16(dn), "json": _encode_json(gt)}
    if out_dir is not None:
        _write_files(Path(out_dir), name, data)
    entry = {
        "index": index, "kind": job.kind, "group": job.group, "seed": job.seed,
        "variant": variant, "complete": True,
        "files": {k: {"path": f"{name}.{k}", "sha256": hashlib.sha256(b).hexdigest()} for k, b in data.items()},
    }
    return {"name": name, "entry": entry, "render_s": timings.get("render_s", 0.0), "reused": timings.get("reused", 0),
            "payload": None if out_dir is not None else data}


def _write_files(out_dir: Path, name: str, data: dict) -> None:
    # the JSON (which names the other two) last; each file appears whole or not at all
    for ext in ("exr", "png", "json"):
        atomic_write_bytes(out_dir / f"{name}.{ext}", data[ext])


class _DirLock:
    """An exclusive ``flock`` on the dataset directory itself (no lock file to leave behind);
    the kernel releases it when the process dies, even on ``kill -9``."""

    def __init__(self, path: Path):
        import fcntl

        self.fd = os.open(path, os.O_RDONLY)
        try:
            fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(self.fd)
            raise InputError(f"{path}: another `edgetruth render` is writing this dataset now; "
                             "wait for it to finish or choose another output directory") from None

    def release(self) -> None:
        os.close(self.fd)  # closing the descriptor drops the flock


def render_spec(spec: Spec | str | Path, out_dir: str | Path, variant: str | None = None, progress: bool = True,
                only: list[int] | None = None, timings: dict | None = None, announce=print,
                backend: str = "local", workers: int | None = 1, address: str | None = None) -> dict:
    """Render every image of ``spec`` into ``out_dir`` (resumable) and return the manifest.

    ``only`` restricts to those job indices; ``timings`` (a dict) accumulates ``render_s``
    (inside ``mi.render``, summed over workers), ``wall_s`` and ``n_rendered``.

    ``backend``/``workers``/``address``: where images render (see ``edgetruth.backends``);
    the default renders in this process.  Whatever the backend, the files of an image are
    identical, only this (driver) process writes ``manifest.json`` (atomically, after each
    image), and an interrupted run -- even ``kill -9`` -- resumes where it stopped.
    """
    from edgetruth.backends import check_backend_args, default_workers, make_backend
    from edgetruth.render.variants import choose_variant

    check_backend_args(backend, workers, address)  # before anything is written
    if variant:
        import mitsuba as mi

        if variant not in mi.variants():
            raise InputError(f"--variant {variant}: not in this Mitsuba build (have: {', '.join(mi.variants())})")
    if not isinstance(spec, Spec):
        spec = load_spec(spec)
    out_dir = Path(out_dir)
    if only is not None:
        bad = sorted(i for i in set(only) if not 0 <= i < spec.n_images)
        if bad:
            raise InputError(f"--only: index {bad[0]} out of range; {spec.name!r} has images 0-{spec.n_images - 1}")
    make_output_dir(out_dir)
    lock = _DirLock(out_dir)
    try:
        return _render_locked(spec, out_dir, variant, progress, only, timings, announce, backend, workers,
                              address, make_backend, default_workers, choose_variant)
    finally:
        lock.release()


def _render_locked(spec, out_dir, variant, progress, only, timings, announce, backend, workers, address,
                   make_backend, default_workers, choose_variant) -> dict:
    mpath = out_dir / MANIFEST
    manifest = read_json(mpath) if mpath.is_file() else _new_manifest(spec)
    if not isinstance(manifest, dict) or not isinstance(manifest.get("images"), dict):
        raise InputError(f"{mpath}: not an edgetruth manifest; choose a new output directory or delete it")
    if manifest.get("spec") != spec.name or manifest.get("spec_sha256") != spec.identity_sha256:
        raise InputError(f"{out_dir} holds renders of another spec (or another version of {spec.name!r}); "
                         "choose a new output directory or delete it")
    for p in out_dir.iterdir():  # temporaries of a killed run (we hold the lock: no writer is alive)
        if is_temporary(p) and p.is_file():
            p.unlink()
    jobs = list(spec.jobs) if only is None else [spec.jobs[i] for i in sorted(set(only))]
    todo = [j for j in jobs if not _entry_complete(out_dir, manifest["images"].get(j.name))]
    # the images of one radiance unit next to each other: a worker renders the unit once and reuses it
    unit_rank = {i: u for u, unit in enumerate(spec.units()) for i in unit}
    todo.sort(key=lambda j: (unit_rank[j.index], j.index))
    stats = timings if timings is not None else {}
    t_start = time.perf_counter()
    if not todo:
        if not mpath.is_file():
            write_json(mpath, manifest)
        stats["wall_s"] = stats.get("wall_s", 0.0) + time.perf_counter() - t_start
        return manifest
    n_workers = default_workers() if workers is None else int(workers)
    n_workers = min(n_workers, len(todo)) if backend == "local" else n_workers
    be = make_backend(backend, workers=n_workers, address=address)  # validates before any rendering
    bar = None
    try:
        if backend == "ray" and getattr(be, "num_gpus", 0) and not variant:
            used = "cuda_ad_rgb"
            announce(f"render: using Mitsuba variant {used} (the Ray cluster has GPUs)")
        else:
            used = choose_variant(variant, announce=announce)
        threads = max(1, default_workers() // max(1, be.concurrency)) if be.concurrency > 1 else None
        be.set_initializer(init_worker, (used, threads))
        bar = console.bar(total=len(jobs), initial=len(jobs) - len(todo), unit="img", desc=f"render {spec.name}",
                          enabled=progress)
        worker_dir = str(out_dir.resolve()) if be.shares_filesystem else None
        tasks = [(spec, j.index, used, worker_dir) for j in todo]
        for res in be.map_unordered(render_task, tasks):
            name = res["name"]
            if res["payload"] is not None:
                _write_files(out_dir, name, res["payload"])
            manifest["images"][name] = res["entry"]
            manifest["images"] = dict(sorted(manifest["images"].items(), key=lambda kv: kv[1]["index"]))
            write_json(mpath, manifest)
            stats["render_s"] = stats.get("render_s", 0.0) + res["render_s"]
            stats["n_rendered"] = stats.get("n_rendered", 0) + 1
            stats["reused"] = stats.get("reused", 0) + res.get("reused", 0)
            bar.update(1)
    except BaseException:
        be.close(abort=True)
        raise
    finally:
        if bar is not None:
            bar.close()
    be.close()
    stats["wall_s"] = stats.get("wall_s", 0.0) + time.perf_counter() - t_start
    return manifest


def list_images(out_dir: str | Path) -> list[str]:
    """Names of the complete images of a dataset, in index order (see ``edgetruth.render.reader``)."""
    from edgetruth.render.reader import open_dataset

    return open_dataset(out_dir).names()
