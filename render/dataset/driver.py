"""Render a spec into a dataset directory: the driver loop, resumable, constant cost per image.

The driver (the calling process) holds an exclusive ``flock`` on the dataset
directory, works out which images are still to render (a resume re-checks the SHA-256
of every file already recorded), and hands them to a backend (``edgetruth.backends``)
through a bounded window: it never holds more than a few tasks per worker, and the spec
goes to each worker once.  For each finished image it writes the files (when the
worker does not share its disk) and appends one synced line to the journal
(``edgetruth.render.dataset.journal``); at the end it compacts the journal into
``manifest.json``.  Its memory does not grow with the dataset: one byte per image of
state, nothing per finished image.
"""
from __future__ import annotations

import os
import time
from collections.abc import Mapping
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from edgetruth import console
from edgetruth.errors import InputError
from edgetruth.fileio import is_temporary, make_output_dir, sha256_file
from edgetruth.render.dataset.journal import (JOURNAL, MANIFEST, JournalScan, JournalWriter, ManifestReader, compact,
                                      journal_positions, merged_entries, new_header, write_manifest)
from edgetruth.render.dataset.spec import Spec, load_spec
from edgetruth.render.dataset.task import init_worker, init_worker_specs, render_indexed, write_files

#: Who writes the image files: ``auto`` = the workers when they see the driver's disk, else the
#: driver; ``driver`` = always the driver (file bytes travel back, as on a multi-node cluster);
#: ``workers`` = always the workers (a file system shared by every node).
FILE_WRITERS = ("auto", "driver", "workers")
_CHECK_CHUNK = 2048  # manifest entries hashed per batch on resume


class DirLock:
    """An exclusive ``flock`` on the dataset directory itself (no lock file to leave behind);
    the kernel releases it when the process dies, even on ``kill -9``."""

    def __init__(self, path: Path, blocking_error: bool = True):
        import fcntl

        self.fd = os.open(path, os.O_RDONLY)
        try:
            fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(self.fd)
            self.fd = None
            if blocking_error:
                raise InputError(f"{path}: another `edgetruth render` is writing this dataset now; "
                                 "wait for it to finish or choose another output directory") from None

    @property
    def held(self) -> bool:
        return self.fd is not None

    def release(self) -> None:
        if self.fd is not None:
            os.close(self.fd)  # closing the descriptor drops the flock
            self.fd = None


class ManifestView(Mapping):
    """What ``render_spec`` returns: the manifest's header keys at once, ``["images"]`` (every
    entry, read from disk) on first use -- a million entries are not loaded unless asked for."""

    def __init__(self, out_dir: Path, header: dict):
        self._dir, self._header, self._images = Path(out_dir), dict(header), None

    def __getitem__(self, key):
        if key != "images":
            return self._header[key]
        if self._images is None:
            from edgetruth.render.dataset.reader import load_manifest

            self._images = load_manifest(self._dir)["images"]
        return self._images

    def __iter__(self):
        yield from self._header
        yield "images"

    def __len__(self) -> int:
        return len(self._header) + 1


def compact_if_idle(out_dir: str | Path) -> bool:
    """Compact a dataset's journal into its manifest unless a render holds the directory (or it
    is read-only); True if it did."""
    d = Path(out_dir)
    if not ((d / JOURNAL).is_file() and (d / MANIFEST).is_file() and os.access(d, os.W_OK)):
        return False
    lock = DirLock(d, blocking_error=False)
    if not lock.held:
        return False
    try:
        return compact(d)
    finally:
        lock.release()


def check_variant_name(variant: str | None) -> None:
    """A ``--variant`` that this Mitsuba build lacks is refused (before anything is written)."""
    if variant:
        import mitsuba as mi

        if variant not in mi.variants():
            raise InputError(f"--variant {variant}: not in this Mitsuba build (have: {', '.join(mi.variants())})")


