"""One image of a dataset: its scene, pose, render, sensor image and ground truth.

``render_job(spec, job)`` -> (radiance, image file pixels, ground-truth dict) for one job of a
spec: the image is the sensor's 16-bit raw DN, or 8-bit sRGB/JPEG pixels per its ``output``.
Writing datasets (the driver loop, journal and manifest) lives in
``edgetruth.render.dataset.driver`` / ``edgetruth.render.dataset.journal``; a worker's task (encode,
hash, write) in ``edgetruth.render.dataset.task``; reading datasets back in
``edgetruth.render.dataset.reader``.
"""
from __future__ import annotations

import platform
import time
from dataclasses import replace

import numpy as np

from edgetruth import __version__
from edgetruth.errors import InputError
from edgetruth.render.optics.camera import Camera
from edgetruth.render.scene.ground_truth import (checker_ground_truth, outline_in_view, squares_ground_truth,
                                           target_ground_truth, view_outline_local)
from edgetruth.render.scene.mitsuba_scene import CheckerRig, RenderSettings, TargetRig
from edgetruth.render.scene.pose import Pose
from edgetruth.render.scene.sample_passes import sample_passes_note
from edgetruth.render.sensor.linear_model import make_rng
from edgetruth.render.dataset.spec import Job, Spec

FORMAT_VERSION = 1
POSE_STREAM, SENSOR_STREAM = 1, 2
VIEW_MARGIN_PX = 12.0  # full-size frames; small test frames use 2 % of their width
_rigs: dict = {}
_radiance_cache: dict = {}  # the last design-slot radiance this process rendered (its cells reuse it)


# --- scene objects ----------------------------------------------------------------
def get_rig(kind: str, camera: Camera, settings: RenderSettings, extra=None, crop=None, bent: bool = False):
    """The process-wide scene for (kind, camera, settings, ...): loaded once, re-posed per image (a
    ``bent`` board's meshes re-shaped too)."""
    import mitsuba as mi

    key = (mi.variant(), kind, camera, settings, extra, crop, bent)
    if key not in _rigs:
        if kind == "target":
            _rigs[key] = TargetRig(camera, settings, target_size_m=extra, crop=crop)
        else:  # checkerboard or squares: ``extra`` is the board
            _rigs[key] = CheckerRig(camera, settings, board=extra, crop=crop, bent=bent)
    return _rigs[key]


def _board_state(job: Job, kind: str, camera: Camera, settings: RenderSettings, board, crop, pose, e_render):
    """Pose (and curl) a board of squares or a checkerboard: its rig, the light's radiance, the bend
    (or None) and the mesh's sag."""
    bend = sag = None
    if job.board_bend_mm is not None:
        from edgetruth.render.scene.bend import BoardBend

        bend = BoardBend.of(job.board_bend_mm, board.black_quads_local(0.0))
    rig = get_rig(kind, camera, settings, board, crop, bent=bend is not None)
    if bend is not None:
        sag = rig.mesh_sag_m(bend)
    le = rig.set_state(pose, e_render, job.light_position_m, bend=bend)
    return rig, le, bend, sag


def _half_view_m(camera: Camera, distance_m: float) -> np.ndarray:
    return np.array([camera.width_px, camera.height_px]) / 2.0 / camera.fx_px * distance_m


def job_pose(job: Job, camera: Camera, outline_local: np.ndarray) -> Pose:
    """The pose of a job: its explicit pose if it has one; else distance from the spec, lateral offset and
    tilts drawn from the job seed, redrawn (deterministically) until the outline lies inside the image."""
    if job.pose is not None:
        return job.pose
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
        if in_view(camera, pose, outline_local):
            return pose
    if job.kind == "target":
        raise InputError(f"image {job.name}: the target's shapes do not fit in the image at {d:.2f} m; move them "
                         "further away or make them smaller")
    raise InputError(f"image {job.name}: the board does not fit in the image at {d:.2f} m; move it further away "
                     "or use a smaller board")


def in_view(camera: Camera, pose: Pose, outline_local: np.ndarray) -> bool:
    """The pose draw's test: every point of the outline within the frame, less a margin."""
    margin = min(VIEW_MARGIN_PX, max(1.0, 0.02 * camera.width_px))
    return bool(outline_in_view(camera, pose.to_camera(outline_local), margin))


def view_points(spec: Spec, job: Job) -> np.ndarray:
    """Board points (N, 3) whose view decides job's pose (``job_pose``): a target's shapes (a paired cell: every
    cell's), a board's plate."""
    if job.kind == "target":
        size_m = spec.target_size_m
        return paired_view_outline(spec, size_m) if job.slot is not None else view_outline_local(job.target, size_m)
    if job.slot is not None:  # a design's board cells (one kind or several) share each slot's pose
        kinds = sorted({g.kind for g in spec.groups if g.paired})
        return np.concatenate([board_of(spec, k).plate_corners_local() for k in kinds])
    return board_of(spec, job.kind).plate_corners_local()


