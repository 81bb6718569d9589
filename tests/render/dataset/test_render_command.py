"""``edgetruth render`` on the command line."""
from __future__ import annotations

import json

from edgetruth.cli import main

from edgetruth.render.testing import write_tiny_spec as _spec


def test_unknown_spec_exits_2(capsys):
    assert main(["render", "no-such-spec", "-o", "/tmp/x"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not found" in err


def test_render_and_resume(tmp_path, capsys):
    spec = _spec(tmp_path)
    out = tmp_path / "out"
    assert main(["render", str(spec), "-o", str(out), "--only", "0", "--no-progress"]) == 0
    first = capsys.readouterr().out
    assert "using Mitsuba variant" in first and "1/3" in first
    assert main(["render", str(spec), "-o", str(out), "--only", "0", "--no-progress"]) == 0
    assert "nothing to do" in capsys.readouterr().out
    assert set(json.loads((out / "manifest.json").read_text())["images"]) == {"0000_T2"}
    assert main(["render", str(spec), "-o", str(out), "--only", "x"]) == 2
