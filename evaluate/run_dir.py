"""Run directories, shared by every study: ``run.json`` says what made one.

A directory that exists, is not empty and has no ``run.json`` is refused, so a run never
writes report files into a dataset or any other folder of the user's; a run of another kind
is refused too; the same kind re-opens it (to resume).
"""
from __future__ import annotations

from datetime import datetime, timezone
from pathlib import Path

from edgetruth import __version__
from edgetruth.errors import InputError
from edgetruth.fileio import check_output_dir, read_json, write_json

RUN_MARKER = "run.json"


def utc_stamp() -> str:
    return datetime.now(timezone.utc).strftime("%Y%m%dT%H%M%SZ")


def check_run_dir(out: str | Path, kind: str, option: str = "-o") -> Path:
    """Refuse (without creating anything) a file, or a non-empty directory that is not a ``kind`` run."""
    out = check_output_dir(out, option)
    marker = out / RUN_MARKER
    if out.is_dir() and any(out.iterdir()):
        if not marker.is_file():
            raise InputError(f"{option} {out}: exists, is not empty and is not an edgetruth run directory (no "
                             f"{RUN_MARKER}); choose a new directory, or an earlier run's to resume it")
        try:
            old = read_json(marker)
        except InputError:
            raise InputError(f"{marker}: unreadable; choose a new run directory") from None
        if old.get("kind") != kind:
            raise InputError(f"{option} {out}: holds an `edgetruth {old.get('kind')}` run, not `{kind}`; "
                             "choose a new directory")
    return out


def prepare_run_dir(out: str | Path, kind: str, settings: dict, option: str = "-o") -> Path:
    """Create (or re-open, to resume) a run directory; refuse a file or a foreign non-empty directory."""
    out = check_run_dir(out, kind, option)
    marker = out / RUN_MARKER
    out.mkdir(parents=True, exist_ok=True)
    write_json(marker, {"kind": kind, "edgetruth": __version__, "settings": settings, "updated_utc": utc_stamp()})
    return out


def check_same_settings(out: str | Path, kind: str, settings: dict, what: str, option: str = "-o") -> Path:
    """``check_run_dir``, and refuse a ``kind`` run made with other ``settings`` (a study that can only
    be resumed or re-made with its own settings); ``what`` names it in the message."""
    out = check_run_dir(out, kind, option)
    marker = out / RUN_MARKER
    if marker.is_file():
        old = read_json(marker).get("settings", {})
        if {k: old.get(k) for k in settings} != settings:
            diff = [k for k in settings if old.get(k) != settings[k]]
            raise InputError(f"{option} {out}: holds {what} of other {', '.join(diff)}; choose a new directory "
                             "(or the same settings to resume or re-make it)")
    return out
