"""Shipped data and default locations.

Shipped specs (``scenes/*.toml``) and assets (``assets/``: entropy thresholds,
cameras) are package data of ``edgetruth.scenes`` and ``edgetruth.assets``, read
through ``importlib.resources`` so they are found the same way from a checkout
and from an installed wheel.  A missing shipped file is an error (a broken
install), never a silent default.

Outputs go under the *current directory* by default (``./runs/...``), never into
the package.
"""
from __future__ import annotations

import subprocess
from importlib import resources as _res
from pathlib import Path

from edgetruth.errors import InputError

SCENES_PACKAGE = "edgetruth.scenes"
ASSETS_PACKAGE = "edgetruth.assets"
THRESHOLDS_NAME = "entropy_thresholds.json"


def _dir(package: str) -> Path:
    # files() of a package that lives on disk (checkout, wheel install) is a real directory
    return Path(str(_res.files(package)))


def scenes_dir() -> Path:
    return _dir(SCENES_PACKAGE)


def assets_dir() -> Path:
    return _dir(ASSETS_PACKAGE)


def shipped_spec_names() -> list[str]:
    return sorted(p.stem for p in scenes_dir().glob("*.toml"))


def shipped_camera_names() -> list[str]:
    return sorted(p.stem for p in (assets_dir() / "cameras").glob("*.toml"))


def shipped_spec(name: str) -> Path:
    p = scenes_dir() / f"{name}.toml"
    if not p.is_file():
        raise InputError(f"spec {name!r} not found; shipped specs: {', '.join(shipped_spec_names()) or 'NONE'}"
                         + ("" if shipped_spec_names() else " (broken install: reinstall edgetruth)")
                         + "; or give a path to a TOML file")
    return p


def shipped_camera(name: str) -> Path:
    p = assets_dir() / "cameras" / f"{name}.toml"
    if not p.is_file():
        names = shipped_camera_names()
        raise InputError(f"camera {name!r} not found; shipped cameras: {', '.join(names) or 'NONE (broken install)'}"
                         "; or give a path to a camera TOML (relative to the spec's folder)")
    return p


def shipped_thresholds() -> Path:
    """``assets/entropy_thresholds.json``; an InputError if the install lacks it."""
    p = assets_dir() / THRESHOLDS_NAME
    if not p.is_file():
        raise InputError(f"shipped entropy thresholds {p} are missing (broken install): reinstall edgetruth, "
                         "or pass --thresholds FILE from `edgetruth calibrate-thresholds`")
    return p


def shipped_real_set_names() -> list[str]:
    return sorted(p.name for p in (assets_dir() / "real").iterdir() if p.is_dir() and not p.name.startswith("_"))


def real_set(name: str) -> Path:
    """The folder of a shipped real photo set (``assets/real/<name>/``, provenance in ``assets/real/README.md``)."""
    p = assets_dir() / "real" / name
    if not p.is_dir() or name.startswith("_"):
        names = shipped_real_set_names()
        raise InputError(f"real photo set {name!r} not found; shipped sets: {', '.join(names) or 'NONE (broken install)'}"
                         "; or give the photos' paths")
    return p


def default_runs_dir() -> Path:
    """Where outputs go unless ``-o`` says otherwise: ``./runs`` under the current directory."""
    return Path.cwd() / "runs"


def source_commit() -> str:
    """The git commit of a source checkout this package runs from, else 'unknown' (installed wheel)."""
    root = Path(__file__).resolve().parent.parent
    if not ((root / ".git").exists() and (root / "pyproject.toml").is_file()):
        return "unknown"
    try:
        out = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True, timeout=5)
        return out.stdout.strip() or "unknown"
    except (OSError, subprocess.SubprocessError):
        return "unknown"
