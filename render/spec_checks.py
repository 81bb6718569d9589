"""Value checks for render specs: every bad value becomes one ``InputError`` naming the
file, the table, the key and the fix -- before anything renders or is written.

``render.spec.load_spec`` checks the *structure* (tables, known keys); this module
checks the *values* (types, ranges, existence of the camera and targets).

    spec = load_checked_spec("scenes/quick.toml")   # load_spec + these checks
"""
from __future__ import annotations

import math
import re

from edgetruth.errors import InputError

SAMPLERS = ("independent", "stratified", "multijitter", "orthogonal", "ldsampler")
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,99}$")
MAX_SPP = 1 << 16
MAX_IMAGES = 1_000_000


def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_num(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _need(ok: bool, where: str, key: str, value, fix: str) -> None:
    if not ok:
        raise InputError(f"{where}: {key} = {value!r}: {fix}")


def check_tables(path, data: dict) -> None:
    """Check the values of a parsed spec (``{"spec": {...}, "sensor": {...}, "group": [...]}``)."""
    from render.mitsuba_scene import TARGETS
    from render.sensor import sensor_from_dict

    src = str(path)
    s = data.get("spec", {})
    where = f"{src} [spec]"
    _need(isinstance(s, dict), src, "spec", s, "must be a table [spec]")
    if "name" in s:
        _need(isinstance(s["name"], str) and _NAME.match(s["name"]) and ".." not in s["name"], where, "name",
              s["name"], "use letters, digits, '_', '-', '.' only (it names the output directory)")
    if "spp" in s:
        _need(_is_int(s["spp"]) and 1 <= s["spp"] <= MAX_SPP, where, "spp", s["spp"],
              f"samples per pixel must be an integer in 1..{MAX_SPP}")
    if "sampler" in s:
        _need(s["sampler"] in SAMPLERS, where, "sampler", s["sampler"], f"choose one of {', '.join(SAMPLERS)}")
    if "camera_scale" in s:
        _need(_is_int(s["camera_scale"]) and 1 <= s["camera_scale"] <= 64, where, "camera_scale",
              s["camera_scale"], "binning factor must be an integer in 1..64")
    if "camera" in s:
        _need(isinstance(s["camera"], str) and s["camera"], where, "camera", s["camera"],
              "give a camera name (assets/cameras/NAME.toml) or a TOML path")
    if "target_size_m" in s:
        _need(_is_num(s["target_size_m"]) and 0 < s["target_size_m"] <= 10, where, "target_size_m",
              s["target_size_m"], "target size must be a number of metres in (0, 10]")
    if "checkerboard" in s:
        cb = s["checkerboard"]
        _need(isinstance(cb, dict), where, "checkerboard", cb, "must be a table {cols, rows, square_m, margin_m}")
        bad = set(cb) - {"cols", "rows", "square_m", "margin_m"}
        _need(not bad, where, "checkerboard", cb, f"unknown keys {sorted(bad)} (known: cols, rows, square_m, margin_m)")
        for k in ("cols", "rows"):
            if k in cb:
                _need(_is_int(cb[k]) and 2 <= cb[k] <= 100, where, f"checkerboard.{k}", cb[k], "must be an integer in 2..100")
        if "square_m" in cb:
            _need(_is_num(cb["square_m"]) and cb["square_m"] > 0, where, "checkerboard.square_m", cb["square_m"],
                  "must be a positive number of metres")
        if "margin_m" in cb:
            _need(_is_num(cb["margin_m"]) and cb["margin_m"] >= 0, where, "checkerboard.margin_m", cb["margin_m"],
                  "must be a number of metres >= 0")
    sensor = data.get("sensor", {})
    _need(isinstance(sensor, dict), src, "sensor", sensor, "must be a table [sensor]")
    groups = data.get("group", [])
    _need(isinstance(groups, list) and groups and all(isinstance(g, dict) for g in groups), src, "group", groups,
          "add one or more [[group]] tables")
    names: set = set()
    total = 0
    for i, g in enumerate(groups):
        where = f"{src} group {g.get('name', i)!r}"
        name = g.get("name")
        _need(isinstance(name, str) and _NAME.match(name), where, "name", name,
              "every [[group]] needs a name of letters, digits, '_', '-', '.'")
        _need(name not in names, where, "name", name, "group names must be unique")
        names.add(name)
        if "count" in g:
            _need(_is_int(g["count"]) and g["count"] >= 1, where, "count", g["count"], "must be an integer >= 1")
        if "count_per_interval" in g:
            _need(_is_int(g["count_per_interval"]) and g["count_per_interval"] >= 1, where, "count_per_interval",
                  g["count_per_interval"], "must be an integer >= 1")
        if "distance_range_cm" in g:
            r = g["distance_range_cm"]
            _need(isinstance(r, list) and len(r) == 2 and all(_is_num(v) for v in r) and 0 < r[0] <= r[1], where,
                  "distance_range_cm", r, "give [near, far] in cm with 0 < near <= far")
        if "distance_intervals_cm" in g:
            iv = g["distance_intervals_cm"]
            _need(isinstance(iv, list) and iv and all(isinstance(r, list) and len(r) == 2 and all(_is_num(v) for v in r)
                                                      and 0 < r[0] <= r[1] for r in iv),
                  where, "distance_intervals_cm", iv, "give [[near, far], ...] in cm with 0 < near <= far")
            total += len(iv) * int(g.get("count_per_interval", 10))
        else:
            total += int(g.get("count", 1)) if _is_int(g.get("count", 1)) else 0
        if "lateral_fraction" in g:
            _need(_is_num(g["lateral_fraction"]) and 0 <= g["lateral_fraction"] <= 1, where, "lateral_fraction",
                  g["lateral_fraction"], "must be a number in [0, 1]")
        for k, hi in (("tilt_max_deg", 80), ("roll_max_deg", 180)):
            if k in g:
                _need(_is_num(g[k]) and 0 <= g[k] <= hi, where, k, g[k], f"must be a number of degrees in [0, {hi}]")
        if "irradiance_w_m2" in g:
            _need(_is_num(g["irradiance_w_m2"]) and g["irradiance_w_m2"] > 0, where, "irradiance_w_m2",
                  g["irradiance_w_m2"], "must be a positive, finite number of W/m^2")
        if g.get("kind", "target") == "target" and "target" in g:
            _need(g["target"] in TARGETS, where, "target", g["target"], f"choose one of {', '.join(sorted(TARGETS))}")
        gs = g.get("sensor", {})
        _need(isinstance(gs, dict), where, "sensor", gs, "must be a table of sensor settings")
        merged = dict(sensor, **gs)
        for k, v in merged.items():
            _need(_is_num(v), f"{where} sensor", k, v, "sensor settings must be finite numbers")
        try:
            sensor_from_dict(merged)
        except InputError as exc:
            raise InputError(f"{where}: {exc}") from None
        except (TypeError, ValueError) as exc:
            raise InputError(f"{where}: sensor: {exc}") from None
    _need(total <= MAX_IMAGES, src, "images", total, f"a spec may hold at most {MAX_IMAGES} images; split it")


def check_spec(spec) -> None:
    """Check a loaded ``Spec``'s values (and that its camera loads)."""
    from render.dataset import spec_camera

    src = spec.path or spec.name
    check_tables(src, {"spec": spec.settings, "sensor": spec.sensor, "group": spec.groups})
    try:
        spec_camera(spec)
    except InputError as exc:
        raise InputError(f"{src} [spec]: {exc}") from None
    except (TypeError, ValueError, KeyError) as exc:
        raise InputError(f"{src} [spec]: camera {spec.settings.get('camera', 'default')!r} is invalid "
                         f"({exc.__class__.__name__}: {exc}); fix the camera TOML") from None


def load_checked_spec(name_or_path):
    """``load_spec`` plus the value checks; any problem is one ``InputError`` naming the file."""
    from render.spec import load_spec, load_toml, resolve_spec_path

    path = resolve_spec_path(name_or_path)
    data = load_toml(path)
    if isinstance(data, dict) and set(data) <= {"spec", "sensor", "group"}:
        check_tables(path, data)  # before expansion, which assumes sane values
    try:
        spec = load_spec(path)
    except InputError:
        raise
    except (TypeError, ValueError, KeyError, AttributeError) as exc:
        raise InputError(f"{path}: invalid spec ({exc.__class__.__name__}: {exc}); "
                         "compare with scenes/quick.toml") from None
    check_spec(spec)
    return spec


__all__ = ["check_spec", "check_tables", "load_checked_spec", "SAMPLERS"]
