"""`edgetruth calibrate --pattern circles:...`: circle grids, OpenCV's blob centroids as the reference row and
edgetruth's ellipse centres (plain and corrected for perspective), on the shipped real set sony_hx5v_circles
(BoofCV-Data, 10x8 symmetric, 25 mm): the blob row reproduces plain OpenCV's own calibration (assets/real/README.md:
fx 454.10, fy 451.93, cx 322.47, cy 242.45 px, RMS 0.450 px)."""
from __future__ import annotations

import json

import pytest

from edgetruth.cli import main


def _run(argv, capsys):
    try:
        rc = main(argv)
    except SystemExit as exc:
        rc = exc.code
    cap = capsys.readouterr()
    return rc, cap.out, cap.err


@pytest.mark.slow
def test_blob_row_reproduces_plain_opencv_and_the_edge_rows_run(tmp_path, capsys):
    out = tmp_path / "blobs.json"
    rc, o, e = _run(["calibrate", "sony_hx5v_circles", "--pattern", "circles:10x8", "--square-m", "0.025",
                     "--no-progress", "-o", str(out)], capsys)
    assert rc == 0, e
    d = json.loads(out.read_text())
    fx, fy, cx, cy = (d[n] for n in ("fx_px", "fy_px", "cx_px", "cy_px"))
    assert (round(fx, 2), round(fy, 2), round(cx, 2), round(cy, 2)) == (454.10, 451.93, 322.47, 242.45)
    assert d["pattern"] == {"kind": "circles", "pattern_size": [10, 8], "asymmetric": False}
    assert sum(p["found"] for p in d["photos"]) == 4
    corr = tmp_path / "corrected.json"
    rc, o, e = _run(["calibrate", "sony_hx5v_circles", "--pattern", "circles:10x8", "--square-m", "0.025",
                     "--centres", "corrected", "--no-progress", "-o", str(corr)], capsys)
    assert rc == 0, e
    c = json.loads(corr.read_text())
    assert c["centres"] == "corrected" and c["circle_rounds"] >= 1 and 0.005 < c["circle_radius_m"] < 0.01
    print(o.strip())


@pytest.mark.parametrize("extra, says", [
    (["--board", "bent"], "--board: not for a circle grid"),
    (["--centres", "middle"], "--centres 'middle'"),
])
def test_circle_grid_options_refused_in_one_line(tmp_path, capsys, extra, says):
    rc, o, e = _run(["calibrate", "sony_hx5v_circles", "--pattern", "circles:10x8", "--square-m", "0.025",
                     "-o", str(tmp_path / "x.json"), *extra], capsys)
    assert rc == 2 and says in e and len(e.strip().splitlines()) == 1
    assert not (tmp_path / "x.json").exists()


def test_centres_only_with_a_circle_grid(tmp_path, capsys):
    rc, o, e = _run(["calibrate", "opencv_left", "--pattern", "9x6", "--square-m", "0.025", "--centres", "conic",
                     "-o", str(tmp_path / "x.json")], capsys)
    assert rc == 2 and "only with a circle-grid --pattern" in e
