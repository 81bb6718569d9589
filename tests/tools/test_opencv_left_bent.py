"""tools/twins/opencv_left_bent.py: the shipped bent twin (scenes/opencv_left_twin_bent.toml) is the flat twin plus
each photo's bend as edgetruth calibrate measures it on the shipped photos, rescaled to the renderer's s."""
from __future__ import annotations

import json

import pytest

from tests.support.tools import load_tool


@pytest.fixture(scope="module")
def tool():
    return load_tool("tools/twins/opencv_left_bent.py", "opencv_left_bent")


def test_shipped_bent_twin_is_the_photos_bend(tool, tmp_path):
    """Calibrating the shipped photos now and writing the spec gives the shipped file byte for byte; it differs from
    the flat twin only in its header, name, description and one board_bend_mm a group."""
    from edgetruth.cli import main

    out = tmp_path / "cal.json"
    assert main(["calibrate", "opencv_left", "--pattern", "9x6", "--square-m", "0.025", "--corners", "lines",
                 "-o", str(out), "--no-progress"]) == 0
    s_render_mm = 112.25  # (8 squares + 2 x 0.490 of the ring) x 25 mm / 2
    text = tool.bent_twin_text(json.loads(out.read_text()), tool.TWIN.read_text(), s_render_mm)
    assert text == tool.OUT.read_text()
    flat = tool.TWIN.read_text().splitlines()
    extra = [ln for ln in text.splitlines() if ln not in flat]
    assert sum(ln.startswith("board_bend_mm = ") for ln in extra) == 13
    assert {ln.split(" =")[0] for ln in extra if not ln.startswith("#")} == {"board_bend_mm", "name", "description"}


def test_renderer_scale_is_the_squares_half_side():
    """The scale the tool converts to is the renderer's own for the twin's board (112.25 mm)."""
    from edgetruth.render.dataset.spec import load_spec
    from edgetruth.render.scene.bend import BoardBend

    spec = load_spec("opencv_left_twin_bent")
    assert BoardBend.of((0, 0, 0), spec.squares.black_quads_local(0.0)).scale_m == pytest.approx(0.11225, abs=1e-12)
    assert all(g.board_bend_mm is not None and len(g.board_bend_mm) == 3 for g in spec.groups)


def test_twin_bend_is_the_shipped_bent_twins():
    """`edgetruth twin --bend`'s curls (``twin_derive.bend_mm``, the derivation's own calibration in squares) on the
    shipped photos are the shipped bent twin's, written from `edgetruth calibrate`'s JSON in metres, to its
    rounding (measured: within 1e-5 mm, the last digit)."""
    import numpy as np

    from edgetruth.evaluate.board.inputs import resolve_inputs
    from edgetruth.evaluate.board.twin_derive import bend_mm, measure_chessboard
    from edgetruth.render.dataset.spec import load_spec

    m = measure_chessboard(resolve_inputs(["opencv_left"]).photos, (9, 6))
    shipped = np.array([g.board_bend_mm for g in load_spec("opencv_left_twin_bent").groups])
    assert np.abs(np.array(bend_mm(m, [0.490, 0.955], 0.025)) - shipped).max() <= 2e-5
