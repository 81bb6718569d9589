"""Render specs: TOML files in ``scenes/`` expanded into a list of image jobs.

A spec has a ``[spec]`` table (name, kind defaults, camera, render settings) and
one or more ``[[group]]`` tables; each group expands into images.  An image job
is a plain dict, and an image is a pure function of (spec name, index): its seed
is derived from a hash of both (``image_seed``).
"""
from __future__ import annotations

import hashlib
import sys
from pathlib import Path

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - python 3.10
    import tomli as tomllib

from edgetruth.errors import InputError


def load_toml(path: str | Path) -> dict:
    """Parse a TOML file; a syntax error becomes an ``InputError`` naming the file."""
    path = Path(path)
    try:
        with path.open("rb") as fh:
            return tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: invalid TOML: {exc}") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read: {exc.strerror}") from None


def image_seed(spec_name: str, index: int) -> int:
    """A 31-bit seed from SHA-256 of (spec name, image index): stable across runs and machines."""
    digest = hashlib.sha256(f"edgetruth/{spec_name}/{index}".encode()).digest()
    return int.from_bytes(digest[:4], "little") & 0x7FFFFFFF


# --- specs ----------------------------------------------------------------------
import math
from dataclasses import dataclass, field

import numpy as np

from edgetruth.errors import require
from edgetruth.paths import SCENES_DIR

GROUP_KEYS = {
    "name", "kind", "target", "count", "count_per_interval", "distance_intervals_cm", "distance_range_cm",
    "lateral_fraction", "tilt_max_deg", "roll_max_deg", "irradiance_w_m2", "sensor",
}
SPEC_KEYS = {"name", "description", "camera", "camera_scale", "spp", "sampler", "target_size_m", "checkerboard"}
KINDS = ("target", "checkerboard")


@dataclass
class Spec:
    """A parsed spec: global settings plus groups (raw tables, validated)."""

    name: str
    path: Path | None
    settings: dict
    sensor: dict
    groups: list[dict]
    text_sha256: str = ""
    jobs: list[dict] = field(default_factory=list)


def resolve_spec_path(name_or_path: str | Path) -> Path:
    """``standard`` -> ``scenes/standard.toml``; anything with a suffix or a slash is a path."""
    s = str(name_or_path)
    path = Path(s)
    if path.suffix != ".toml" and "/" not in s:
        path = SCENES_DIR / f"{s}.toml"
    if not path.is_file():
        names = sorted(p.stem for p in SCENES_DIR.glob("*.toml"))
        raise InputError(f"spec {s!r} not found (looked for {path}); shipped specs: {', '.join(names)}")
    return path


def load_spec(name_or_path: str | Path) -> Spec:
    """Load and validate a spec, and expand it into image jobs (``spec.jobs``)."""
    path = resolve_spec_path(name_or_path)
    raw = path.read_bytes()
    data = load_toml(path)
    bad = set(data) - {"spec", "sensor", "group"}
    require(not bad, f"{path}: unknown tables {sorted(bad)} (allowed: spec, sensor, group)")
    settings = dict(data.get("spec", {}))
    bad = set(settings) - SPEC_KEYS
    require(not bad, f"{path}: [spec] has unknown keys {sorted(bad)} (known: {sorted(SPEC_KEYS)})")
    settings.setdefault("name", path.stem)
    groups = data.get("group", [])
    require(isinstance(groups, list) and groups, f"{path}: needs at least one [[group]]")
    for g in groups:
        bad = set(g) - GROUP_KEYS
        require(not bad, f"{path}: group {g.get('name', '?')!r} has unknown keys {sorted(bad)} (known: {sorted(GROUP_KEYS)})")
        require(g.get("kind", "target") in KINDS, f"{path}: group kind must be one of {KINDS}")
        require("name" in g, f"{path}: every [[group]] needs a name")
    spec = Spec(name=settings["name"], path=path, settings=settings, sensor=dict(data.get("sensor", {})),
                groups=groups, text_sha256=hashlib.sha256(raw).hexdigest())
    from render.spec_checks import check_spec  # values (types, ranges, camera) before expanding jobs

    check_spec(spec)
    spec.jobs = expand(spec)
    return spec


def _distances_cm(g: dict, rng: np.random.Generator) -> list[float]:
    """Stratified distances: ``count_per_interval`` per interval, one per equal sub-interval."""
    if "distance_intervals_cm" in g:
        out = []
        for a, b in g["distance_intervals_cm"]:
            n = int(g.get("count_per_interval", 10))
            out += [a + (k + rng.uniform()) * (b - a) / n for k in range(n)]
        return out
    a, b = g.get("distance_range_cm", (150.0, 150.0))
    n = int(g.get("count", 1))
    return [a + (k + rng.uniform()) * (b - a) / n for k in range(n)]


def expand(spec: Spec) -> list[dict]:
    """Image jobs of a spec.  Pose randomness is drawn from the job seed, so a job is a pure
    function of (spec name, index) and the spec text."""
    jobs: list[dict] = []
    for g in spec.groups:
        kind = g.get("kind", "target")
        # draw distances from a group-level stream so the list is stable
        grng = np.random.Generator(np.random.PCG64(image_seed(spec.name, -1 - len(jobs))))
        dists = _distances_cm(g, grng)
        for k, d_cm in enumerate(dists):
            index = len(jobs)
            job = {
                "index": index,
                "name": f"{index:04d}_{g['name']}",
                "group": g["name"],
                "kind": kind,
                "seed": image_seed(spec.name, index),
                "distance_cm": float(d_cm),
                "lateral_fraction": float(g.get("lateral_fraction", 0.0)),
                "tilt_max_deg": float(g.get("tilt_max_deg", 0.0)),
                "roll_max_deg": float(g.get("roll_max_deg", 0.0)),
                "irradiance_w_m2": float(g.get("irradiance_w_m2", 1.75)),
                "sensor": dict(spec.sensor, **g.get("sensor", {})),
            }
            if kind == "target":
                job["target"] = g.get("target", "T1")
            jobs.append(job)
    return jobs
