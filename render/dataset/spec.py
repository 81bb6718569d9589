"""Render specs: a TOML file -> one typed, validated ``Spec`` whose images are pure functions of (spec, index).

A spec has a ``[spec]`` table (name, camera, render settings), an optional
``[sensor]`` table and one or more ``[[group]]`` tables.  ``load_spec`` parses and
validates it in one pass against the key tables (``SPEC_KEYS``, ``GROUP_KEYS``,
``edgetruth.render.sensor.linear_model.SENSOR_KEYS``, ``edgetruth.render.optics.camera.CAMERA_KEYS``;
documented in ``docs/spec.md``): every problem is one ``InputError`` naming the file,
the table, the key and the fix, before anything renders.

A group shows a target on a board, a checkerboard (``[spec] checkerboard``) or a board of dark
squares (``[spec] squares``: a model file such as Zhang's ``Model.txt``, or a pattern); its poses
are drawn from ranges or listed explicitly (``poses``: R, t per image).

The camera is a shipped name (``assets/cameras/NAME.toml``) or a TOML path relative to
the spec's own folder; a group may override the keys marked per-group (f-number,
focus distance, ...) and any sensor key, so one spec can sweep them.

Image ``index`` is the pure function of (spec, index): its seed is
``image_seed(spec.name, index)``; ``spec.jobs[index]`` computes the job on demand,
so a spec of a million images costs nothing to load.
"""
from __future__ import annotations

import bisect
import functools
import hashlib
import json
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from edgetruth.errors import InputError
from edgetruth.fileio import read_toml
from edgetruth.render.optics.camera import Camera, camera_overrides, load_camera
from edgetruth.render.scene.mitsuba_scene import LIGHT_OFFSET_M, RenderSettings
from edgetruth.render.scene.pose import ROTATION_TOLERANCE, ExplicitPose, nearest_rotation
from edgetruth.render.schema import _is_num, parse_table
from edgetruth.render.sensor.linear_model import SensorModel, sensor_from_dict
from edgetruth.render.scene.target_scene import SCENE_GROUP_KEYS, scene_from_group
from edgetruth.render.scene.targets import CHECKERBOARD_KEYS, Checkerboard, SquareBoard, square_board_from_dict
from edgetruth.render.scene.circles_grid import CirclesGrid, circles_grid_from_dict

from edgetruth.render.scene.charuco import CharucoBoard, charuco_board_from_dict

from edgetruth.render.dataset.spec_keys import (  # noqa: F401  (the key tables, re-exported: spec.SPEC_KEYS)
    BOARD_KINDS, DEFAULT_IRRADIANCE_W_M2, DESIGN_KEYS, DESIGN_MODES, FACTOR_KEYS, GROUP_KEYS, GROUP_ONLY_KEYS, KINDS,
    LEVEL_KEYS, MAX_IMAGES, MAX_SPP, POSE_KEYS, SAMPLERS, SPEC_KEYS)


def image_seed(spec_name: str, index: int) -> int:
    """A 31-bit seed from SHA-256 of (spec name, image index): stable across runs and machines."""
    return key_seed(spec_name, str(index))


def key_seed(spec_name: str, key: str) -> int:
    """A 31-bit seed from SHA-256 of (spec name, key): stable across runs and machines."""
    digest = hashlib.sha256(f"edgetruth/{spec_name}/{key}".encode()).digest()
    return int.from_bytes(digest[:4], "little") & 0x7FFFFFFF


def slot_seed(spec_name: str, slot: int) -> int:
    """The seed of pose slot ``slot`` of a spec's design: every cell renders this pose."""
    return key_seed(spec_name, f"slot/{slot}")


@dataclass(frozen=True)
class Group:
    """One ``[[group]]``: its images share kind, target, pose ranges, light, sensor and camera."""

    name: str
    kind: str
    target: object  # a preset id (str), a ``TargetScene`` (the group's own scene) or None (not a target)
    first_index: int
    distances_cm: tuple  # one per image, stratified (see ``_distances_cm``)
    lateral_fraction: float
    tilt_max_deg: float
    roll_max_deg: float
    irradiance_w_m2: float
    sensor: SensorModel
    camera: Camera
    camera_overrides: dict = field(default_factory=dict)
    sensor_overrides: dict = field(default_factory=dict)
    #: paired design cells only: {factor: level} and the radiance unit (cells that differ only in light
    #: power and sensor settings share one radiance render per pose slot)
    levels: dict | None = None
    base_levels: dict | None = None
    radiance_unit: int | None = None
    unit_irradiance_w_m2: float | None = None
    #: explicit poses (``ExplicitPose``, in the rendering's board frame: centred on the board), one per image
    poses: tuple | None = None
    light_position_m: tuple | None = None  # None: ``LIGHT_OFFSET_M``
    #: the board's curl (coefficients, mm; ``render.scene.bend``), or None: flat
    board_bend_mm: tuple | None = None

    @property
    def count(self) -> int:
        return len(self.distances_cm)

    @property
    def paired(self) -> bool:
        """Image k of this group is pose slot k of the spec's design (shared with the other cells)."""
        return self.levels is not None