def render_spec(spec: Spec | str | Path, out_dir: str | Path, variant: str | None = None, progress: bool = True,
                only: list[int] | None = None, timings: dict | None = None, announce=print,
                backend: str = "local", workers: int | None = 1, address: str | None = None,
                files: str = "auto", window: int | None = None, pool: "RenderPool | None" = None) -> ManifestView:
    """Render every image of ``spec`` into ``out_dir`` (resumable) and return the manifest.

    Each image is a pure function of (spec, index), written atomically (``NAME.exr`` radiance, ``NAME.png``
    sensor image, ``NAME.json`` ground truth) and recorded by this (driver) process in a journal that is
    compacted into ``manifest.json``. Whatever the backend, an image's files are identical, and an
    interrupted run -- even ``kill -9`` -- resumes where it stopped.

    Parameters
    ----------
    spec : Spec or str or pathlib.Path
        A loaded spec, a shipped spec's name or a TOML path.
    out_dir : str or pathlib.Path
        The dataset folder: new, empty, or an earlier render of the same spec (resumed).
    variant : str, optional
        Mitsuba's variant (default: the fastest that runs here: ``cuda_ad_rgb``, ``llvm_ad_rgb``, ``scalar_rgb``).
    progress : bool, optional
        Draw a progress bar (on a terminal only).
    only : list of int, optional
        Render only these image indices.
    timings : dict, optional
        Accumulates ``render_s`` (inside ``mi.render``, summed over workers), ``stage_s``, ``journal_s``,
        ``wall_s``, ``n_rendered``, ``reused``, ``n_written_by_driver``, ``n_complete`` and, on Ray,
        ``tasks_per_node`` (node id -> images).
    announce : callable, optional
        Receives the one-line notes (the variant chosen, ...); default ``print``.
    backend : str, optional
        ``"local"`` (default: this process, or a pool of ``workers``) or ``"ray"`` (``edgetruth.backends``).
    workers : int or None, optional
        Local worker processes (1: this process; None: one per core).
    address : str, optional
        A Ray cluster's address (``HOST:6379`` or ``ray://HOST:10001``); default: a local Ray instance.
    files : str, optional
        Who writes the image files: ``"auto"``, ``"driver"`` or ``"workers"`` (``FILE_WRITERS``).
    window : int, optional
        Tasks in flight (default: a few per worker).
    pool : RenderPool, optional
        A pool made for this spec whose workers stay up for the caller's next call.

    Returns
    -------
    ManifestView
        The dataset's manifest (every image with the SHA-256 of each file).

    Raises
    ------
    edgetruth.errors.InputError
        A bad spec, backend, variant or output folder, before anything is written.
    """
    from edgetruth.backends import check_backend_args
    from edgetruth.render import variants  # noqa: F401 -- before Mitsuba: points Dr.Jit at the pip libLLVM

    check_backend_args(backend, workers, address)  # before anything is written
    if files not in FILE_WRITERS:
        raise InputError(f"files={files!r}: choose one of {', '.join(FILE_WRITERS)}")
    if window is not None and (not isinstance(window, int) or window < 1):
        raise InputError(f"window={window!r}: must be a positive integer")
    check_variant_name(variant)
    if not isinstance(spec, Spec):
        spec = load_spec(spec)
    out_dir = Path(out_dir)
    selected = np.ones(spec.n_images, dtype=bool)
    if only is not None:
        bad = sorted(i for i in set(only) if not 0 <= i < spec.n_images)
        if bad:
            raise InputError(f"--only: spec {spec.name!r} has images 0-{spec.n_images - 1}, and {len(bad)} of the "
                             f"indices asked for lie beyond them (the first: {bad[0]}); ask for indices within them")
        selected[:] = False
        selected[sorted(set(only))] = True
    from edgetruth.render.dataset.image import check_views

    check_views(spec)  # a pose no draw can meet: refused before anything is written
    check_not_foreign(out_dir)
    make_output_dir(out_dir)
    lock = DirLock(out_dir)
    try:
        return _render_locked(spec, out_dir, variant, progress, selected, timings if timings is not None else {},
                              announce, backend, workers, address, files, window, pool)
    finally:
        lock.release()


