"""A command that fails leaves what an earlier run wrote byte for byte: everything that can fail
(variant, methods, plug-ins, thresholds, seed overlaps, calibration, output folder) is checked
before the first write.  One case per command and option that can fail after the folder exists."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from edgetruth.cli import main
from edgetruth.evaluate.run_dir import prepare_run_dir
from edgetruth.locate import thresholds as thr

from tests.support.files import tree_hash


def _earlier_run(path: Path, kind: str) -> Path:
    prepare_run_dir(path, kind, {"limit": 1, "calib_limit": 4, "methods": ["canny_pixel"]})
    (path / "report.md").write_text("# an earlier report\n")
    (path / "calibration.json").write_text(json.dumps({"K": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}))
    return path


def _overlapping_thresholds(dataset: Path, path: Path) -> Path:
    """Render-calibrated thresholds whose calibration images are the dataset's own (seed overlap)."""
    from edgetruth.render import open_dataset

    shipped = json.loads(thr.source(None).read_text())
    images = [{"image": s.name, "seeds": s.truth.get("seeds", {})} for s in open_dataset(dataset).targets()]
    shipped.setdefault("provenance", {})["data"] = {"images": images}
    path.write_text(json.dumps(shipped))
    return path


@pytest.fixture
def earlier(tmp_path, tiny_dataset):
    _, data = tiny_dataset
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "cal.json").write_text(json.dumps({"not": "a calibration"}))
    (bad / "tau.json").write_text(json.dumps({"models": {"4p": {"tau": [0.9, 0.2, 0.1]}}}))
    return {"data": str(data), "bad": str(bad), "tmp": tmp_path,
            "overlap": str(_overlapping_thresholds(data, tmp_path / "overlap.json"))}


CASES = [
    ("run", "run", ["run", "-o", "{OUT}", "--variant", "nosuch_rgb", "--limit", "1"], "--variant"),
    ("run", "run", ["run", "-o", "{OUT}", "--methods", "nope"], "unknown method"),
    ("run", "run", ["run", "-o", "{OUT}", "--plugin", "no_such_module_xyz"], "no module named"),
    ("run", "run", ["run", "-o", "{OUT}", "--thresholds", "{BAD}/tau.json"], "tau.json"),
    ("run", "run", ["run", "-o", "{OUT}", "--camera-thresholds", "{BAD}/tau.json"], "tau.json"),
    ("evaluate", "evaluate", ["evaluate", "{DATA}", "-o", "{OUT}", "--calibration", "{BAD}/cal.json"],
     "not an edgetruth calibration"),
    ("evaluate", "evaluate", ["evaluate", "{DATA}", "-o", "{OUT}", "--camera-thresholds", "{OVERLAP}"],
     "calibrated on"),
    ("evaluate", "evaluate", ["evaluate", "{DATA}", "-o", "{OUT}", "--methods", "nope"], "unknown method"),
    ("study", "synthetic", ["study", "synthetic", "-o", "{OUT}", "--thresholds", "{BAD}/tau.json"], "tau.json"),
    ("study", "board", ["study", "board", "zhang1998", "-o", "{OUT}", "--methods", "nope"], "unknown method"),
    ("render", "render", ["render", "quick", "-o", "{DATA}", "--variant", "nosuch_rgb"], "--variant"),
    ("calibrate-thresholds", "thr", ["calibrate-thresholds", "--dataset", "{DATA}", "-o", "{OUT}/t.json",
                                     "--step", "0"], "--step"),
]


@pytest.mark.parametrize("command, kind, argv, expect", CASES,
                         ids=[f"{c[0]}-{i}" for i, c in enumerate(CASES)])
def test_failed_command_keeps_the_earlier_output(command, kind, argv, expect, earlier, capsys):
    out = _earlier_run(earlier["tmp"] / "earlier", kind if kind in ("run", "evaluate") else "run")
    watched = Path(earlier["data"]) if "{DATA}" in argv[argv.index("-o") + 1] else out
    argv = [a.format(OUT=out, DATA=earlier["data"], BAD=earlier["bad"], OVERLAP=earlier["overlap"]) for a in argv]
    before = tree_hash(watched)
    try:
        rc = main(argv)
    except SystemExit as exc:  # argparse
        rc = exc.code
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and expect in err[0], err
    assert tree_hash(watched) == before, f"{command}: the earlier output changed"
