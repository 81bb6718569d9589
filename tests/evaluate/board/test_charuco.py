"""ChArUco boards in photos (``edgetruth.evaluate.board.charuco``, ``edgetruth calibrate --pattern charuco:...``).

On synthetic views (OpenCV's own board image seen through a pinhole camera of known K by a homography, on a 4x finer
grid averaged to box pixels, blurred a little, 8-bit): the reference row is plain OpenCV (CharucoDetector, matchImagePoints, calibrateCamera) to 1e-6 in K, 1e-5 in the
distortion (the object points sit one square apart, which moves the solver's last digits);
both rows find K near the truth (k1, k2 free); edgetruth's line corners sit on the true corners; bad options are one line.
"""
from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from edgetruth.errors import InputError
from edgetruth.evaluate.board import charuco as ch
from edgetruth.evaluate.pattern import parse_board_pattern
from edgetruth.evaluate.calibration import DIST_MODELS, calibrate_photos

K = np.array([[600.0, 0.0, 319.5], [0.0, 600.0, 239.5], [0.0, 0.0, 1.0]])
SIZE = (640, 480)
PX_PER_M = 4000.0  # the board image's resolution (0.25 mm per pixel)
BOARD = ch.board_of(parse_board_pattern("charuco:5x7:DICT_4X4_50"), 0.04, 0.03)
POSES = [((0.25, -0.2, 0.05), (-0.09, -0.13, 0.62)), ((-0.3, 0.15, -0.1), (-0.11, -0.14, 0.6)),
         ((0.1, 0.35, 0.3), (-0.12, -0.12, 0.65)), ((-0.2, -0.3, -0.25), (-0.07, -0.15, 0.63)),
         ((0.35, 0.1, 0.0), (-0.1, -0.11, 0.6)), ((0.0, -0.35, 0.15), (-0.13, -0.13, 0.66))]


def _view(rvec, tvec) -> tuple[np.ndarray, np.ndarray]:
    """(8-bit image, true corners (K, 2)) of the board at pose (rvec, tvec) in OpenCV's board frame."""
    w, h = int(BOARD.cols * BOARD.square_m * PX_PER_M), int(BOARD.rows * BOARD.square_m * PX_PER_M)
    src = BOARD.cv_board().generateImage((w, h), marginSize=0, borderBits=1)
    src = cv2.copyMakeBorder(src, 40, 40, 40, 40, cv2.BORDER_CONSTANT, value=255)  # a white margin
    r = cv2.Rodrigues(np.asarray(rvec, float))[0]
    # source pixel (u, v) -> board point ((u - 40 + 0.5) / ppm, (v - 40 + 0.5) / ppm), pixel centres at i + 0.5
    s = np.array([[1 / PX_PER_M, 0, (0.5 - 40) / PX_PER_M], [0, 1 / PX_PER_M, (0.5 - 40) / PX_PER_M], [0, 0, 1]])
    # warped onto a 4x finer grid (its pixel centres: x4 = 4 x + 1.5), then each 4 x 4 block averaged: box pixels
    up = np.array([[4.0, 0, 1.5], [0, 4.0, 1.5], [0, 0, 1]])
    hom = up @ K @ np.c_[r[:, :2], tvec] @ s
    fine = cv2.warpPerspective(src.astype(np.float32), hom, (4 * SIZE[0], 4 * SIZE[1]), flags=cv2.INTER_LINEAR,
                               borderValue=255)
    img = cv2.GaussianBlur(cv2.resize(fine, SIZE, interpolation=cv2.INTER_AREA), (0, 0), 0.7)
    img = np.clip(30 + img * (200 / 255), 0, 255).round().astype(np.uint8)
    truth = cv2.projectPoints(BOARD.corner_object_points(), np.asarray(rvec, float), np.asarray(tvec, float), K,
                              None)[0].reshape(-1, 2)
    return img, truth


@pytest.fixture(scope="module")
def photos(tmp_path_factory):
    d = tmp_path_factory.mktemp("charuco_photos")
    out = []
    for i, (rv, tv) in enumerate(POSES):
        img, truth = _view(rv, tv)
        cv2.imwrite(str(d / f"v{i}.png"), img)
        out.append((f"v{i}.png", d / f"v{i}.png", truth))
    return out


def _plain_opencv(paths, flags):
    """What a user of OpenCV alone does with these photos."""
    detector = cv2.aruco.CharucoDetector(BOARD.cv_board())
    obj, img = [], []
    for p in paths:
        cc, ids, _, _ = detector.detectBoard(cv2.imread(str(p), cv2.IMREAD_GRAYSCALE))
        o, i = BOARD.cv_board().matchImagePoints(cc, ids)
        obj.append(o)
        img.append(i)
    rms, k, dist, _, _ = cv2.calibrateCamera(obj, img, SIZE, None, None, flags=flags)
    return rms, k, dist.ravel()


