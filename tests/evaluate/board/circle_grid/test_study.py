"""`edgetruth study board --pattern circles:...` (evaluate/board/circle_grid): on six exact synthetic views of an
asymmetric circle grid (tests/evaluate/board/circle_images.py, every pixel the exact coverage of the circles) the
method rows recover the true intrinsics; bad input is one line and exit 2.  On the shipped real set the reference
row is plain OpenCV's calibration: tests/evaluate/board/test_real_sets.py."""
from __future__ import annotations

import csv

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
    cam, paths, truths = write_views(folder)
    out = folder / "run"
    rc = main(["study", "board", *map(str, paths), "--pattern", PATTERN, "--square", str(SPACING_M * 1000), "-o",
               str(out), "--methods", METHODS, "--no-progress"])
    return rc, cam, truths, out


def _centre_errors(out, truths) -> dict:
    """Per row: RMS distance (px) of its circle centres (per_circle.csv) from the true images of the circles'
    centres (distorted)."""
    per: dict = {}
    with open(out / "per_circle.csv", newline="") as fh:
        for r in csv.DictReader(fh):
            per.setdefault(r["row"], {}).setdefault(r["image"], []).append((float(r["x_px"]), float(r["y_px"])))
    return {row: float(np.sqrt(np.mean(np.concatenate(
        [np.sum((np.array(p[f"v{k}.png"]) - np.asarray(t["centre_distorted_px"])) ** 2, axis=1)
         for k, t in enumerate(truths)])))) for row, p in per.items()}


def test_method_rows_recover_the_true_intrinsics(synthetic_run):
    """Tolerance against the exact truth: each method row's fx, fy within 0.1 % (measured 0.033-0.054 %) and its
    principal point within 0.5 px (measured <= 0.2 px) of the camera's; its centres within 0.01 px RMS of the true
    images of the circles' centres (measured 0.0035-0.0053 px) and closer than OpenCV's perspective-biased blob
    centroids (0.036 px); the ellipse residual below 0.1 px on these exact edges (measured 0.027-0.068 px)."""
    rc, cam, truths, out = synthetic_run
    assert rc == 0
    rows = _rows(out / "summary.csv")
    assert list(rows) == [*METHODS.split(","), "opencv_blobs"]
    cx, cy = cam.principal_point_px
    errors = _centre_errors(out, truths)
    for m in METHODS.split(","):
        r = rows[m]
        assert abs(float(r["fx"]) / cam.fx_px - 1) <= 1e-3, (m, r["fx"], cam.fx_px)
        assert abs(float(r["fy"]) / cam.fy_px - 1) <= 1e-3, (m, r["fy"], cam.fy_px)
        assert abs(float(r["cx"]) - cx) <= 0.5 and abs(float(r["cy"]) - cy) <= 0.5, m
        assert float(r["ellipse_rms_px"]) < 0.1, m
        assert errors[m] <= 0.01 and errors[m] < errors["opencv_blobs"], (m, errors)
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


@pytest.mark.parametrize("args, words", [
    (["--pattern", "circles:10x8"], "--square"),
    (["--pattern", "circles:10x8", "--square", "-3"], "--square"),
    (["--pattern", "circles:10x8", "--square", "25", "--tone", "srgb"], "--tone"),
    (["--pattern", "circles:10x8", "--square", "25"], "found on 1 of 3"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, args, words):
    """One line on stderr naming the input and the fix, exit 2, nothing written."""
    from edgetruth.resources import real_set

    folder = real_set("sony_hx5v_circles")
    photos = [str(folder / f"image0000{k}.jpg") for k in (0, 1, 4)]  # the grid found in image00001 only
    out = tmp_path / "run"
    rc = main(["study", "board", *photos, *args, "-o", str(out), "--methods", "erf4p_fixed11", "--no-progress"])
    err = capsys.readouterr().err.strip()
    assert rc == 2
    assert len(err.splitlines()) == 1 and words in err, err
    assert not out.exists()
