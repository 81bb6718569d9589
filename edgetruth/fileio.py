"""File I/O at the bottom of the house: atomic writes, JSON/TOML reading, hashes, path checks.

Every writer writes a temporary file in the destination directory (``.tmp-PID-NAME``)
and renames it into place with ``os.replace``: an interrupted run never leaves a
truncated file under a final name.  The path checks turn every bad input or output
path into one ``InputError`` naming the path and the fix, *before* long work starts.
"""
from __future__ import annotations

import hashlib
import json
import os
import stat
import sys
from pathlib import Path

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - python 3.10
    import tomli as tomllib

from edgetruth.errors import InputError

TMP_PREFIX = ".tmp-"


def tmp_path(path: Path) -> Path:
    """The temporary sibling a writer uses for ``path`` (keeps the suffix: some encoders pick the format from it)."""
    return path.with_name(f"{TMP_PREFIX}{os.getpid()}-{path.stem}{path.suffix}")


def is_temporary(path: Path) -> bool:
    """A writer's temporary file, left behind only by a killed run."""
    return Path(path).name.startswith(TMP_PREFIX)


def atomic_write_bytes(path: str | Path, data: bytes, fsync: bool = True) -> None:
    path = Path(path)
    tmp = tmp_path(path)
    with open(tmp, "wb") as fh:
        fh.write(data)
        if fsync:
            fh.flush()
            os.fsync(fh.fileno())
    os.replace(tmp, path)


def atomic_write_text(path: str | Path, text: str) -> None:
    atomic_write_bytes(path, text.encode(), fsync=False)


def write_json(path: str | Path, obj, indent: int | None = 1) -> None:
    atomic_write_bytes(path, (json.dumps(obj, indent=indent, sort_keys=False) + "\n").encode())


def read_json(path: str | Path):
    path = Path(path)
    check_input_file(path, "JSON file")
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise InputError(f"{path}: cannot read JSON ({exc}); re-create the file") from None


def read_toml(path: str | Path) -> dict:
    """Parse a TOML file; a syntax error becomes an ``InputError`` naming the file and line."""
    path = Path(path)
    check_input_file(path, "TOML file")
    try:
        with path.open("rb") as fh:
            return tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: invalid TOML ({exc}); fix the syntax") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot read ({getattr(exc, 'strerror', None) or exc})") from None


def sha256_bytes(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def sha256_file(path: str | Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


# --- path checks --------------------------------------------------------------------
def _a(noun: str) -> str:
    """``noun`` with its indefinite article: 'an image', 'an EXR file', 'a photo'."""
    return f"{'an' if noun[:1].lower() in 'aeiou' else 'a'} {noun}"


def check_input_file(path: str | Path, what: str = "input") -> Path:
    """``path`` exists and is a regular, readable file (a FIFO or device would block or never end)."""
    p = Path(path)
    try:
        st = p.stat()
    except FileNotFoundError:
        raise InputError(f"{p}: no such {what}; check the path") from None
    except OSError as exc:
        raise InputError(f"{p}: cannot access this {what} ({exc.strerror}); check the path") from None
    if stat.S_ISDIR(st.st_mode):
        raise InputError(f"{p}: is a directory, not {_a(what)}; pass a file")
    if not stat.S_ISREG(st.st_mode):
        on_disk = _a(what) if what.endswith("file") else f"{_a(what)} file"
        raise InputError(f"{p}: not a regular file (a pipe, socket or device); pass {on_disk} on disk")
    if not os.access(p, os.R_OK):
        raise InputError(f"{p}: {what} is not readable; fix its permissions")
    return p


def _first_existing_ancestor(p: Path) -> Path:
    q = p
    while not q.exists():
        if q.parent == q:
            break
        q = q.parent
    return q


def _same_file(a: Path, b: Path) -> bool:
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def check_output_file(path: str | Path, option: str = "-o", inputs=(), make_parents: bool = False) -> Path:
    """An output file we may (atomically) write: not a directory, parent a writable directory, not
    one of ``inputs``.  ``make_parents`` allows a parent that does not exist yet (created later)."""
    p = Path(path)
    if p.is_dir():
        raise InputError(f"{option} {p}: is a directory; give a file name such as {p / 'out'}")
    if p.exists() and not p.is_file():
        raise InputError(f"{option} {p}: exists and is not a regular file; choose another name")
    for q in inputs:
        if q is not None and (_same_file(p, Path(q)) or p.resolve() == Path(q).resolve()):
            raise InputError(f"{option} {p}: is also the input {q}; writing it would destroy the input, "
                             "choose another output name")
    parent = p.parent
    anc = _first_existing_ancestor(parent)
    if not anc.is_dir():
        raise InputError(f"{option} {p}: {anc} is a file, not a directory; choose an output path in a directory")
    if anc != parent and not make_parents:
        raise InputError(f"{option} {p}: directory {parent} does not exist; create it first")
    if not os.access(anc, os.W_OK | os.X_OK):
        raise InputError(f"{option} {p}: directory {anc} is not writable; choose a writable location")
    return p


def check_output_dir(path: str | Path, option: str = "-o") -> Path:
    """An output directory we may create or write into: not a file, under a writable directory."""
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise InputError(f"{option} {p}: is a file, not a directory; choose a directory path")
    anc = _first_existing_ancestor(p)
    if not anc.is_dir():
        raise InputError(f"{option} {p}: {anc} is a file, not a directory; choose another location")
    if not os.access(anc, os.W_OK | os.X_OK):
        raise InputError(f"{option} {p}: {anc} is not writable; fix its permissions or choose another location")
    return p


def make_output_dir(path: str | Path, option: str = "-o") -> Path:
    p = check_output_dir(path, option)
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"{option} {p}: cannot create the directory ({exc.strerror}); choose a writable location") from None
    return p
