"""A dataset's record of finished images: an append-only journal compacted into ``manifest.json``.

While a render runs, the driver appends one line per finished image to ``journal.jsonl``,
synced (``fdatasync``) right after by a background thread: a constant cost per image,
however large the dataset.  At
the end (or on ``edgetruth verify``) the journal is *compacted*: merged with the manifest,
sorted by image index, written to a temporary file, synced, renamed over
``manifest.json``, and only then deleted.  A ``kill -9`` at any moment therefore leaves
a manifest that parses, plus a journal whose entries are all still to merge (merging
twice is harmless: an image's entry is the same every time).

Layouts (both plain JSON / JSON lines):

- ``manifest.json``: the header on line 1, one image entry per line, index order::

      {"format": 1, "spec": "tiny", "spec_sha256": "...", "n_images": 3, "images": {
      "0000_T2": {"index": 0, "kind": "target", ..., "files": {"exr": {"path": ..., "sha256": ...}, ...}},
      ...
      }}

  so it can be streamed (constant memory) as well as read with ``json.load``; a
  manifest in any other layout (older versions) is read whole.
- ``journal.jsonl``: a header line ``{"journal": 1, "spec_sha256": ...}``, then one
  ``{"name": ..., "entry": {...}}`` per finished image, newest last (the latest line of
  an image wins).  A torn last line (the run was killed mid-write) is ignored and cut
  off before the next append; a damaged line elsewhere is reported and ignored (its
  image is rendered again).
"""
from __future__ import annotations

import json
import os
import re
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

import numpy as np

from edgetruth.errors import InputError
from edgetruth.fileio import tmp_path

MANIFEST = "manifest.json"
JOURNAL = "journal.jsonl"
MANIFEST_FORMAT = 1
JOURNAL_FORMAT = 1
_SHA = re.compile(r"^[0-9a-f]{64}$")
_IMAGES_OPEN = ', "images": {'
_FOOTER = "}}\n"


def entry_ok(e) -> bool:
    """An image entry of the right shape: an int index and files with a path and a SHA-256 each."""
    return (isinstance(e, dict) and isinstance(e.get("index"), int) and isinstance(e.get("files"), dict)
            and all(isinstance(f, dict) and isinstance(f.get("path"), str) and _SHA.match(str(f.get("sha256", "")))
                    for f in e["files"].values()))


def new_header(spec_name: str, spec_sha256: str, n_images: int) -> dict:
    return {"format": MANIFEST_FORMAT, "spec": spec_name, "spec_sha256": spec_sha256, "n_images": int(n_images)}


def _entry_line(name: str, entry: dict) -> str:
    return json.dumps(name) + ": " + json.dumps(entry)


def _bad_manifest(path: Path, not_json: bool = False) -> InputError:
    what = "not valid JSON" if not_json else "not an edgetruth manifest (missing or malformed images/files/sha256)"
    return InputError(f"{path}: {what}; re-render into a new directory, or delete {MANIFEST} and {JOURNAL} "
                      "there to render every image again")