@dataclass(frozen=True)
class Job:
    """Image ``index`` of a spec: what to render (a pure function of the spec and the index)."""

    index: int
    name: str
    group: str
    kind: str
    seed: int
    distance_cm: float
    target: object  # a preset id (str), a ``TargetScene`` or None
    lateral_fraction: float
    tilt_max_deg: float
    roll_max_deg: float
    irradiance_w_m2: float
    sensor: SensorModel
    camera: Camera
    #: the pose's seed: the image's own, or its design slot's (shared by every cell)
    pose_seed: int = 0
    #: the Monte-Carlo seed of the radiance render (shared by the cells of a radiance unit)
    render_seed: int = 0
    slot: int | None = None
    levels: dict | None = None
    base_levels: dict | None = None
    radiance_unit: int | None = None
    #: the radiance of this image is the unit's render at ``unit_irradiance_w_m2``, scaled by
    #: irradiance_w_m2 / unit_irradiance_w_m2 (light transport is linear in emitted power)
    unit_irradiance_w_m2: float | None = None
    #: an explicit pose (``ExplicitPose``, rendering board frame), or None: drawn from the pose seed
    pose: ExplicitPose | None = None
    light_position_m: tuple | None = None
    board_bend_mm: tuple | None = None


class Jobs:
    """``spec.jobs``: a read-only sequence of ``Job`` computed on demand (``len``, index, iterate)."""

    def __init__(self, spec: "Spec"):
        self._spec = spec
        self._starts = [g.first_index for g in spec.groups]

    def __len__(self) -> int:
        return self._spec.n_images

    def __getitem__(self, index: int) -> Job:
        n = len(self)
        if not isinstance(index, (int, np.integer)):
            raise TypeError("spec.jobs takes an integer index")
        index = int(index)
        if index < 0:
            index += n
        if not 0 <= index < n:
            raise IndexError(f"image {index} out of range: {self._spec.name!r} has images 0-{n - 1}")
        g = self._spec.groups[bisect.bisect_right(self._starts, index) - 1]
        k = index - g.first_index
        seed = image_seed(self._spec.name, index)
        if g.paired:
            pose_seed = slot_seed(self._spec.name, k)
            render_seed = key_seed(self._spec.name, f"slot/{k}/unit/{g.radiance_unit}")
        else:
            pose_seed = render_seed = seed
        return Job(index=index, name=f"{index:04d}_{g.name}", group=g.name, kind=g.kind,
                   seed=seed, distance_cm=float(g.distances_cm[k]), target=g.target,
                   lateral_fraction=g.lateral_fraction, tilt_max_deg=g.tilt_max_deg, roll_max_deg=g.roll_max_deg,
                   irradiance_w_m2=g.irradiance_w_m2, sensor=g.sensor, camera=g.camera, pose_seed=pose_seed,
                   render_seed=render_seed, slot=k if g.paired else None, levels=g.levels, base_levels=g.base_levels,
                   radiance_unit=g.radiance_unit, unit_irradiance_w_m2=g.unit_irradiance_w_m2,
                   pose=None if g.poses is None else g.poses[k], light_position_m=g.light_position_m,
                   board_bend_mm=g.board_bend_mm)

    def __iter__(self):
        for i in range(len(self)):
            yield self[i]