def board_of(spec: Spec, kind: str):
    """The board a board job renders: its squares (a ChArUco board's dark squares and marker cells), its circle
    grid, or the checkerboard."""
    return {"squares": spec.squares, "charuco": spec.charuco.squares if spec.charuco else None,
            "circles_grid": spec.circles_grid}.get(kind, spec.checkerboard)


def check_views(spec: Spec) -> None:
    """Before anything renders: each group's nearest image (the largest in the frame) draws its pose as its render
    will (``job_pose``: a pure function of the job), so no render stops half-way on a pose no draw can meet.
    One line naming the group and a distance at which the board or target fits centred and untilted (the draw's
    last resort)."""
    for g in spec.groups:
        if g.poses is not None or not g.count:
            continue
        job = spec.jobs[g.first_index + int(np.argmin(g.distances_cm))]
        pts, d = view_points(spec, job), job.distance_cm / 100.0
        try:
            job_pose(job, job.camera, pts)
            continue
        except InputError:
            pass
        def fits(z: float) -> bool:
            return in_view(job.camera, Pose(z, 0.0, 0.0, 0.0, 0.0, 0.0), pts)

        lo, need = d, d
        while need < 100.0 * d and not fits(need):
            lo, need = need, need * 1.25
        for _ in range(30):  # the nearest distance that fits, to well under a centimetre
            mid = 0.5 * (lo + need)
            lo, need = (lo, mid) if fits(mid) else (mid, need)
        what = "the target's shapes do" if job.kind == "target" else "the board does"
        raise InputError(f"{spec.name} group {g.name!r}: {what} not fit in the image at {d:.2f} m (image "
                         f"{job.name}) in any pose the draw tries; start its distance_range_cm at "
                         f"{int(np.ceil(need * 100.0))} or more (where it fits centred and untilted), or make "
                         f"{'them' if job.kind == 'target' else 'it'} smaller")


_PAIRED_VIEW: dict = {}


def paired_view_outline(spec: Spec, size_m: float) -> np.ndarray:
    """Board points (N, 3) the view check of every paired design cell uses: the union of every paired
    target cell's view points (its shapes' outlines and the square that bounds a preset's circle), so a
    slot draws one pose whatever shapes a cell shows.  Cells that all show the same shapes get the same
    points as each alone (the union only repeats them): the poses they drew before stay."""
    key = (spec.identity_sha256, float(size_m))
    if key not in _PAIRED_VIEW:
        pts = [view_outline_local(g.target, size_m, paired=True) for g in spec.groups
               if g.paired and g.kind == "target"]
        _PAIRED_VIEW[key] = np.unique(np.concatenate(pts), axis=0)
    return _PAIRED_VIEW[key]


def target_pose(spec: Spec, job: Job, camera: Camera) -> Pose:
    """The pose of a target job: a paired design cell checks the view with every cell's shapes
    (``paired_view_outline``), any other job with its own."""
    return job_pose(job, camera, view_points(spec, job))


def versions(variant: str) -> dict:
    import cv2
    import drjit
    import mitsuba

    return {"edgetruth": __version__, "mitsuba": mitsuba.__version__, "drjit": drjit.__version__,
            "variant": variant, "numpy": np.__version__, "opencv": cv2.__version__,
            "python": platform.python_version()}


