"""Render a spec into a dataset directory, resumably; read images back.

Per image ``NAME``: ``NAME.exr`` (linear radiance, float32), ``NAME.png`` (sensor
image, 16-bit, raw DN) and ``NAME.json`` (ground truth).  ``manifest.json`` lists
every image with the SHA-256 of each file; an image counts as done only when its
manifest entry says so *and* its files still hash to the recorded values.
"""
from __future__ import annotations

import platform
import sys
import time
from pathlib import Path

import numpy as np

from edgetruth import __version__
from edgetruth.errors import InputError, require
from render.camera import Camera, load_camera
from render.files import read_exr, read_json, read_png16, sha256_file, write_exr, write_json, write_png16
from render.ground_truth import checker_ground_truth, outline_in_view, target_ground_truth, target_outline_local
from render.mitsuba_scene import TARGETS, CheckerRig, Checkerboard, RenderSettings, TargetRig
from render.pose import Pose
from render.sensor import SensorModel, make_rng, sensor_from_dict
from render.spec import Spec, load_spec

MANIFEST = "manifest.json"
FORMAT_VERSION = 1
POSE_STREAM, SENSOR_STREAM = 1, 2
VIEW_MARGIN_PX = 12.0  # full-size frames; small test frames use 2 % of their width
_rigs: dict = {}


# --- spec -> scene objects ----------------------------------------------------------
def spec_camera(spec: Spec) -> Camera:
    cam = load_camera(spec.settings.get("camera", "default"))
    scale = int(spec.settings.get("camera_scale", 1))
    return cam.scaled(scale) if scale != 1 else cam


def spec_settings(spec: Spec) -> RenderSettings:
    return RenderSettings(spp=int(spec.settings.get("spp", RenderSettings.spp)),
                          sampler=str(spec.settings.get("sampler", RenderSettings.sampler)))


def spec_checkerboard(spec: Spec) -> Checkerboard:
    return Checkerboard(**spec.settings.get("checkerboard", {}))


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


def job_pose(job: dict, camera: Camera, outline_local: np.ndarray) -> Pose:
    """The pose of a job: distance from the spec, lateral offset and tilts drawn from the job seed,
    redrawn (deterministically) until the outline lies inside the image."""
    rng = make_rng(job["seed"], POSE_STREAM)
    d = job["distance_cm"] / 100.0
    extent = float(np.max(np.abs(outline_local[:, :2])))
    for attempt in range(200):
        shrink = 1.0 if attempt < 100 else 0.0  # after 100 misses: centred
        room = np.maximum(_half_view_m(camera, d) - extent * 1.2, 0.0)
        ox, oy = job["lateral_fraction"] * shrink * room * rng.uniform(-1, 1, 2)
        tx, ty = job["tilt_max_deg"] * shrink * rng.uniform(-1, 1, 2)
        roll = job["roll_max_deg"] * shrink * rng.uniform(-1, 1)
        pose = Pose(d, float(ox), float(oy), float(tx), float(ty), float(roll))
        margin = min(VIEW_MARGIN_PX, max(1.0, 0.02 * camera.width_px))
        if outline_in_view(camera, pose.to_camera(outline_local), margin):
            return pose
    raise InputError(f"image {job['name']}: the board does not fit in the image at {d:.2f} m; "
                     "move it further away or use a smaller board")


def versions(variant: str) -> dict:
    import cv2
    import drjit
    import mitsuba

    return {"edgetruth": __version__, "mitsuba": mitsuba.__version__, "drjit": drjit.__version__,
            "variant": variant, "numpy": np.__version__, "opencv": cv2.__version__,
            "python": platform.python_version()}