@dataclass(frozen=True)
class Spec:
    """A parsed, validated render spec (``load_spec``): what every image of a dataset is made from.

    Attributes
    ----------
    name : str
        The spec's name; it seeds every random draw, so two specs of different names share no seed.
    description : str
        Free text from ``[spec] description``.
    path : pathlib.Path or None
        The TOML file it was read from.
    camera : edgetruth.render.optics.camera.Camera
        The spec's camera (binned by ``camera_scale``); groups may override per-group keys.
    groups : tuple
        The ``[[group]]`` tables (and a ``[design]``'s cells), each a run of consecutive images.
    n_images : int
        How many images the spec makes.
    jobs : sequence of Job
        ``spec.jobs[i]`` is image i: its name, group, kind, seeds, distance (cm), pose draw, camera, sensor.
    """

    name: str
    description: str
    path: Path | None
    camera: Camera  # the spec's camera (binned by camera_scale); groups may override per-group keys
    camera_ref: str
    camera_scale: int
    render: RenderSettings
    target_size_m: float
    checkerboard: Checkerboard
    sensor: SensorModel
    groups: tuple
    text_sha256: str = ""
    squares: SquareBoard | None = None
    circles_grid: CirclesGrid | None = None
    charuco: CharucoBoard | None = None

    @property
    def n_images(self) -> int:
        """How many images the spec makes (every group's and design cell's)."""
        g = self.groups[-1]
        return g.first_index + g.count

    @property
    def jobs(self) -> Jobs:
        """``spec.jobs[i]``: image i's ``Job`` (name, group, kind, seeds, distance in cm, camera, sensor), made on demand."""
        return Jobs(self)

    def group(self, name: str) -> Group:
        for g in self.groups:
            if g.name == name:
                return g
        raise KeyError(name)

    def resolved(self) -> dict:
        """Every value that determines the images (no paths): what ``identity_sha256`` hashes.  The
        keys of the squares board, explicit poses and the light's place appear only when used (the
        hashes of specs without them are unchanged)."""
        groups = []
        for g in self.groups:
            d = {"name": g.name, "kind": g.kind, "target": str(g.target) if g.target is not None else None,
                 "count": g.count,
                 "distances_cm": list(g.distances_cm), "lateral_fraction": g.lateral_fraction,
                 "tilt_max_deg": g.tilt_max_deg, "roll_max_deg": g.roll_max_deg,
                 "irradiance_w_m2": g.irradiance_w_m2, "sensor": g.sensor.identity(),
                 "camera": g.camera.to_dict(), "levels": g.levels, "radiance_unit": g.radiance_unit,
                 "unit_irradiance_w_m2": g.unit_irradiance_w_m2}
            if g.poses is not None:
                d["poses"] = [p.to_dict() for p in g.poses]
            if g.light_position_m is not None:
                d["light_position_m"] = list(g.light_position_m)
            if g.board_bend_mm is not None:
                d["board_bend_mm"] = list(g.board_bend_mm)
            if g.target is not None and not isinstance(g.target, str):  # a scene of its own
                d["scene"] = g.target.resolved()
            groups.append(d)
        out = {"name": self.name, "camera": self.camera.to_dict(), "camera_scale": self.camera_scale,
               "render": self.render.to_dict(), "target_size_m": self.target_size_m,
               "checkerboard": asdict(self.checkerboard), "sensor": self.sensor.identity(), "groups": groups}
        if any(g.kind == "squares" for g in self.groups):
            out["squares"] = self.squares.resolved()
        if any(g.kind == "circles_grid" for g in self.groups):
            out["circles_grid"] = self.circles_grid.resolved()
        if any(g.kind == "charuco" for g in self.groups):
            out["charuco"] = self.charuco.resolved()
        return out

    def units(self) -> list[list[int]]:
        """Image indices that share one radiance render (a design slot of one radiance unit); every
        other image is a unit of its own.  Rendering a unit's images together renders it once."""
        out, by_key = [], {}
        for g in self.groups:
            for k in range(g.count):
                i = g.first_index + k
                if g.paired:
                    key = (g.radiance_unit, k)
                    if key not in by_key:
                        by_key[key] = len(out)
                        out.append([])
                    out[by_key[key]].append(i)
                else:
                    out.append([i])
        return out

    @functools.cached_property  # the spec is frozen; hashing a million-image spec takes ~1 s
    def identity_sha256(self) -> str:
        """SHA-256 of the resolved spec: equal for any two specs that render the same images."""
        text = json.dumps(self.resolved(), sort_keys=True, default=float)
        return hashlib.sha256(text.encode()).hexdigest()


def resolve_spec_path(name_or_path: str | Path) -> Path:
    """``standard`` -> the shipped ``scenes/standard.toml``; anything with a suffix or a slash is a path."""
    from edgetruth.resources import shipped_spec

    s = str(name_or_path)
    if Path(s).suffix != ".toml" and "/" not in s and "\\" not in s:
        return shipped_spec(s)
    return Path(s).expanduser()


