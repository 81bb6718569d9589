"""The dataset record: an append-only journal (one synced line per image) compacted into a
streamable manifest.json; torn and damaged lines; older manifest layouts; one-line errors."""
from __future__ import annotations

import json

import numpy as np
import pytest

from edgetruth.errors import InputError
from edgetruth.render.dataset.journal import (JOURNAL, MANIFEST, JournalScan, JournalWriter, ManifestReader, compact,
                                      iter_journal, journal_positions, new_header, write_manifest)

KEY = "ab" * 32


def _entry(i: int, tag: str = "a") -> tuple[str, dict]:
    sha = tag * 64  # a hex digit
    name = f"{i:04d}_T1"
    return name, {"index": i, "kind": "target", "group": "T1", "seed": i, "variant": "scalar_rgb", "complete": True,
                  "files": {k: {"path": f"{name}.{k}", "sha256": sha} for k in ("exr", "png", "json")}}


def _new(tmp_path, n=10, entries=()):
    write_manifest(tmp_path / MANIFEST, new_header("s", KEY, n), list(entries))
    return tmp_path


def test_manifest_is_plain_json_and_streams_in_index_order(tmp_path):
    d = _new(tmp_path, entries=[_entry(i) for i in (0, 3, 7)])
    whole = json.loads((d / MANIFEST).read_text())
    assert whole["n_images"] == 10 and list(whole["images"]) == ["0000_T1", "0003_T1", "0007_T1"]
    r = ManifestReader(d / MANIFEST)
    assert r.streamable and r.header == new_header("s", KEY, 10)
    assert [e["index"] for _, e in r] == [0, 3, 7]
    assert (d / MANIFEST).read_text().count("\n") == 1 + 3 + 1  # header, one line per entry, footer
    (tmp_path / "empty").mkdir()
    _new(tmp_path / "empty")
    assert json.loads((tmp_path / "empty" / MANIFEST).read_text())["images"] == {}


def test_journal_lines_are_merged_latest_wins_and_compaction_is_idempotent(tmp_path):
    d = _new(tmp_path, entries=[_entry(0), _entry(5)])
    w = JournalWriter(d / JOURNAL, KEY)
    for i, tag in [(2, "b"), (5, "c"), (9, "d"), (2, "e")]:
        w.append(*_entry(i, tag))
    w.close()
    scan = JournalScan()
    assert [e["index"] for _, _, e in iter_journal(d / JOURNAL, 10, scan)] == [2, 5, 9, 2]
    assert scan.spec_sha256 == KEY and not scan.bad and not scan.torn
    assert compact(d) and not (d / JOURNAL).exists()
    m = json.loads((d / MANIFEST).read_text())
    assert [e["index"] for e in m["images"].values()] == [0, 2, 5, 9]
    assert m["images"]["0002_T1"]["files"]["png"]["sha256"] == "e" * 64  # the latest line of image 2
    assert m["images"]["0005_T1"]["files"]["png"]["sha256"] == "c" * 64  # the journal over the manifest
    before = (d / MANIFEST).read_bytes()
    assert not compact(d) and (d / MANIFEST).read_bytes() == before  # nothing to do
    # merging the same journal twice (a kill between the rename and the unlink) changes nothing
    w = JournalWriter(d / JOURNAL, KEY)
    w.append(*_entry(9, "d"))
    w.close()
    assert compact(d) and (d / MANIFEST).read_bytes() == before


def test_torn_last_line_is_ignored_and_cut_before_the_next_append(tmp_path):
    d = _new(tmp_path)
    w = JournalWriter(d / JOURNAL, KEY)
    w.append(*_entry(1))
    w.close()
    whole = (d / JOURNAL).read_bytes()
    line = json.dumps({"name": "0002_T1", "entry": _entry(2)[1]}).encode()
    (d / JOURNAL).write_bytes(whole + line[:40])  # killed in the middle of a write
    scan = JournalScan()
    assert [e["index"] for _, _, e in iter_journal(d / JOURNAL, 10, scan)] == [1]
    assert scan.torn and not scan.bad and scan.problem() is None and scan.good_end == len(whole)
    w = JournalWriter(d / JOURNAL, KEY, scan.good_end)
    w.append(*_entry(3))
    w.close()
    scan = JournalScan()
    assert [e["index"] for _, _, e in iter_journal(d / JOURNAL, 10, scan)] == [1, 3] and not scan.torn