# --- one image ----------------------------------------------------------------------
def render_job(spec: Spec, job: dict, crop=None, timings: dict | None = None):
    """Render one job -> (radiance float32 (H, W), DN uint16 (H, W), ground-truth dict)."""
    import mitsuba as mi

    camera = spec_camera(spec)
    settings = spec_settings(spec)
    sensor = sensor_from_dict(job["sensor"])
    if job["kind"] == "target":
        size_m = float(spec.settings.get("target_size_m", 0.13))
        require(job["target"] in TARGETS, f"spec {spec.name}: unknown target {job['target']!r} (have {sorted(TARGETS)})")
        pose = job_pose(job, camera, target_outline_local(TARGETS[job["target"]]["shape"], size_m))
        rig = get_rig("target", camera, settings, size_m, crop)
        le = rig.set_state(job["target"], pose, job["irradiance_w_m2"])
        gt = target_ground_truth(camera, pose, job["target"], size_m)
    else:
        board = spec_checkerboard(spec)
        b = board
        corners = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]]) * [b.cols * b.square_m / 2 + b.margin_m,
                                                                               b.rows * b.square_m / 2 + b.margin_m, 0]
        pose = job_pose(job, camera, corners)
        rig = get_rig("checkerboard", camera, settings, board, crop)
        le = rig.set_state(pose, job["irradiance_w_m2"])
        gt = checker_ground_truth(camera, pose, board)
    t0 = time.perf_counter()
    radiance = rig.render(job["seed"])
    if timings is not None:
        timings["render_s"] = timings.get("render_s", 0.0) + time.perf_counter() - t0
    dn = sensor.expose(radiance, camera.f_number, camera.pitch_um, make_rng(job["seed"], SENSOR_STREAM))
    full = {
        "format": FORMAT_VERSION,
        "name": job["name"], "index": job["index"], "spec": spec.name, "group": job["group"], "kind": job["kind"],
        "seed": job["seed"],
        "seeds": {"mitsuba": job["seed"], "pose_rng": [job["seed"], POSE_STREAM], "sensor_rng": [job["seed"], SENSOR_STREAM],
                  "rng": "numpy PCG64 seeded with [seed, stream]"},
        "conventions": "pixel coordinates: OpenCV (pixel (r, c) centre at x=c, y=r); lengths in metres; "
                       "camera frame x right, y down, z forward",
        "camera": camera.ground_truth(),
        "pose": pose.to_dict(),
        **gt,
        "illumination": rig.light_ground_truth(pose, le, job["irradiance_w_m2"]),
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
    return {"format": FORMAT_VERSION, "spec": spec.name, "spec_path": str(spec.path),
            "spec_sha256": spec.text_sha256, "n_images": len(spec.jobs), "images": {}}


def render_spec(spec: Spec | str | Path, out_dir: str | Path, variant: str | None = None, progress: bool = True,
                only: list[int] | None = None, timings: dict | None = None, announce=print) -> dict:
    """Render every image of ``spec`` into ``out_dir`` (resumable) and return the manifest.

    ``only`` restricts to those job indices; ``timings`` (a dict) accumulates ``render_s``
    (inside ``mi.render``), ``wall_s`` and ``n_rendered``.
    """
    from render.variants import choose_variant

    if not isinstance(spec, Spec):
        spec = load_spec(spec)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    mpath = out_dir / MANIFEST
    manifest = read_json(mpath) if mpath.is_file() else _new_manifest(spec)
    if manifest.get("spec") != spec.name or manifest.get("spec_sha256") != spec.text_sha256:
        raise InputError(f"{out_dir} holds renders of another spec (or another version of {spec.name!r}); "
                         "choose a new output directory or delete it")
    jobs = [j for j in spec.jobs if only is None or j["index"] in only]
    todo = [j for j in jobs if not _entry_complete(out_dir, manifest["images"].get(j["name"]))]
    if todo:
        used = choose_variant(variant, announce=announce)
    t_start = time.perf_counter()
    stats = timings if timings is not None else {}
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=len(jobs), initial=len(jobs) - len(todo), unit="img", desc=f"render {spec.name}",
                   file=sys.stderr, dynamic_ncols=True)
    try:
        for job in todo:
            radiance, dn, gt = render_job(spec, job, timings=stats)
            name = job["name"]
            gt["files"] = {"exr": f"{name}.exr", "png": f"{name}.png"}
            write_exr(out_dir / f"{name}.exr", radiance)
            write_png16(out_dir / f"{name}.png", dn)
            write_json(out_dir / f"{name}.json", gt)
            manifest["images"][name] = {
                "index": job["index"], "kind": job["kind"], "group": job["group"], "seed": job["seed"],
                "variant": used, "complete": True,
                "files": {k: {"path": f"{name}.{k}", "sha256": sha256_file(out_dir / f"{name}.{k}")}
                          for k in ("exr", "png", "json")},
            }
            manifest["images"] = dict(sorted(manifest["images"].items(), key=lambda kv: kv[1]["index"]))
            write_json(mpath, manifest)
            stats["n_rendered"] = stats.get("n_rendered", 0) + 1
            if bar:
                bar.update(1)
    finally:
        if bar:
            bar.close()
    stats["wall_s"] = stats.get("wall_s", 0.0) + time.perf_counter() - t_start
    if not mpath.is_file():
        write_json(mpath, manifest)
    return manifest


def load_image(out_dir: str | Path, name: str) -> tuple[np.ndarray, dict]:
    """(sensor image uint16 (H, W), ground truth dict) of image ``name`` in a dataset."""
    out_dir = Path(out_dir)
    require((out_dir / f"{name}.json").is_file(), f"{out_dir}: no image named {name!r}")
    return read_png16(out_dir / f"{name}.png"), read_json(out_dir / f"{name}.json")


def load_radiance(out_dir: str | Path, name: str) -> np.ndarray:
    """The linear radiance (float32, W m⁻² sr⁻¹) of image ``name``."""
    return read_exr(Path(out_dir) / f"{name}.exr")


def list_images(out_dir: str | Path) -> list[str]:
    """Names of the complete images of a dataset, in index order."""
    m = read_json(Path(out_dir) / MANIFEST)
    return [n for n, e in m["images"].items() if e.get("complete")]