def _distances_cm(seed: int, g: dict) -> tuple:
    """Stratified distances: one per equal sub-interval, uniform inside it, from a group-level stream
    so the list is stable."""
    rng = np.random.Generator(np.random.PCG64(seed))
    if g.get("distance_intervals_cm") is not None:
        n = g["count_per_interval"]
        out = []
        for a, b in g["distance_intervals_cm"]:
            out.append(a + (np.arange(n) + rng.uniform(size=n)) * (b - a) / n)
        return tuple(float(v) for v in np.concatenate(out))
    a, b = g["distance_range_cm"]
    n = g["count"]
    return tuple(float(v) for v in a + (np.arange(n) + rng.uniform(size=n)) * (b - a) / n)


def _design_cells(design, where: str) -> list[tuple[dict, dict]]:
    """The cells of a [design] as (group table, {factor: level}) pairs, in a stable order."""
    import itertools

    d = parse_table(design, DESIGN_KEYS, where)
    factors = design.get("factor")
    if not (isinstance(factors, list) and factors and all(isinstance(f, dict) for f in factors)):
        raise InputError(f"{where}: factor: give one or more [[design.factor]] tables with a name and levels")
    pose = {k: design[k] for k in POSE_KEYS if k in design}
    parsed, fnames = [], set()
    for i, f in enumerate(factors):
        fw = f"{where} factor {f.get('name', i)!r}"
        fv = parse_table(f, FACTOR_KEYS, fw)
        if fv["name"] in fnames:
            raise InputError(f"{fw}: name = {fv['name']!r}: factor names must be unique")
        fnames.add(fv["name"])
        levels = f["levels"]
        if not (isinstance(levels, list) and levels and all(isinstance(v, dict) for v in levels)):
            raise InputError(f"{fw}: levels: give a list of tables [{{name = ..., ...}}, ...]")
        lv = []
        for j, level in enumerate(levels):
            lw = f"{fw} level {level.get('name', j)!r}"
            parse_table(level, LEVEL_KEYS, lw)
            if level["name"] in {x["name"] for x in lv}:
                raise InputError(f"{lw}: level names must be unique within a factor")
            lv.append(level)
        parsed.append((fv["name"], lv))
    if d["mode"] == "full":
        combos = list(itertools.product(*[range(len(lv)) for _, lv in parsed]))
    else:  # the base cell, then each other level of one factor at a time
        combos = [tuple(0 for _ in parsed)]
        for fi, (_, lv) in enumerate(parsed):
            combos += [tuple(j if q == fi else 0 for q in range(len(parsed))) for j in range(1, len(lv))]
    base = {fname: lv[0]["name"] for fname, lv in parsed}
    cells = []
    for combo in combos:
        table = {"kind": d["kind"], **pose}
        levels = {}
        for (fname, lv), j in zip(parsed, combo):
            level = dict(lv[j])
            levels[fname] = level.pop("name")
            for k, v in level.items():
                if isinstance(v, dict) and isinstance(table.get(k), dict):  # sensor/camera: merge
                    table[k] = {**table[k], **v}
                elif k in table and k != "kind":
                    raise InputError(f"{where}: key {k} is set by two factors ({', '.join(levels)}); "
                                     "let one factor own each key")
                else:
                    table[k] = v
        table["name"] = "_".join(levels.values())
        cells.append((table, {"levels": levels, "base": base}))
    kinds = {t["kind"] for t, _ in cells}
    if len(kinds) > 1 and "target" in kinds:
        raise InputError(f"{where}: a level's kind names a board, so every cell must be a board; set the design's "
                         f"kind to a board ({', '.join(BOARD_KINDS)}) or drop the level's kind")
    return cells


def _n_images(g: dict) -> int:
    if g.get("poses") is not None:
        return len(g["poses"])
    if g.get("distance_intervals_cm") is not None:
        return len(g["distance_intervals_cm"]) * g["count_per_interval"]
    return g["count"]