def test_reference_row_is_plain_opencv(photos):
    finder, label, undistort = ch.corner_finder(BOARD, "subpix")
    cal, results = calibrate_photos([(n, p) for n, p, _ in photos], (4, 6), 0.04, model="k1k2",
                                    corner_finder=finder, corner_label=label)
    rms, k, dist = _plain_opencv([p for _, p, _ in photos], DIST_MODELS["k1k2"][0])
    assert all(r.found and r.corners == 24 for r in results) and not undistort
    np.testing.assert_allclose(cal.K, k, rtol=1e-6)
    np.testing.assert_allclose(cal.dist, dist, rtol=1e-4, atol=1e-5)  # its object points sit one square apart
    assert cal.rms_px == pytest.approx(rms, rel=1e-6)
    assert abs(cal.fx / K[0, 0] - 1) < 0.01 and abs(cal.fy / K[1, 1] - 1) < 0.01


def test_line_corners_lie_on_the_true_corners(photos):
    """OpenCV's corners and the line corners (ERF4P-fixed11, fitted in the photo: no distortion here) against the
    exact projection (measured: 0.05 and 0.035 px RMS), and the calibration from the line corners near K."""
    err = {"opencv": [], "lines": []}
    for _, path, truth in photos:
        img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        err["opencv"].append(ch.charuco_corners(img, BOARD)[0] - truth)
        grid = ch.charuco_grid_points(img, BOARD)
        err["lines"].append(grid.corners() - truth)
    rms = {k: float(np.sqrt(np.nanmean(np.sum(np.concatenate(v) ** 2, 1)))) for k, v in err.items()}
    print(f"corner RMS vs truth: {rms}")
    assert rms["opencv"] < 0.1 and rms["lines"] < 0.06
    finder, label, undistort = ch.corner_finder(BOARD, "lines")
    cal, _ = calibrate_photos([(n, p) for n, p, _ in photos], (4, 6), 0.04, model="k1k2", corner_finder=finder,
                              corner_label=label, undistort_lines=undistort)
    assert abs(cal.fx / K[0, 0] - 1) < 0.01 and abs(cal.fy / K[1, 1] - 1) < 0.01


def test_calibrate_command(photos, tmp_path, capsys):
    from edgetruth.cli import main

    folder = str(photos[0][1].parent)
    out = tmp_path / "cal.json"
    assert main(["calibrate", folder, "--pattern", "charuco:5x7:DICT_4X4_50", "--square-m", "0.04", "--marker-m",
                 "0.03", "-o", str(out), "--no-progress"]) == 0
    doc = json.loads(out.read_text())
    assert doc["charuco"]["marker_m"] == 0.03 and doc["pattern_size"] == [4, 6] and len(doc["photos"]) == 6
    assert "ChArUco" in doc["method"]
    for extra, match in ((["--square-m", "0.04"], "--marker-m"),
                         (["--square-m", "0.04", "--marker-m", "0.05"], "smaller than --square-m")):
        assert main(["calibrate", folder, "--pattern", "charuco:5x7:DICT_4X4_50", *extra, "-o",
                     str(tmp_path / "x.json")]) == 2
        assert match in capsys.readouterr().err
    assert main(["calibrate", folder, "--pattern", "9x6", "--square-m", "0.04", "--marker-m", "0.03", "-o",
                 str(tmp_path / "x.json")]) == 2
    assert "only with a ChArUco" in capsys.readouterr().err
    assert not (tmp_path / "x.json").exists()


def test_board_of_refuses_a_marker_larger_than_its_square():
    with pytest.raises(InputError, match="marker"):
        ch.board_of(parse_board_pattern("charuco:5x7:DICT_4X4_50"), 0.04, 0.04)


def test_board_study_on_charuco_photos(photos, tmp_path, capsys):
    """``study board --pattern charuco:... --marker``: the chessboard study on the ChArUco board's dark squares, its
    grid from OpenCV's CharucoDetector; every photo's 8 squares found, OpenCV's corners as the reference row, fx
    near the truth (600 px) for both rows; --marker is required with a ChArUco pattern and refused without one."""
    import csv

    from edgetruth.cli import main

    folder = str(photos[0][1].parent)
    out = tmp_path / "study"
    assert main(["study", "board", folder, "--pattern", "charuco:5x7:DICT_4X4_50", "--square", "40", "--marker", "30",
                 "--methods", "canny_devernay", "-o", str(out), "--no-progress"]) == 0
    report = (out / "report.md").read_text()
    assert "ChArUco 5x7 squares, markers 0.75 of a square" in report and "CharucoDetector" in report
    assert "| 8 | 8 |" in report  # every photo: all 8 dark squares between the inner corners
    rows = {r["row"]: r for r in csv.DictReader((out / "summary.csv").open())}
    assert set(rows) == {"canny_devernay", "opencv_corners"}
    for r in rows.values():
        assert abs(float(r["fx"]) / K[0, 0] - 1) < 0.005 and abs(float(r["fy"]) / K[1, 1] - 1) < 0.005
    assert main(["study", "board", folder, "--pattern", "charuco:5x7:DICT_4X4_50", "-o", str(tmp_path / "x")]) == 2
    assert "--marker" in capsys.readouterr().err
    assert main(["study", "board", folder, "--pattern", "4x6", "--marker", "0.75", "-o", str(tmp_path / "y")]) == 2
    assert "only a ChArUco board" in capsys.readouterr().err