# --- one image ----------------------------------------------------------------------
def render_job(spec: Spec, job: Job, crop=None, timings: dict | None = None):
    """Render one job -> (radiance float32 (H, W), image file pixels (H, W) uint16 or uint8, ground-truth dict)."""
    import mitsuba as mi

    from edgetruth.render.sensor.capture import capture
    from edgetruth.render.scene.edge_band import render_edge_band
    from edgetruth.render.optics.prediction import field_height, predicted_mtf50

    camera = job.camera
    sensor = job.sensor
    settings = replace(spec.render, exposure_s=sensor.exposure_s) if camera.moving else spec.render
    # a design cell renders its unit's radiance at the unit's irradiance and scales it (light transport
    # is linear in emitted power): every cell of a unit shares one render, whatever order they come in
    e_render = job.unit_irradiance_w_m2 if job.unit_irradiance_w_m2 is not None else job.irradiance_w_m2
    if job.kind == "target":
        size_m = spec.target_size_m
        # paired cells share the pose whatever the target: the view check uses every cell's shapes
        pose = target_pose(spec, job, camera)
        rig = get_rig("target", camera, settings, size_m, crop)
        le = rig.set_state(job.target, pose, e_render, job.light_position_m)
        gt = target_ground_truth(camera, pose, job.target, size_m, exposure_s=sensor.exposure_s)
        cx, cy = gt["centre"]["distorted_px"][0]
        h = float(field_height(camera, cx, cy))
        gt["optics_at_target"] = {"field_height": h, "defocus_radius_px": gt["defocus_radius_px"],
                                  "mtf50_cy_px": predicted_mtf50(camera, h, gt["defocus_radius_px"]),
                                  "meaning": "analytic MTF50 (pixel x PSF x defocus disk) at the target centre"}
    elif job.kind == "squares":
        board = spec.squares
        pose = job_pose(job, camera, view_points(spec, job))
        rig, le, bend, sag = _board_state(job, "squares", camera, settings, board, crop, pose, e_render)
        gt = squares_ground_truth(camera, pose, board, bend, sag)
    elif job.kind == "circles_grid":
        from edgetruth.render.scene.circles_truth import circles_ground_truth

        board = spec.circles_grid
        pose = job_pose(job, camera, view_points(spec, job))
        rig, le, bend, sag = _board_state(job, "circles_grid", camera, settings, board, crop, pose, e_render)
        gt = circles_ground_truth(camera, pose, board)
    elif job.kind == "charuco":  # rendered as its dark squares and marker cells (render.scene.charuco)
        from edgetruth.render.scene.charuco_truth import charuco_ground_truth

        board = spec.charuco.squares
        pose = job_pose(job, camera, view_points(spec, job))
        rig, le, bend, sag = _board_state(job, "squares", camera, settings, board, crop, pose, e_render)
        gt = charuco_ground_truth(camera, pose, spec.charuco, bend, sag)
    else:
        board = spec.checkerboard
        if settings.checkerboard_spp:  # the board's own spp; the JSON's render.spp says what was used
            settings = replace(settings, spp=settings.checkerboard_spp, checkerboard_spp=0)
        pose = job_pose(job, camera, view_points(spec, job))
        rig, le, bend, sag = _board_state(job, "checkerboard", camera, settings, board, crop, pose, e_render)
        gt = checker_ground_truth(camera, pose, board, bend, sag)
    key = (spec.identity_sha256, job.radiance_unit, job.slot, crop)
    t0 = time.perf_counter()
    if job.slot is not None and _radiance_cache.get("key") == key:
        radiance, band = _radiance_cache["radiance"], _radiance_cache["band"]
        reused, render_s = True, 0.0
    else:
        band = None
        if job.kind == "target" and settings.edge_mode == "frame":  # no full-frame render: the composite
            from edgetruth.render.scene.shading_frame import render_target_frame

            radiance, band = render_target_frame(camera, settings, job, pose, gt, crop, e_render)
            band.pop("render_s")
            render_s = time.perf_counter() - t0
        elif job.kind != "target" and settings.board_mode == "frame":  # a flat board: the composite
            from edgetruth.render.scene.board_frame import render_board_job

            radiance, band = render_board_job(camera, settings, board, pose, crop, job.render_seed, e_render,
                                              job.light_position_m)
            band.pop("render_s")
            render_s = time.perf_counter() - t0
        else:
            radiance = rig.render(job.render_seed)
            render_s = time.perf_counter() - t0
        if job.kind == "target" and settings.edge_spp and band is None:  # part of the unit's radiance: cells reuse it
            band = render_edge_band(radiance, camera, settings, job, pose, gt, crop, e_render)
            render_s += band.pop("render_s")
        reused = False
        if job.slot is not None:
            _radiance_cache.update(key=key, radiance=radiance, band=band)
    if timings is not None:
        timings["render_s"] = timings.get("render_s", 0.0) + render_s
        timings["reused"] = timings.get("reused", 0) + int(reused)
    scale = job.irradiance_w_m2 / e_render
    if scale != 1.0:
        radiance = (radiance * np.float32(scale)).astype(np.float32)
        le *= scale
    image, captured = capture(radiance, camera, sensor, make_rng(job.seed, SENSOR_STREAM), name=job.name, crop=crop)
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
        **captured,
        "render": {**settings.to_dict(), "integrator": "direct (emitter sampling only)", "rfilter": "box",
                   "film": "hdrfilm float32", "crop": list(crop) if crop else None,
                   "distortion": "exact, per-ray inverse Brown-Conrady in a Python sensor plugin",
                   "psf": rig.psf_description(), "edge_band": band,
                   "radiance_meaning": "EXR = scene radiance times the lens's relative illumination (the ray "
                                       "weights), integrated over pixel (x) PSF: photons = EXR x photons_per_radiance",
                   **sample_passes_note(mi.variant(), settings.sampler)},
        "versions": versions(mi.variant()),
    }
    return radiance, image, full