def check_not_foreign(out_dir: Path) -> None:
    """``-o`` must be new, empty or a dataset (it has a manifest or a journal): never a folder of the
    user's that rendering would fill with image files."""
    if not out_dir.is_dir() or (out_dir / MANIFEST).exists() or (out_dir / JOURNAL).exists():
        return
    other = sorted(p.name for p in out_dir.iterdir() if not is_temporary(p.name))
    if other:
        raise InputError(f"-o {out_dir}: exists and is not empty ({other[0]}{', ...' if len(other) > 1 else ''}) but "
                         "is not an edgetruth dataset (no manifest.json); choose a new or empty directory")


def _open_dataset(spec: Spec, spec_key: str, out_dir: Path, selected: np.ndarray, announce):
    """Check the directory holds this spec and read its record (manifest + journal, every file
    re-hashed) before touching anything; then clear a killed run's temporaries and start the
    manifest if new.  Returns (header, which images are complete, the journal scan)."""
    mpath = out_dir / MANIFEST
    scan = JournalScan()
    done = np.zeros(spec.n_images, dtype=bool)
    if mpath.is_file():
        reader = ManifestReader(mpath)
        header = reader.header
        if (header.get("spec") != spec.name or header.get("spec_sha256") != spec_key
                or header.get("n_images") != spec.n_images):
            raise InputError(f"{out_dir} holds renders of another spec (or another version of {spec.name!r}); "
                             "choose a new output directory or delete it")
        pos, scan = journal_positions(out_dir, spec.n_images, spec_key)  # a foreign journal: InputError
        done = _complete_images(out_dir, reader, pos, selected)  # a damaged manifest: InputError
    else:  # a new dataset (a journal without a manifest is not trusted: it is started afresh)
        header = new_header(spec.name, spec_key, spec.n_images)
    for p in os.scandir(out_dir):  # temporaries of a killed run (we hold the lock: no writer is alive)
        if is_temporary(Path(p.name)) and p.is_file():
            os.unlink(p.path)
    if not mpath.is_file():
        write_manifest(mpath, header, [])
    if scan.problem():
        announce(f"render: {out_dir / JOURNAL}: {scan.problem()}")
    return header, done, scan


def _entry_complete(out_dir: Path, entry: dict) -> bool:
    if not entry.get("complete"):
        return False
    for f in entry["files"].values():
        p = out_dir / f["path"]
        try:
            if sha256_file(p) != f["sha256"]:
                return False
        except OSError:
            return False
    return True


def _complete_images(out_dir: Path, reader, pos: np.ndarray, selected: np.ndarray) -> np.ndarray:
    """Per image: recorded as complete (manifest or journal, the latest entry) and, for the
    ``selected`` images, every file still matching its SHA-256 (the others are not re-hashed).
    Streams the record and hashes in parallel threads (hashlib and reads release the GIL)."""
    done = np.zeros(len(selected), dtype=bool)
    chunk: list = []

    def flush(pool):
        for idx, ok in zip([e["index"] for e in chunk], pool.map(lambda e: _entry_complete(out_dir, e), chunk)):
            done[idx] = ok
        chunk.clear()

    with ThreadPoolExecutor(max_workers=min(8, 2 * (os.cpu_count() or 1))) as pool:
        for _, entry in merged_entries(out_dir, reader, pos):
            if not selected[entry["index"]]:
                done[entry["index"]] = bool(entry.get("complete"))
                continue
            chunk.append(entry)
            if len(chunk) >= _CHECK_CHUNK:
                flush(pool)
        flush(pool)
    return done


def _llvm_threads() -> int | None:
    import drjit as dr

    return int(dr.thread_count())


