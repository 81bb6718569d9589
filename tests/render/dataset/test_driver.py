"""The render driver at scale: the spec goes to each worker once, tasks stay small, the journal is
resumed and compacted, a million-image spec starts at once and the driver's memory stays flat."""
from __future__ import annotations

import json
import pickle
import sys
from pathlib import Path

import pytest

from edgetruth import backends
from edgetruth.render.testing import write_patch_spec, write_tiny_spec


def _files(d: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(d.iterdir())}


class _Recording(backends.SerialBackend):
    """The in-process backend, recording what each task and the initializer receive (pickled)."""

    task_bytes: list = []
    init_calls: list = []

    def map_unordered(self, fn, args_list, window=None):
        init, self._initializer = self._initializer, None
        if init is not None:
            _Recording.init_calls.append(len(pickle.dumps(self._initargs)))
            init(*self._initargs)
        for args in args_list:
            _Recording.task_bytes.append(len(pickle.dumps(args)))
            yield fn(*args)


def test_each_task_names_the_spec_by_hash_and_the_spec_travels_once(tmp_path, monkeypatch):
    from edgetruth.render.dataset.driver import render_spec

    spec = write_patch_spec(tmp_path, 1000)  # its pickle holds 1000 distances: ~9 kB
    monkeypatch.setattr(backends, "make_backend", lambda *a, **k: _Recording())
    _Recording.task_bytes, _Recording.init_calls = [], []
    t: dict = {}
    render_spec(spec, tmp_path / "out", only=list(range(12)), progress=False, announce=lambda s: None, timings=t)
    assert t["n_rendered"] == 12 and len(_Recording.task_bytes) == 12
    assert _Recording.init_calls and len(_Recording.init_calls) == 1 and _Recording.init_calls[0] > 9000
    assert max(_Recording.task_bytes) < 300  # (spec hash, index, variant, directory)


def test_killed_run_journal_resumes_and_is_compacted(tmp_path):
    """A journal left by a dead driver (torn last line, one damaged line) is resumed: the images it
    records are not rendered again, the damaged one is, and the result equals an uninterrupted run."""
    from edgetruth.render.dataset.driver import render_spec
    from edgetruth.render.dataset.journal import JOURNAL, MANIFEST, JournalWriter, new_header, write_manifest

    spec = write_tiny_spec(tmp_path, spp=4)
    ref, out = tmp_path / "ref", tmp_path / "out"
    render_spec(spec, ref, progress=False, announce=lambda s: None)
    m = json.loads((ref / MANIFEST).read_text())
    # the state of a driver killed after recording images 0 and 2 (image 1's files exist, unrecorded)
    out.mkdir()
    for name in ("0000_T2", "0001_T2", "0002_cal"):
        for ext in ("exr", "png", "json"):
            (out / f"{name}.{ext}").write_bytes((ref / f"{name}.{ext}").read_bytes())
    write_manifest(out / MANIFEST, {k: v for k, v in m.items() if k != "images"}, [])
    w = JournalWriter(out / JOURNAL, m["spec_sha256"])
    w.append("0000_T2", m["images"]["0000_T2"])
    w.append("0002_cal", m["images"]["0002_cal"])
    w.close()
    lines = (out / JOURNAL).read_bytes().split(b"\n")
    lines[2] = b'{"name": "0002_cal", "entr'  # damaged (not the last line)
    (out / JOURNAL).write_bytes(b"\n".join(lines[:3]) + b"\n" + b'{"name": "0001_T2", "en')  # + torn tail
    said: list = []
    t: dict = {}
    render_spec(spec, out, progress=False, announce=said.append, timings=t)
    assert t["n_rendered"] == 2  # images 1 and 2; image 0 was recorded
    assert [s for s in said if "damaged line" in s] and not (out / JOURNAL).exists()
    assert _files(out) == _files(ref)


def test_verify_and_open_dataset_read_a_journal_verify_compacts_it_unless_a_render_holds_the_dir(tmp_path, capsys):
    from edgetruth.cli import main
    from edgetruth.render.dataset.driver import DirLock, render_spec
    from edgetruth.render.dataset.journal import JOURNAL, MANIFEST, JournalWriter, write_manifest

    spec = write_tiny_spec(tmp_path, spp=4)
    d = tmp_path / "d"
    render_spec(spec, d, progress=False, announce=lambda s: None)
    ref = _files(d)
    m = json.loads((d / MANIFEST).read_text())
    write_manifest(d / MANIFEST, {k: v for k, v in m.items() if k != "images"}, [])  # all in the journal
    w = JournalWriter(d / JOURNAL, m["spec_sha256"])
    for name, e in m["images"].items():
        w.append(name, e)
    w.close()
    from edgetruth.render import open_dataset

    ds = open_dataset(d)  # reads the journal form too
    assert ds.names() == list(m["images"]) and ds[2].truth["index"] == 2
    lock = DirLock(d)  # a render running now
    try:
        assert main(["verify", str(d)]) == 0
        assert "OK, 3/3" in capsys.readouterr().out and (d / JOURNAL).exists()
    finally:
        lock.release()
    assert main(["verify", str(d)]) == 0
    out = capsys.readouterr().out
    assert "compacted" in out and "OK, 3/3" in out and not (d / JOURNAL).exists()
    assert _files(d) == ref


def test_damaged_manifest_stops_render_and_verify_in_one_line_touching_nothing(tmp_path, capsys):
    from edgetruth.cli import main
    from edgetruth.render.dataset.driver import render_spec

    spec = write_tiny_spec(tmp_path, spp=4)
    d = tmp_path / "d"
    render_spec(spec, d, only=[0], progress=False, announce=lambda s: None)
    text = (d / "manifest.json").read_text()
    (d / "manifest.json").write_text(text[: len(text) // 2])  # damaged from outside (cut in half)
    (d / "journal.jsonl").write_text('{"journal": 1}\n')
    before = _files(d)
    for argv in (["render", str(spec), "-o", str(d), "--workers", "1", "--no-progress"], ["verify", str(d)]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "manifest.json" in err and "Traceback" not in err
    assert _files(d) == before


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads the driver's RSS from /proc")
@pytest.mark.parametrize("workers", [1, 2])
def test_million_image_spec_starts_at_once_and_driver_memory_stays_flat(tmp_path, workers):
    """``edgetruth render`` of a 1,000,000-image spec records images within the timeout (its start
    time is a bench figure, `make bench`), and the driver's RSS after 1,000 images is within 5 %
    of its RSS after 100: nothing is kept per task or per finished image.

    The leak this catches: the bench's limit (`make bench`: within 10 % from 200 to 2,000 images) flags a
    per-image leak above 0.10 a / 1,800 (a = the RSS, ~240 MB: ~13 kB per image); over 900 images the same
    per-image limit is 0.10 a x 900 / 1,800 = 5 % of a, so half the images detect the same leak.  The RSS
    is flat from 50 images on (measured, 2,000 images: within 0.35 % with 1 worker, 0.01 % with 2), far
    inside 5 %."""
    from edgetruth.render.bench import million_image_run

    lo, hi = 100, 1000
    r = million_image_run(tmp_path, workers=workers, checkpoints=(lo, hi), timeout_s=240)
    a, b = r["rss_mb"][lo], r["rss_mb"][hi]
    print(f"workers {workers}: first image after {r['first_image_s']:.1f} s, RSS {a:.0f} -> {b:.0f} MB, "
          f"{r['images_per_s']:.0f} images/s")
    assert r["first_image_s"] is not None
    assert abs(b - a) <= 0.10 * (hi - lo) / 1800 * a  # = 5 % of a: the bench's per-image leak limit