def parse_poses(poses: list, unit_m: float, where: str) -> tuple:
    """Explicit poses -> ``ExplicitPose`` (nearest rotation, t in metres), each checked: R a 3 x 3 rotation
    (within ``ROTATION_TOLERANCE``, det +1), t three numbers."""
    out = []
    for i, p in enumerate(poses):
        pw = f"{where}: poses[{i}]"
        unknown = sorted(set(p) - {"R", "t"})
        if unknown or "R" not in p or "t" not in p:
            raise InputError(f"{pw}: give exactly R (3 x 3, by rows) and t (3 numbers)"
                             + (f"; unknown key(s) {', '.join(unknown)}" if unknown else ""))
        r, t = p["R"], p["t"]
        if not (isinstance(r, list) and len(r) == 3 and all(isinstance(row, list) and len(row) == 3
                                                            and all(_is_num(v) for v in row) for row in r)):
            raise InputError(f"{pw}: R = {r!r}: give a 3 x 3 matrix by rows, [[r11, r12, r13], [r21, ...], [...]]")
        if not (isinstance(t, list) and len(t) == 3 and all(_is_num(v) for v in t)):
            raise InputError(f"{pw}: t = {t!r}: give [tx, ty, tz] (in pose_unit_m)")
        rm = np.asarray(r, dtype=np.float64)
        dev = float(np.max(np.abs(rm.T @ rm - np.eye(3))))
        if dev > ROTATION_TOLERANCE or np.linalg.det(rm) <= 0:
            raise InputError(f"{pw}: R is not a rotation (max |R^T R - I| = {dev:.3g}, det = {np.linalg.det(rm):.4g}); "
                             f"give an orthonormal matrix with det +1 (to {ROTATION_TOLERANCE:g})")
        out.append(ExplicitPose.from_rt(nearest_rotation(rm), np.asarray(t, dtype=np.float64) * unit_m))
    return tuple(out)


def _check_explicit_poses(poses: tuple, g: dict, spec_parts: dict, camera: Camera, where: str) -> None:
    """The board must lie in front of the camera; a target's outline in the image."""
    from edgetruth.render.scene.ground_truth import outline_in_view, view_outline_local

    for i, pose in enumerate(poses):
        if g["kind"] == "squares":
            pts = spec_parts["squares"].plate_corners_local()
        elif g["kind"] == "charuco":
            pts = spec_parts["charuco"].squares.plate_corners_local()
        elif g["kind"] == "checkerboard":
            pts = spec_parts["checkerboard"].plate_corners_local()
        elif g["kind"] == "circles_grid":
            pts = spec_parts["circles_grid"].plate_corners_local()
        else:
            pts = view_outline_local(spec_parts["scene"] or g["target"], spec_parts["target_size_m"])
        cam_pts = pose.to_camera(pts)
        if np.any(cam_pts[:, 2] <= 0):
            raise InputError(f"{where}: poses[{i}]: the board reaches behind the camera (z <= 0); check R, t and "
                             "pose_unit_m (the board frame's z axis points away from the camera)")
        if g["kind"] == "target" and not outline_in_view(camera, cam_pts, 0.0):
            raise InputError(f"{where}: poses[{i}]: the target's outline leaves the image; move it into view")


#: Dr.Jit's LLVM backend splits a render into blocks of 2^14 samples: with a power-of-two spp up to
#: that, a pixel's samples never straddle two blocks, so the film's atomic adds happen in one order
#: whatever the thread count (any other spp leaves ~1/1000 pixels differing in the last bit).
MAX_REPRODUCIBLE_SPP = 1 << 14
#: Samplers that round the sample count up to a near-square grid (multijitter: 32 -> 5 x 7 = 35,
#: 512 -> 22 x 24 = 528): only a power of four stays a power of two for them.
SQUARE_GRID_SAMPLERS = ("multijitter", "stratified")


def _check_sample_counts(s: dict, where: str) -> None:
    """spp and edge_spp must be powers of two up to ``MAX_REPRODUCIBLE_SPP`` (of four for the
    samplers that round to a square grid): byte-identical renders whatever the thread count."""
    square = s.get("sampler") in SQUARE_GRID_SAMPLERS
    base, what = (4, "a power of four") if square else (2, "a power of two")
    for key in ("spp", "edge_spp", "checkerboard_spp"):
        n = s.get(key, 0)
        if key != "spp" and n == 0:
            continue
        ok = n & (n - 1) == 0 and (not square or (n.bit_length() - 1) % 2 == 0)
        if not ok or n > MAX_REPRODUCIBLE_SPP:
            lo = 1
            while lo * base <= min(n, MAX_REPRODUCIBLE_SPP):
                lo *= base
            hint = f"use {lo} or {base * lo}" if n < MAX_REPRODUCIBLE_SPP else f"use at most {MAX_REPRODUCIBLE_SPP}"
            extra = f" (the {s['sampler']} sampler rounds other counts to a square grid)" if square else ""
            raise InputError(f"{where}: {key} = {n}: {hint} -- {what} up to {MAX_REPRODUCIBLE_SPP}{extra} keeps "
                             "renders byte-identical whatever the number of threads and workers")