def test_damaged_line_is_reported_in_one_line_and_skipped(tmp_path):
    d = _new(tmp_path)
    w = JournalWriter(d / JOURNAL, KEY)
    for i in (1, 2, 3):
        w.append(*_entry(i))
    w.close()
    lines = (d / JOURNAL).read_bytes().split(b"\n")
    lines[2] = lines[2][:30] + b"#garbage#" + lines[2][39:]  # image 2's line
    (d / JOURNAL).write_bytes(b"\n".join(lines))
    pos, scan = journal_positions(d, 10, KEY)
    assert list(np.flatnonzero(pos >= 0)) == [1, 3] and scan.bad == [3]
    assert "\n" not in scan.problem() and "1 damaged line" in scan.problem()
    compact(d)
    assert [e["index"] for e in json.loads((d / MANIFEST).read_text())["images"].values()] == [1, 3]


def test_journal_of_another_spec_and_damaged_manifest_are_one_line_errors(tmp_path):
    d = _new(tmp_path)
    JournalWriter(d / JOURNAL, "cd" * 32).close()
    with pytest.raises(InputError, match="another spec"):
        compact(d)
    (d / JOURNAL).unlink()
    text = (d / MANIFEST).read_text()
    for bad, why in [(text[:-3], "not an edgetruth manifest"), ("{oops\n", "not valid JSON"),
                     (text.replace("}}\n", '"x": 1}}\n').replace('images": {\n', 'images": {\n"0001_T1": 3,\n'),
                      "not an edgetruth manifest")]:
        (d / MANIFEST).write_text(bad)
        with pytest.raises(InputError, match=why) as exc:
            list(ManifestReader(d / MANIFEST))
        assert "\n" not in str(exc.value)


def test_older_whole_json_manifest_is_read_and_compacted_to_the_line_layout(tmp_path):
    entries = dict(_entry(i) for i in (4, 1))
    legacy = {"format": 1, "spec": "s", "spec_sha256": KEY, "n_images": 10, "images": entries}
    (tmp_path / MANIFEST).write_text(json.dumps(legacy, indent=1) + "\n")
    r = ManifestReader(tmp_path / MANIFEST)
    assert not r.streamable and [e["index"] for _, e in r] == [1, 4]
    assert compact(tmp_path) and ManifestReader(tmp_path / MANIFEST).streamable
    m = json.loads((tmp_path / MANIFEST).read_text())
    assert m["images"] == dict(sorted(entries.items())) and m["n_images"] == 10


def test_lines_are_synced_in_the_background_in_groups_and_a_failed_sync_is_raised(tmp_path):
    import time

    d = _new(tmp_path)
    w = JournalWriter(d / JOURNAL, KEY)
    for i in range(200):
        w.append(*_entry(i % 10))
    end = time.monotonic() + 10
    while w.n_syncs == 0 and time.monotonic() < end:
        time.sleep(0.01)
    assert 1 <= w.n_syncs <= 200  # group commit: one sync covers the lines written meanwhile
    w.close()
    assert sum(1 for _ in iter_journal(d / JOURNAL, 10, JournalScan())) == 200

    w = JournalWriter(d / JOURNAL, KEY, (d / JOURNAL).stat().st_size)

    def broken(fd):
        raise OSError(5, "Input/output error")

    w._sync = broken
    w.append(*_entry(1))
    end = time.monotonic() + 10
    while w._error is None and time.monotonic() < end:
        time.sleep(0.01)
    with pytest.raises(OSError, match="cannot sync the journal"):
        w.append(*_entry(2))
    with pytest.raises(OSError):
        w.close()
    assert w.fd is None