class RenderPool:
    """Local worker processes shared by several ``render_spec`` calls (the main job's threshold, calibration and
    target specs): each worker starts, imports Mitsuba and warms its caches once, not once per spec (~3 s of a
    2-core run per pool, measured).  Every worker is given all ``specs`` when it starts; a call renders one of
    them.  A context manager; ``close()`` stops the workers."""

    def __init__(self, specs, workers: int | None = None):
        from edgetruth.backends import default_workers

        self.specs = {s.identity_sha256: s for s in specs}
        self.workers = default_workers() if workers is None else int(workers)
        self.backend = None
        self.variant = None

    def backend_for(self, variant: str):
        """The pool (started on first use, its workers on ``variant``); a second variant: InputError."""
        from edgetruth.backends import PoolBackend, default_workers

        if self.backend is None:
            self.variant = variant
            self.backend = PoolBackend(self.workers)
            threads = max(1, default_workers() // self.workers)
            self.backend.set_initializer(init_worker_specs, (variant, threads, self.specs))
        elif variant != self.variant:
            raise InputError(f"render pool: its workers run {self.variant}, not {variant}; use one variant per run")
        return self.backend

    def close(self, abort: bool = False) -> None:
        if self.backend is not None:
            self.backend.close(abort=abort)
            self.backend = None

    def __enter__(self) -> "RenderPool":
        return self

    def __exit__(self, exc_type, *exc) -> None:
        self.close(abort=exc_type is not None)


def unit_tasks(spec, todo: np.ndarray) -> list[tuple]:
    """The tasks of a paired spec's images ``todo``: one per radiance unit (the images that share one render, a
    design slot's cells, go to one worker together, which renders the unit once; every other image is a unit of
    its own), and one for the units of a slot whose preset targets share an outline (T1, T3, T4: the worker
    computes their exact coverage once, ``edge_band.band_coverage`` keeps it).  A unit's images are consecutive
    in index order; the tasks come in the order of their first unit."""
    rank = np.empty(spec.n_images, dtype=np.int64)
    task = np.empty(spec.n_images, dtype=np.int64)
    shared = outline_sharing(spec)
    ids: dict = {}
    for u, unit in enumerate(spec.units()):
        rank[unit] = u
        task[unit] = ids.setdefault(shared.get(unit[0], ("unit", u)), len(ids))
    todo = np.asarray(todo, dtype=np.int64)
    todo = todo[np.lexsort((todo, rank[todo], task[todo]))]
    cuts = np.flatnonzero(np.diff(task[todo])) + 1
    return [tuple(int(i) for i in part) for part in np.split(todo, cuts)]


def outline_sharing(spec) -> dict:
    """{image index: (slot, outline shape, camera)} for the images of paired target cells whose coverage is exact
    and depends only on the outline (``edge_mode`` "analytic" or "frame", a preset target): the units of one slot
    with one shape and camera share it.  Other images are absent."""
    from edgetruth.render.scene.targets import TARGETS

    if spec.render.edge_mode not in ("analytic", "frame"):
        return {}
    out = {}
    for g in spec.groups:
        if g.paired and g.kind == "target" and isinstance(g.target, str) and g.target in TARGETS:
            shape = TARGETS[g.target]["shape"]
            for k in range(g.count):
                out[g.first_index + k] = ("slot", k, shape, g.camera)
    return out

def _render_locked(spec, out_dir, variant, progress, selected, stats, announce, backend, workers, address,
                   files, window, pool=None) -> ManifestView:
    from edgetruth.backends import default_workers, make_backend
    from edgetruth.render.variants import choose_variant

    t_start = time.perf_counter()
    spec_key = spec.identity_sha256  # computed once: it hashes every image's distance
    header, done, scan = _open_dataset(spec, spec_key, out_dir, selected, announce)
    todo = np.flatnonzero(selected & ~done)  # index order, so the journal is nearly sorted
    if any(g.paired for g in spec.groups):
        task_indices = unit_tasks(spec, todo)
        todo = np.asarray([i for ix in task_indices for i in ix], dtype=np.int64)
    else:
        task_indices = None
    n_sel = int(selected.sum())
    stats["resume_check_s"] = stats.get("resume_check_s", 0.0) + time.perf_counter() - t_start
    if not len(todo):
        compact(out_dir)  # a killed run's journal, or an older manifest layout
        stats["n_complete"] = int(done.sum())
        stats["wall_s"] = stats.get("wall_s", 0.0) + time.perf_counter() - t_start
        return ManifestView(out_dir, header)
    if pool is not None and spec_key not in pool.specs:
        raise InputError(f"render pool: made without spec {spec.name!r}; give RenderPool every spec it renders")
    n_workers = default_workers() if workers is None else int(workers)
    n_workers = min(n_workers, len(todo)) if backend == "local" else n_workers
    # validates before any rendering; a shared pool is the caller's (started once, closed by it)
    be = make_backend(backend, workers=n_workers, address=address) if pool is None else None
    bar = writer = None
    threads_before = _llvm_threads() if be is not None and be.in_process else None  # init_worker may change them
    try:
        if backend == "ray" and getattr(be, "num_gpus", 0) and not variant:
            used = "cuda_ad_rgb"
            announce(f"render: using Mitsuba variant {used} (the Ray cluster has GPUs)")
        else:
            used = choose_variant(variant, announce=announce)
        if pool is not None:
            be = pool.backend_for(used)
        else:
            threads = max(1, default_workers() // max(1, be.concurrency)) if be.concurrency > 1 else None
            be.set_initializer(init_worker, (used, threads, spec, spec_key))  # the spec: once per worker
        if files == "workers" or (files == "auto" and be.shares_filesystem):
            worker_dir = str(out_dir.resolve())
        else:
            worker_dir = None  # the bytes come back with the result; this process writes them
        writer = JournalWriter(out_dir / JOURNAL, spec_key, scan.good_end)
        bar = console.bar(total=n_sel, initial=n_sel - len(todo), unit="img", desc=f"render {spec.name}",
                          enabled=progress)
        if task_indices is None:
            tasks = ((spec_key, (int(i),), used, worker_dir) for i in todo)
        else:
            tasks = ((spec_key, ix, used, worker_dir) for ix in task_indices)
        stage = stats.setdefault("stage_s", {})
        if hasattr(be, "tasks_per_node"):
            stats["tasks_per_node"] = be.tasks_per_node  # live: a watcher sees where images render
        for res in (r for batch in be.map_unordered(render_indexed, tasks, window=window) for r in batch):
            t0 = time.perf_counter()
            name, entry = res["name"], res["entry"]
            if res["payload"] is not None:
                write_files(out_dir, name, res["payload"])
                stats["n_written_by_driver"] = stats.get("n_written_by_driver", 0) + 1
            writer.append(name, entry)
            done[entry["index"]] = True
            stats["journal_s"] = stats.get("journal_s", 0.0) + time.perf_counter() - t0
            stats["render_s"] = stats.get("render_s", 0.0) + res["render_s"]
            for k, v in res["stage_s"].items():
                stage[k] = stage.get(k, 0.0) + v
            stats["n_rendered"] = stats.get("n_rendered", 0) + 1
            stats["reused"] = stats.get("reused", 0) + res.get("reused", 0)
            bar.update(1)
    except BaseException:
        if pool is not None:
            pool.close(abort=True)
        elif be is not None:
            be.close(abort=True)
        raise
    finally:
        if bar is not None:
            bar.close()
        if writer is not None:
            writer.close()
        if threads_before:
            import drjit as dr

            dr.set_thread_count(threads_before)
    if pool is None:
        be.close()
    per_node = stats.get("tasks_per_node") or {}
    if len(per_node) > 1:
        announce("render: images per Ray node: " + ", ".join(f"{k[:12]} {v}" for k, v in sorted(per_node.items())))
    t0 = time.perf_counter()
    compact(out_dir)
    stats["compact_s"] = stats.get("compact_s", 0.0) + time.perf_counter() - t0
    stats["n_complete"] = int(done.sum())
    stats["wall_s"] = stats.get("wall_s", 0.0) + time.perf_counter() - t_start
    return ManifestView(out_dir, header)
