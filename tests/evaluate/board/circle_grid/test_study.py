"""`edgetruth study board --pattern circles:...` (evaluate/board/circle_grid): on six exact synthetic views of an
asymmetric circle grid (tests/evaluate/board/circle_images.py, every pixel the exact coverage of the circles) the
method rows recover the true intrinsics; on the shipped real set the reference row is plain OpenCV's calibration;
bad input is one line and exit 2."""
from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from edgetruth.cli import main
from tests.evaluate.board.circle_images import PATTERN, SPACING_M, write_views

METHODS = "canny_devernay,erf4p_fixed11,dynamic_erf_4p"


def _rows(path):
    with open(path, newline="") as fh:
        return {r["row"]: r for r in csv.DictReader(fh)}


@pytest.fixture(scope="module")
def synthetic_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("circle_views")
    cam, paths = write_views(folder)
    out = folder / "run"
    rc = main(["study", "board", *map(str, paths), "--pattern", PATTERN, "--square", str(SPACING_M * 1000), "-o",
               str(out), "--methods", METHODS, "--no-progress"])
    return rc, cam, out


def test_method_rows_recover_the_true_intrinsics(synthetic_run):
    """Tolerance: fx, fy within 0.05 % and the principal point within 0.5 px of the camera's (the corrected centres
    of tests/evaluate/board/test_circles.py reach 0.05 %); the ellipse residual below 0.02 px on exact edges; the
    blob row (perspective-biased centroids) is reported beside them."""
    rc, cam, out = synthetic_run
    assert rc == 0
    rows = _rows(out / "summary.csv")
    assert list(rows) == [*METHODS.split(","), "opencv_blobs"]
    cx, cy = cam.principal_point_px
    for m in METHODS.split(","):
        r = rows[m]
        assert abs(float(r["fx"]) / cam.fx_px - 1) <= 5e-4, (m, r["fx"], cam.fx_px)
        assert abs(float(r["fy"]) / cam.fy_px - 1) <= 5e-4, (m, r["fy"], cam.fy_px)
        assert abs(float(r["cx"]) - cx) <= 0.5 and abs(float(r["cy"]) - cy) <= 0.5, m
        assert float(r["ellipse_rms_px"]) < 0.02, m
        assert float(r["ellipse_ci_lo"]) <= float(r["ellipse_rms_px"]) <= float(r["ellipse_ci_hi"])
        assert int(r["circles_fitted"]) == int(r["circles_total"]) == 6 * 20
        assert float(r["calib_rms_px"]) < 0.02 and float(r["loo_rms_px"]) < 0.05, m
    ref = rows["opencv_blobs"]
    assert ref["ellipse_rms_px"] == "" and np.isfinite(float(ref["calib_rms_px"]))
    tests = list(csv.DictReader(open(out / "paired_tests.csv")))
    assert {t["family"] for t in tests} == {"ellipse_residual", "reprojection", "loo"}
    assert {t["baseline"] for t in tests} == {"dynamic_erf_4p"}
    report = (out / "report.md").read_text()
    assert "ellipse residual" in report and "Table 2" in report


@pytest.mark.slow
def test_reference_row_is_plain_opencv_on_the_shipped_set(tmp_path):
    """OpenCV's blob centroids on sony_hx5v_circles calibrate as plain OpenCV does (assets/real/README.md,
    tests/evaluate/board/test_real_sets.py): RMS 0.450 px, fx 454.10, fy 451.93, cx 322.47, cy 242.45 (to 0.01
    px); image00000 and image00004 skipped with why."""
    out = tmp_path / "run"
    assert main(["study", "board", "sony_hx5v_circles", "-o", str(out), "--methods", "erf4p_fixed11",
                 "--no-progress"]) == 0
    ref = _rows(out / "summary.csv")["opencv_blobs"]
    assert float(ref["calib_rms_px"]) == pytest.approx(0.450, abs=5e-4)
    np.testing.assert_allclose([float(ref[k]) for k in ("fx", "fy", "cx", "cy")], [454.10, 451.93, 322.47, 242.45],
                               atol=0.01)
    photos = list(csv.DictReader(open(out / "per_photo.csv")))
    assert [p["photo"] for p in photos if p["used"] == "no"] == ["image00000.jpg", "image00004.jpg"]
    assert all("findCirclesGrid did not find" in p["why_skipped"] for p in photos if p["used"] == "no")
    cal = json.loads((out / "calibration" / "opencv_blobs.json").read_text())
    assert cal["photos"] == ["image00001.jpg", "image00002.jpg", "image00003.jpg", "image00005.jpg"]


@pytest.mark.parametrize("args, words", [
    (["--pattern", "circles:10x8"], "--square"),
    (["--pattern", "circles:10x8", "--square", "-3"], "--square"),
    (["--pattern", "circles:10x8", "--square", "25", "--tone", "srgb"], "--tone"),
    (["--pattern", "circles:7x5", "--square", "25"], "found on 0 of"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, args, words):
    """One line on stderr naming the input and the fix, exit 2, nothing written."""
    from edgetruth.resources import real_set

    photos = [str(p) for p in sorted(real_set("sony_hx5v_circles").glob("*.jpg"))[:3]]
    out = tmp_path / "run"
    rc = main(["study", "board", *photos, *args, "-o", str(out), "--methods", "erf4p_fixed11", "--no-progress"])
    err = capsys.readouterr().err.strip()
    assert rc == 2
    assert len(err.splitlines()) == 1 and words in err, err
    assert not out.exists()
