"""One image of a dataset, in a worker process: render it, encode its three files, hash them.

``render_task(spec, index, variant, out_dir)`` is a pure function of (spec, index).  The
driver does not send the spec with every task: ``init_worker`` receives it once per
worker process and keeps it under its identity hash, and ``render_indexed(spec_key,
indices, ...)`` looks it up (one task per radiance unit).  A task that ran returns the image's manifest entry (with the
SHA-256 of every file) and, when the worker does not see the driver's disk, the file
bytes for the driver to write.
"""
from __future__ import annotations

import hashlib
import json
import time
from pathlib import Path

from edgetruth.fileio import atomic_write_bytes
from edgetruth.render.dataset.image import render_job
from edgetruth.render.dataset.files import encode_exr, encode_png16
from edgetruth.render.dataset.spec import Spec

#: Specs this worker process was given, by identity hash (``Spec.identity_sha256``).
_specs: dict[str, Spec] = {}
#: Dr.Jit's LLVM backend hands out work in blocks of 16384 SIMD packets (>= 8 lanes each): a
#: render with fewer samples than this runs on one thread anyway, and idle worker threads only
#: compete with this one for the cores (measured: 1.3 ms median either way, but a mean of 5.0 ms
#: with 2 threads vs 2.6 ms with 1 on a loaded 2-core machine).
SMALL_RENDER_SAMPLES = 16384 * 8


def samples_per_render(spec: Spec) -> int:
    """The most Monte-Carlo samples one image of ``spec`` takes (pixels x spp, largest group)."""
    return max(g.camera.width_px * g.camera.height_px for g in spec.groups) * spec.render.spp


def init_worker(variant: str, threads: int | None = None, spec: Spec | None = None,
                spec_key: str | None = None) -> None:
    """Once per worker process: activate ``variant``, share the cores among the workers, and keep
    ``spec`` for the tasks that name it by ``spec_key``."""
    import edgetruth.render.variants  # noqa: F401 -- points Dr.Jit at the pip libLLVM before it is imported
    import mitsuba as mi

    if mi.variant() != variant:
        mi.set_variant(variant)
    if spec is not None and samples_per_render(spec) <= SMALL_RENDER_SAMPLES:
        threads = 1  # the calling thread only
    if threads and variant.startswith("llvm"):
        import drjit as dr

        dr.set_thread_count(int(threads))
    if spec is not None:
        _specs[spec_key or spec.identity_sha256] = spec


def init_worker_specs(variant: str, threads: int | None, specs: dict) -> None:
    """``init_worker`` for a worker shared by several specs (``driver.RenderPool``): all of them, by identity hash;
    one Dr.Jit thread if every spec's renders are small."""
    if specs and all(samples_per_render(s) <= SMALL_RENDER_SAMPLES for s in specs.values()):
        threads = 1
    init_worker(variant, threads)
    _specs.update(specs)


def render_indexed(spec_key: str, indices: tuple, variant: str, out_dir: str | None) -> list[dict]:
    """``render_task`` of each of ``indices`` (one radiance unit: rendered once, in this worker) for the
    spec this worker was given by ``init_worker``."""
    spec = _specs.get(spec_key)
    if spec is None:
        raise RuntimeError(f"worker has no spec {spec_key[:12]}: the backend's initializer did not run here")
    return [render_task(spec, int(i), variant, out_dir) for i in indices]


def encode_json(obj) -> bytes:
    return (json.dumps(obj, indent=1, sort_keys=False) + "\n").encode()


def render_task(spec: Spec, index: int, variant: str, out_dir: str | None) -> dict:
    """Render image ``index`` of ``spec``: a pure function of (spec, index) (its seed is
    ``image_seed(spec.name, index)``).  With ``out_dir`` the files are written there, each
    atomically; otherwise their bytes come back in ``payload`` for the driver to write.
    Returns the image's manifest entry and the seconds spent per stage (``stage_s``)."""
    import mitsuba as mi

    if mi.variant() != variant:
        init_worker(variant)
    t0 = time.perf_counter()
    job = spec.jobs[index]
    timings: dict = {}
    radiance, dn, gt = render_job(spec, job, timings=timings)
    name = job.name
    gt["files"] = {"exr": f"{name}.exr", "png": f"{name}.png"}
    t1 = time.perf_counter()
    data = {"exr": encode_exr(radiance)}
    t2 = time.perf_counter()
    data["png"] = encode_png16(dn)
    t3 = time.perf_counter()
    data["json"] = encode_json(gt)
    t4 = time.perf_counter()
    files = {k: {"path": f"{name}.{k}", "sha256": hashlib.sha256(b).hexdigest()} for k, b in data.items()}
    t5 = time.perf_counter()
    if out_dir is not None:
        write_files(Path(out_dir), name, data)
    t6 = time.perf_counter()
    entry = {"index": index, "kind": job.kind, "group": job.group, "seed": job.seed,
             "variant": variant, "complete": True, "files": files}
    render_s = timings.get("render_s", 0.0)
    stage_s = {"scene_sensor_truth": t1 - t0 - render_s, "mi_render": render_s, "exr": t2 - t1, "png": t3 - t2,
               "json": t4 - t3, "sha256": t5 - t4, "write": t6 - t5}
    return {"name": name, "entry": entry, "render_s": render_s, "stage_s": stage_s,
            "reused": timings.get("reused", 0), "payload": None if out_dir is not None else data}


def write_files(out_dir: Path, name: str, data: dict) -> None:
    """The three files of an image, each atomically (temporary name, then rename), the JSON (which
    names the other two) last.  Not synced one by one: the journal line that records them is,
    and a resume re-hashes every file, so a file lost in a power cut is rendered again."""
    for ext in ("exr", "png", "json"):
        atomic_write_bytes(out_dir / f"{name}.{ext}", data[ext], fsync=False)
