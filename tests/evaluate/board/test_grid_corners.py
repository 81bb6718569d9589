"""A chessboard's inner corners from an edge method's grid lines (``line_corners``), against the truth and against
cornerSubPix, and ``edgetruth calibrate --corners lines`` on rendered boards of a known camera."""
import json

import cv2
import numpy as np
import pytest

from edgetruth.cli import main
from edgetruth.evaluate.board import chessboard as cb
from edgetruth.evaluate.board.grid_corners import line_corners, open_halves, to_opencv_order
from edgetruth.evaluate.calibration import detect_corners
from tests.evaluate.board.board_images import apply_h
from tests.evaluate.board.chessboard_images import K, ROTATIONS, SHAPE, render

ROTATIONS_6 = ROTATIONS + [(0.1, 0.2, 0.4), (-0.2, -0.1, -0.3)]


def true_inner_corners(h, pattern=(9, 6)):
    cols, rows = pattern
    g = np.stack(np.meshgrid(np.arange(cols), np.arange(rows)), axis=2).reshape(-1, 2).astype(float)
    return apply_h(h, g)


def nearest_error(got, truth):
    """Each corner's distance (px) to its nearest true inner corner (OpenCV may number from either end)."""
    return np.linalg.norm(got[:, None] - truth[None], axis=2).min(axis=1)


@pytest.mark.parametrize("flip", [False, True])
def test_line_corners_land_on_the_true_inner_corners(flip):
    """Exact edges (sigma 0.5 px): every inner corner comes back, the two open corners (grid corners whose square
    between the inner corners is light) included, in OpenCV's order, far closer to the truth than cornerSubPix's.
    Measured (4 views): mean error 0.0005 px (max 0.010) against 0.032 px for cornerSubPix; the same on the mirror
    image."""
    errs, subs = [], []
    for r in ROTATIONS:
        img, h = render((9, 6), r)
        truth = true_inner_corners(h)
        if flip:
            img = img[:, ::-1]
            truth = truth * [-1, 1] + [SHAPE[1] - 1, 0]
        got = line_corners(img, (9, 6))
        sub = detect_corners(img, (9, 6))
        ok = np.all(np.isfinite(got), axis=1)
        assert ok.sum() == 54
        # OpenCV's order: where both are measured, the line corner and cornerSubPix's are the same inner corner
        assert np.linalg.norm(got[ok] - sub[ok], axis=1).max() < 0.2
        errs.append(nearest_error(got[ok], truth))
        subs.append(nearest_error(sub[ok], truth))
    e, s = np.concatenate(errs), np.concatenate(subs)
    assert e.mean() < 0.002 and e.max() < 0.015
    assert e.mean() < s.mean() / 10


def test_calibrate_with_line_corners(tmp_path):
    """`edgetruth calibrate --corners lines` on 6 rendered views (8-bit, exact edges, no distortion, fx 600):
    the camera comes back closer than with cornerSubPix.  Measured: RMS 0.0010 against 0.031 px; fx 600.009 against
    600.019; cy 239.4998 against 239.574 (true 239.5)."""
    for i, r in enumerate(ROTATIONS_6):
        img, _ = render((9, 6), r)
        cv2.imwrite(str(tmp_path / f"v{i}.png"), np.clip(np.round(img), 0, 255).astype(np.uint8))
    out = {}
    for corners in ("subpix", "lines"):
        rc = main(["calibrate", str(tmp_path), "--pattern", "9x6", "--square-m", "0.025", "--corners", corners,
                   "--model", "k1k2", "-o", str(tmp_path / f"{corners}.json"), "--no-progress"])
        assert rc == 0
        out[corners] = json.loads((tmp_path / f"{corners}.json").read_text())
    lines, sub = out["lines"], out["subpix"]
    assert lines["corners"] == "lines" and "grid lines" in lines["method"]
    assert all(p["corners"] == 54 for p in lines["photos"]) and all(p["corners"] == 54 for p in sub["photos"])
    fx = lambda d: np.array(d["K"])[0, 0]  # noqa: E731
    assert lines["reprojection_rms_px"] < 0.5 * sub["reprojection_rms_px"]
    assert abs(fx(lines) - K[0, 0]) < abs(fx(sub) - K[0, 0])
    assert abs(fx(lines) - K[0, 0]) < 0.05
    assert abs(np.array(lines["K"])[1, 2] - K[1, 2]) < 0.01 < abs(np.array(sub["K"])[1, 2] - K[1, 2])


def test_the_open_corners_come_from_the_grid_lines_into_the_outer_ring():
    """The two inner corners of a 9x6 board that no dark square between the inner corners touches (OpenCV's
    corners 8 and 53 here) are measured on the grid segments either side of them, the outer one in the board's
    outer ring.  Measured (4 views): within 0.002 px of the truth (0.0000-0.0020)."""
    for r in ROTATIONS:
        img, h = render((9, 6), r)
        model = cb.settle_parity([img], cb.chessboard_model((9, 6), 1.0))
        view = cb.find_squares(img, model)
        reached = np.all(np.isfinite(to_opencv_order(np.zeros_like(view.squares.corners), view)), axis=1)
        open_ = np.flatnonzero(~reached)
        assert len(open_) == 2 and set(open_) <= {0, 8, 45, 53}  # two of the grid's four extreme corners
        err = nearest_error(line_corners(img, (9, 6))[open_], true_inner_corners(h))
        assert err.max() < 0.005, err


def test_open_halves_run_to_the_neighbours_and_mirror_past_the_grid():
    """Each half starts at the corner and ends at the next inner corner along its row or column; past the grid's
    edge it ends at the mirror of the corner's neighbour on the other side."""
    cols, rows = 4, 3
    inner = np.stack(np.meshgrid(np.arange(cols) * 10.0, np.arange(rows) * 7.0), axis=2).reshape(-1, 2)
    (row, col), = open_halves(inner, (cols, rows), np.array([0]))  # corner (0, 0): both lines leave the grid
    assert np.allclose(row, [[[0, 0], [-10, 0]], [[0, 0], [10, 0]]])
    assert np.allclose(col, [[[0, 0], [0, -7]], [[0, 0], [0, 7]]])
    (row, col), = open_halves(inner, (cols, rows), np.array([6]))  # corner (row 1, col 2): all four inside
    assert np.allclose(row, [[[20, 7], [10, 7]], [[20, 7], [30, 7]]])
    assert np.allclose(col, [[[20, 7], [20, 0]], [[20, 7], [20, 14]]])