# --- manifest.json --------------------------------------------------------------------
class ManifestReader:
    """``header`` at once; iterating yields ``(name, entry)`` in index order, streaming the line
    layout (constant memory) and reading any other layout whole."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self._whole: dict | None = None
        with open(self.path, "rb") as fh:
            first = fh.readline()
        text = first.decode("utf-8", "replace").rstrip("\n")
        self.streamable = text.startswith("{") and text.endswith(_IMAGES_OPEN)
        try:
            if self.streamable:
                self.header = json.loads(text[:-len(_IMAGES_OPEN)] + "}")
            else:
                self._whole = json.loads(self.path.read_text())
                self.header = {k: v for k, v in self._whole.items() if k != "images"} if isinstance(
                    self._whole, dict) else None
        except (ValueError, UnicodeDecodeError):
            raise _bad_manifest(self.path, not_json=True) from None
        if not (isinstance(self.header, dict) and isinstance(self.header.get("n_images"), int)
                and (self._whole is None or isinstance(self._whole.get("images"), dict))):
            raise _bad_manifest(self.path)

    def __iter__(self) -> Iterator[tuple[str, dict]]:
        if self._whole is not None:
            items = list(self._whole["images"].items())
            if not all(entry_ok(e) for _, e in items):
                raise _bad_manifest(self.path)
            yield from sorted(items, key=lambda kv: kv[1]["index"])
            return
        with open(self.path, "rb") as fh:
            fh.readline()
            closed = False
            for raw in fh:
                line = raw.decode("utf-8", "replace").rstrip("\n")
                if line == "}}":
                    closed = True
                    break
                try:
                    one = json.loads("{" + line.rstrip(",") + "}")
                except ValueError:
                    raise _bad_manifest(self.path, not_json=True) from None
                if len(one) != 1:
                    raise _bad_manifest(self.path)
                name, entry = next(iter(one.items()))
                if not entry_ok(entry):
                    raise _bad_manifest(self.path)
                yield name, entry
            if not closed:
                raise _bad_manifest(self.path)


def write_manifest(path: Path, header: dict, entries) -> int:
    """Write ``entries`` (``(name, entry)`` in index order) atomically and durably; returns how many."""
    tmp = tmp_path(path)
    n = 0
    try:
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(json.dumps(header)[:-1] + _IMAGES_OPEN + "\n")
            sep = ""
            for name, entry in entries:  # streamed: may find the old manifest damaged half-way
                fh.write(sep + _entry_line(name, entry))
                sep = ",\n"
                n += 1
            fh.write(("\n" if n else "") + _FOOTER)
            fh.flush()
            os.fsync(fh.fileno())
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    os.replace(tmp, path)
    _fsync_dir(path.parent)
    return n


def _fsync_dir(d: Path) -> None:
    fd = os.open(d, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


# --- journal.jsonl ----------------------------------------------------------------------
@dataclass
class JournalScan:
    """What reading a journal found: ``good_end`` (bytes up to the last whole line), ``bad`` (line
    numbers of damaged lines, ignored), ``torn`` (a partial last line, ignored)."""

    spec_sha256: str | None = None
    good_end: int = 0
    bad: list = field(default_factory=list)
    torn: bool = False

    def problem(self) -> str | None:
        if not self.bad:
            return None
        shown = ", ".join(map(str, self.bad[:5])) + (", ..." if len(self.bad) > 5 else "")
        return (f"{JOURNAL}: {len(self.bad)} damaged line(s) ignored (line {shown}); "
                "their images are rendered again by `edgetruth render`")


def iter_journal(path: str | Path, n_images: int, scan: JournalScan) -> Iterator[tuple[int, str, dict]]:
    """``(byte offset, name, entry)`` per whole, valid line of the journal, oldest first; fills ``scan``."""
    path = Path(path)
    off = 0
    with open(path, "rb") as fh:
        for lineno, raw in enumerate(fh, 1):
            start, off = off, off + len(raw)
            if not raw.endswith(b"\n"):  # the run was killed while writing it
                scan.torn = True
                break
            try:
                obj = json.loads(raw)
            except ValueError:
                obj = None
            if lineno == 1:
                if isinstance(obj, dict) and obj.get("journal") == JOURNAL_FORMAT:
                    scan.spec_sha256 = obj.get("spec_sha256")
                else:
                    scan.bad.append(lineno)
                scan.good_end = off
                continue
            scan.good_end = off
            name, entry = (obj.get("name"), obj.get("entry")) if isinstance(obj, dict) else (None, None)
            if not (isinstance(name, str) and entry_ok(entry) and 0 <= entry["index"] < n_images):
                scan.bad.append(lineno)
                continue
            yield start, name, entry


def read_journal_line(fh, offset: int) -> tuple[str, dict]:
    fh.seek(offset)
    obj = json.loads(fh.readline())
    return obj["name"], obj["entry"]


class JournalWriter:
    """Appends one line per finished image (creates the journal with its header).

    A line is in the journal -- and survives a ``kill -9`` -- as soon as ``append`` returns; a
    background thread makes it durable (``fdatasync``) right after: back to back, so at a few
    images per second each line gets its own sync, and faster, one sync covers the lines
    written while the previous one ran (group commit).  The driver never waits for the disk,
    and a power cut loses at most the lines of the last two syncs (their images are rendered
    again).  ``close`` syncs what is left; a failed sync is raised by the next call."""

    def __init__(self, path: str | Path, spec_sha256: str, good_end: int = 0):
        """``good_end``: where the whole lines of an existing journal end (``JournalScan.good_end``)."""
        self.path = Path(path)
        if good_end == 0 or not self.path.exists():
            tmp = tmp_path(self.path)
            tmp.write_text(json.dumps({"journal": JOURNAL_FORMAT, "spec_sha256": spec_sha256}) + "\n")
            os.replace(tmp, self.path)
        elif self.path.stat().st_size != good_end:
            os.truncate(self.path, good_end)  # drop a torn last line before appending after it
        self.fd = os.open(self.path, os.O_WRONLY | os.O_APPEND)
        self._sync = getattr(os, "fdatasync", os.fsync)
        self._sync(self.fd)
        self._dirty, self._closing, self._error = threading.Event(), False, None
        self.n_syncs = 0
        self._thread = threading.Thread(target=self._syncer, name="journal-sync", daemon=True)
        self._thread.start()

    def _syncer(self) -> None:
        while True:
            self._dirty.wait()
            self._dirty.clear()  # lines appended from now on are left for the next round
            if self._closing:
                return
            try:
                self._sync(self.fd)
                self.n_syncs += 1
            except OSError as exc:
                self._error = exc
                return

    def _raise(self) -> None:
        if self._error is not None:
            raise OSError(f"{self.path}: cannot sync the journal ({self._error})") from self._error

    def append(self, name: str, entry: dict) -> None:
        self._raise()
        os.write(self.fd, (json.dumps({"name": name, "entry": entry}) + "\n").encode())
        self._dirty.set()

    def close(self) -> None:
        if self.fd is None:
            return
        self._closing = True
        self._dirty.set()
        self._thread.join()
        try:
            self._raise()
            self._sync(self.fd)
        finally:
            os.close(self.fd)
            self.fd = None


# --- merged view and compaction ---------------------------------------------------------
def journal_positions(d: Path, n_images: int, spec_sha256: str | None) -> tuple[np.ndarray, JournalScan]:
    """The byte offset of each image's latest journal line (-1: none) and the scan; an InputError if
    the journal belongs to another spec."""
    pos = np.full(n_images, -1, dtype=np.int64)
    scan = JournalScan()
    jp = d / JOURNAL
    if jp.is_file():
        for off, _, entry in iter_journal(jp, n_images, scan):
            pos[entry["index"]] = off
        if spec_sha256 is not None and scan.spec_sha256 not in (None, spec_sha256):
            raise InputError(f"{jp}: written for another spec than {d / MANIFEST}; delete {JOURNAL} "
                             "(its images are rendered again)")
    return pos, scan


def merged_entries(d: Path, reader: ManifestReader, pos: np.ndarray) -> Iterator[tuple[str, dict]]:
    """The manifest's entries merged with the journal's (the journal's win), in index order."""
    latest = np.flatnonzero(pos >= 0)
    k = 0
    jf = open(d / JOURNAL, "rb") if len(latest) else None
    try:
        last = -1
        for name, entry in reader:
            idx = entry["index"]
            if idx <= last:  # we write manifests in index order: this one was edited or damaged
                raise _bad_manifest(reader.path)
            last = idx
            while k < len(latest) and latest[k] < idx:
                yield read_journal_line(jf, int(pos[latest[k]]))
                k += 1
            if k < len(latest) and latest[k] == idx:
                yield read_journal_line(jf, int(pos[idx]))
                k += 1
            else:
                yield name, entry
        while k < len(latest):
            yield read_journal_line(jf, int(pos[latest[k]]))
            k += 1
    finally:
        if jf is not None:
            jf.close()


def _syncfs(d: Path) -> None:
    """Flush the file system holding ``d`` (Linux ``syncfs``; elsewhere every file system)."""
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        fd = os.open(d, os.O_RDONLY)
        try:
            if libc.syncfs(fd) == 0:
                return
        finally:
            os.close(fd)
    except (OSError, AttributeError):
        pass
    os.sync()


def compact(d: str | Path) -> bool:
    """Merge the journal into ``manifest.json`` (atomic, durable) and delete it; False if there was
    nothing to do.  Safe to interrupt at any moment and to repeat."""
    d = Path(d)
    mpath, jpath = d / MANIFEST, d / JOURNAL
    reader = ManifestReader(mpath)
    if not jpath.exists() and reader.streamable:
        return False
    pos, _ = journal_positions(d, reader.header["n_images"], reader.header.get("spec_sha256"))
    _syncfs(d)  # the image files reach the disk before the manifest that vouches for them
    write_manifest(mpath, reader.header, merged_entries(d, reader, pos))
    if jpath.exists():
        jpath.unlink()
        _fsync_dir(d)
    return True