def _edge_frame_obstacle(groups) -> tuple[str, str] | None:
    """(group name, why) where ``edge_mode = "frame"`` (or "analytic") cannot render a group's target images, or
    None: their scope is ``edgetruth.render.scene.edge_band.band_coverage``'s, the preset targets T1..T4 and a
    static camera."""
    for g in groups:
        if g.kind == "target" and (g.camera.moving or not isinstance(g.target, str)):
            return g.name, ("its camera moves" if g.camera.moving else
                            "it has a scene of its own (shapes, a target_material or a texture)")
    return None


#: the board kinds ``board_mode = "frame"`` composites (boards of dark squares: ``render.scene.board_frame``)
BOARD_FRAME_KINDS = ("checkerboard", "squares", "charuco", "circles_grid")


def _board_frame_obstacle(groups) -> tuple[str, str] | None:
    """(group name, why) where ``board_mode = "frame"`` (``edgetruth.render.scene.board_frame``: flat boards of
    dark squares, a static camera) cannot render a group's boards, or None."""
    for g in groups:
        if g.kind != "target" and (g.camera.moving or g.board_bend_mm is not None or g.kind not in BOARD_FRAME_KINDS):
            return g.name, ("its camera moves" if g.camera.moving else "its board is curled"
                            if g.board_bend_mm is not None else f"it shows a {g.kind} board")
    return None


#: (spec path, text SHA-256) whose fall-back to "path" this process has said: once per spec, not per image
_FALLBACK_SAID: set = set()


def _resolve_modes(s: dict, given: dict, groups, src: str, text_sha256: str) -> None:
    """Set ``s["edge_mode"]`` and ``s["board_mode"]``.  A mode the spec names renders as named (one outside its
    scope is refused); a mode it does not name is "frame" where that is valid for every group it applies to,
    "path" where no group is of its kind (so the spec's identity is the one it always had), and otherwise "path",
    said in one line on stderr (``console.warn``)."""
    fallback = []
    edge, board = _edge_frame_obstacle(groups), _board_frame_obstacle(groups)
    if "edge_mode" in given:
        if s["edge_mode"] in ("analytic", "frame") and edge:
            raise InputError(f"{src} group {edge[0]!r}: edge_mode = \"{s['edge_mode']}\" covers the preset targets "
                             f"T1..T4 as shipped and a static camera, and {edge[1]}; set edge_mode = \"path\" "
                             "for this spec")
    elif not any(g.kind == "target" for g in groups) or edge:
        s["edge_mode"] = "path"
        if edge:
            fallback.append(f"edge_mode = \"path\" (group {edge[0]!r}: {edge[1]}; \"frame\" takes the preset "
                            "targets T1..T4 and a static camera)")
    if "board_mode" in given:
        if s["board_mode"] == "frame" and board:
            raise InputError(f"{src} group {board[0]!r}: board_mode = \"frame\" renders flat boards of squares seen "
                             f"by a static camera, and {board[1]}; set board_mode = \"path\" for this spec")
    elif all(g.kind == "target" for g in groups) or board:
        s["board_mode"] = "path"
        if board:
            fallback.append(f"board_mode = \"path\" (group {board[0]!r}: {board[1]}; \"frame\" takes flat boards "
                            "and a static camera)")
    said = (src, text_sha256)
    if fallback and said not in _FALLBACK_SAID:
        from edgetruth import console

        _FALLBACK_SAID.add(said)
        console.warn(f"{src}: renders with {' and '.join(fallback)}: the Monte-Carlo reference, not the noise-free "
                     "composite; name the mode in [spec] to silence this (docs/spec.md)")

