"""The twin report's flatness check (``twin.flatness``): a chessboard's shared junctions count once, and a board
of squares curled per view reads as bent where a flat one does not."""
from __future__ import annotations

import cv2
import numpy as np

from edgetruth.evaluate.board.detect import chessboard as cb
from edgetruth.evaluate.board.twin.flatness import board_flatness, unique_corners
from tests.evaluate.bent_views import DIST_TRUE, K_TRUE, view_poses


def test_a_chessboards_junctions_count_once():
    """OpenCV's 9x6 chessboard model (20 dark squares between the inner corners): its 80 square corners are 52
    distinct junctions (each inner junction is a corner of two dark squares)."""
    model = cb.chessboard_model((9, 6), 1.0)
    idx = unique_corners(model.corners)
    pts = model.corners.reshape(-1, 2)[idx]
    assert len(idx) == len(np.unique(pts, axis=0)) == 52 and model.corners.size // 2 == 80


def _square_views(curl_mm: float, n_views: int = 8, noise_px: float = 0.02):
    """A chessboard model (25 mm squares) seen in ``n_views`` poses, each view curled by ``curl_mm`` along ŷ²."""
    rng = np.random.default_rng(5)
    model = cb.chessboard_model((9, 6), 1.0)
    obj = model.corners.reshape(-1, 2) * 0.025
    c = obj.mean(0)
    s = np.abs(obj - c).max()
    z = curl_mm * 1e-3 * ((obj[:, 1] - c[1]) / s) ** 2
    views = []
    for r, t in view_poses(n_views, rng):
        p, _ = cv2.projectPoints(np.c_[obj, z], r, t, K_TRUE, DIST_TRUE)
        views.append((p[:, 0] + rng.normal(0, noise_px, obj.shape)).reshape(model.corners.shape))
    return views, model.corners


def test_a_curled_board_reads_bent_and_a_flat_one_does_not():
    """0.5 mm of curl at ŷ = 1 over 0.02 px of noise: most of the 5-term calibration's residual is the bend
    (measured 0.77), found at its depth (0.5 × the corners' ŷ² span, within 0.05 mm); flat: chance, p not small."""
    views, corners = _square_views(0.5)
    f = board_flatness(views, corners, (640, 480), unit_m=0.025)
    q = f["quadratic"]
    assert f["views"] == 8 and f["corners"] == 8 * 52
    obj = corners.reshape(-1, 2)
    yh = (obj[:, 1] - obj[:, 1].mean()) / np.abs(obj - obj.mean(0)).max()
    assert q["bend_share"] > 0.6 and abs(q["depth_mm_median"] - 0.5 * np.ptp(yh ** 2)) < 0.05
    flat = board_flatness(*_square_views(0.0), (640, 480), unit_m=0.025)["quadratic"]
    assert abs(flat["bend_share"] - flat["bend_share_chance"]) < 0.05 and flat["p_value"] > 0.01


def test_too_few_views():
    views, corners = _square_views(0.0, n_views=2)
    assert board_flatness(views, corners, (640, 480), 0.025) == {}
