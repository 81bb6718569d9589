"""``edgetruth verify DIR``: exit 0 intact, 1 problems listed, 2 not a dataset."""
from __future__ import annotations

import json

from edgetruth.cli import main


def _run(capsys, *argv):
    rc = main(["verify", *map(str, argv)])
    cap = capsys.readouterr()
    return rc, cap.out, cap.err


def test_intact_dataset_is_ok(dataset_copy, capsys):
    _, d = dataset_copy
    rc, out, err = _run(capsys, d)
    assert rc == 0 and "OK, 3/3" in out and not err


def test_damage_is_listed_and_exit_1(dataset_copy, capsys):
    _, d = dataset_copy
    (d / "0000_T2.png").write_bytes((d / "0000_T2.png").read_bytes()[:-1] + b"\0")
    (d / "0001_T2.exr").unlink()
    (d / ".tmp-4242-0002_cal.png").write_bytes(b"partial")
    (d / "stray.txt").write_text("x")
    rc, out, _ = _run(capsys, d)
    assert rc == 1
    assert "hash mismatch: 0000_T2.png" in out
    assert "missing: 0001_T2.exr" in out
    assert "extra-temp: .tmp-4242-0002_cal.png" in out
    assert "extra: stray.txt" in out
    assert "1/3 images" in out


def test_partial_dataset_is_incomplete(dataset_copy, capsys):
    _, d = dataset_copy
    m = json.loads((d / "manifest.json").read_text())
    del m["images"]["0002_cal"]
    (d / "manifest.json").write_text(json.dumps(m))
    for ext in ("exr", "png", "json"):
        (d / f"0002_cal.{ext}").unlink()
    rc, out, _ = _run(capsys, d)
    assert rc == 1 and "not rendered: 1 of 3 images" in out


def test_repair_by_rendering_again(dataset_copy, capsys):
    spec, d = dataset_copy
    before = (d / "0000_T2.png").read_bytes()
    (d / "0000_T2.png").write_bytes(b"damaged")
    (d / ".tmp-1-0000_T2.png").write_bytes(b"partial")
    assert main(["render", str(spec), "-o", str(d), "--no-progress", "--workers", "1"]) == 0
    assert (d / "0000_T2.png").read_bytes() == before
    capsys.readouterr()
    assert _run(capsys, d)[0] == 0