def load_spec(name_or_path: str | Path) -> Spec:
    """Parse and validate a render spec in one pass.

    Every key is checked against the loader's key tables (docs/spec.md is generated from them).

    Parameters
    ----------
    name_or_path : str or pathlib.Path
        A shipped spec's name (``"quick"``, ``"study"``, ``"calibration"``, ...; ``edgetruth render --help``
        lists them) or a path to a TOML file; a camera it names by a relative path is read from the
        spec's folder.

    Returns
    -------
    Spec
        The typed spec; ``spec.jobs[i]`` is image i.

    Raises
    ------
    edgetruth.errors.InputError
        A missing file, an unknown table or key, or a bad value: one line naming the key and the fix.
    """
    path = resolve_spec_path(name_or_path)
    data = read_toml(path)
    src = str(path)
    unknown = sorted(set(data) - {"spec", "sensor", "group", "design"})
    if unknown:
        raise InputError(f"{src}: unknown table(s) {', '.join(unknown)}; a spec has [spec], [sensor], [[group]] "
                         "and [design]")
    s = parse_table(data.get("spec", {}), SPEC_KEYS, f"{src} [spec]")
    name = s["name"] or path.stem
    from edgetruth.render.schema import check_value

    check_value(SPEC_KEYS[0], name, f"{src} [spec] (default name from the file name)")
    board = Checkerboard(**parse_table(s["checkerboard"], CHECKERBOARD_KEYS, f"{src} [spec] checkerboard"))
    squares = square_board_from_dict(s["squares"], path.parent, f"{src} [spec] squares")
    circles = circles_grid_from_dict(s["circles_grid"], f"{src} [spec] circles_grid")
    try:
        base_camera = load_camera(s["camera"], base_dir=path.parent)
    except InputError as exc:
        raise InputError(f"{src} [spec] camera = {s['camera']!r}: {exc}") from None
    if s["camera_scale"] != 1:
        c = base_camera
        if c.width_px % s["camera_scale"] or c.height_px % s["camera_scale"]:
            raise InputError(f"{src} [spec] camera_scale = {s['camera_scale']}: {c.width_px} x {c.height_px} px is "
                             "not divisible by it; choose a divisor of both")
        base_camera = base_camera.scaled(s["camera_scale"])
    base_sensor = sensor_from_dict(data.get("sensor", {}), where=f"{src} [sensor]")
    groups_raw = data.get("group", [])
    design_cells = _design_cells(data["design"], f"{src} [design]") if "design" in data else []
    charuco = None  # built (OpenCV's layout) only for a spec that shows or names one
    if s["charuco"] or any(isinstance(g, dict) and g.get("kind") == "charuco"
                           for g in list(groups_raw) + [c for c, _ in design_cells]):
        charuco = charuco_board_from_dict(s["charuco"], f"{src} [spec] charuco")
    if not (isinstance(groups_raw, list) and all(isinstance(g, dict) for g in groups_raw)) or \
            not (groups_raw or design_cells):
        raise InputError(f"{src}: needs at least one [[group]] table or a [design] (see docs/spec.md)")
    groups, names, first = [], set(), 0
    units: dict = {}
    for i, raw in enumerate(list(groups_raw) + [c for c, _ in design_cells]):
        cell = design_cells[i - len(groups_raw)][1] if i >= len(groups_raw) else None
        levels = cell["levels"] if cell else None
        where = (f"{src} group {raw.get('name', i)!r}" if levels is None
                 else f"{src} [design] cell {raw.get('name')!r}")
        g = parse_table(raw, GROUP_KEYS, where)
        if g["name"] in names:
            raise InputError(f"{where}: name = {g['name']!r}: group names must be unique")
        names.add(g["name"])
        if g["kind"] != "target" and "target" in raw:
            raise InputError(f"{where}: target = {raw['target']!r}: a {g['kind']} group has no target; remove it")
        if g["kind"] == "circles_grid" and g.get("board_bend_mm") is not None:
            raise InputError(f"{where}: board_bend_mm: a circle grid renders flat (its circles' truth is planar); "
                             "bend a squares or checkerboard group, or remove it")
        if g["kind"] == "target" and g.get("board_bend_mm") is not None:
            raise InputError(f"{where}: board_bend_mm: a target scene's board is flat (its edge band and "
                             "shadows are planar); bend a squares or checkerboard group, or remove it")
        if g.get("poses") is not None:
            given = sorted(k for k in POSE_KEYS if k in raw)
            if given:
                raise InputError(f"{where}: poses and {', '.join(given)}: explicit poses replace the drawn ones "
                                 "(one image per pose); remove one or the other")
        elif "pose_unit_m" in raw:
            raise InputError(f"{where}: pose_unit_m applies to explicit poses; remove it or add poses")
        if g.get("distance_intervals_cm") is not None and ("count" in raw or "distance_range_cm" in raw):
            raise InputError(f"{where}: give either distance_intervals_cm (+ count_per_interval) or "
                             "distance_range_cm (+ count), not both")
        n = _n_images(g)
        if first + n > MAX_IMAGES:
            raise InputError(f"{src}: more than {MAX_IMAGES:,} images; split the spec")
        sensor = sensor_from_dict(g["sensor"], base_sensor, where=f"{where} sensor")
        cam_over = camera_overrides(g["camera"], f"{where} camera")
        camera = replace(base_camera, **cam_over) if cam_over else base_camera
        scene = None
        if g["kind"] == "target":
            scene = scene_from_group(g, raw, s["target_size_m"], g["light_position_m"], where, base_dir=path.parent)
        else:
            given = [k for k in SCENE_GROUP_KEYS if k in raw]
            if given:
                raise InputError(f"{where}: {', '.join(given)} applies to kind = \"target\" groups; remove it")
        poses = None
        if g.get("poses") is not None:
            poses = parse_poses(g["poses"], g["pose_unit_m"], where)
            if g["kind"] == "squares":  # model frame -> the rendering's board frame (centred on the squares)
                poses = tuple(p.moved_origin(squares.centre_model_m) for p in poses)
            elif g["kind"] == "charuco":  # OpenCV's board frame -> the rendering's (centred on the squares)
                poses = tuple(p.moved_origin(charuco.squares.centre_model_m) for p in poses)
            elif g["kind"] == "circles_grid":  # the object points' frame -> the board frame (centred on the circles)
                poses = tuple(p.moved_origin(circles.centre_model_m) for p in poses)
            _check_explicit_poses(poses, g, {"squares": squares, "charuco": charuco, "checkerboard": board,
                                             "circles_grid": circles,
                                             "scene": scene,
                                             "target_size_m": s["target_size_m"]}, camera, where)
        light = None if "light_position_m" not in raw else tuple(g["light_position_m"])
        unit = unit_e = None
        if levels is not None:
            # cells that differ only in light power and sensor settings share one radiance render
            key = (g["kind"], g["target"], json.dumps(camera.to_dict(), sort_keys=True), g.get("board_bend_mm"))
            if scene is not None:  # materials, shapes and lights change the radiance, not just its scale
                key += (json.dumps(scene.resolved(), sort_keys=True),)
            if camera.moving:  # the exposure sets the motion blur: part of the radiance
                key += (sensor.exposure_s,)
            unit, unit_e = units.setdefault(key, (len(units), g["irradiance_w_m2"]))
            dists = _distances_cm(key_seed(name, "design/distances"), g)  # the slots: one stream for all cells
        elif poses is not None:
            dists = tuple(100.0 * p.distance_m for p in poses)  # the board centre's z
        else:
            dists = _distances_cm(image_seed(name, -1 - first), g)  # seeded by the group's first image index
        target = (scene or g["target"]) if g["kind"] == "target" else None
        groups.append(Group(name=g["name"], kind=g["kind"], target=target,
                            first_index=first, distances_cm=dists,
                            lateral_fraction=g["lateral_fraction"], tilt_max_deg=g["tilt_max_deg"],
                            roll_max_deg=g["roll_max_deg"], irradiance_w_m2=g["irradiance_w_m2"], sensor=sensor,
                            camera=camera, camera_overrides=cam_over, sensor_overrides=dict(g["sensor"]),
                            levels=levels, base_levels=cell["base"] if cell else None, radiance_unit=unit,
                            unit_irradiance_w_m2=unit_e, poses=poses, light_position_m=light,
                            board_bend_mm=g.get("board_bend_mm")))
        first += n
    _check_sample_counts(s, f"{src} [spec]")
    text_sha256 = hashlib.sha256(path.read_bytes()).hexdigest()
    _resolve_modes(s, data.get("spec", {}), groups, src, text_sha256)
    return Spec(name=name, description=s["description"], path=path, camera=base_camera, camera_ref=s["camera"],
                camera_scale=s["camera_scale"], render=RenderSettings(spp=s["spp"], sampler=s["sampler"],
                                                                         edge_spp=s["edge_spp"],
                                                                         checkerboard_spp=s["checkerboard_spp"],
                                                                         edge_mode=s["edge_mode"],
                                                                         shading_step_px=s["shading_step_px"],
                                                                         board_mode=s["board_mode"]),
                target_size_m=s["target_size_m"], checkerboard=board, sensor=base_sensor, groups=tuple(groups),
                text_sha256=text_sha256, squares=squares, circles_grid=circles, charuco=charuco)
