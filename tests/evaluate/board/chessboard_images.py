"""Rendered views of a chessboard with exact side lines (test support, not a test module): a 9x6 board (10 x 7
squares of side 1) 16 units from a 600 px camera, through ``board_images.render_board``."""
from __future__ import annotations

import cv2
import numpy as np

from tests.evaluate.board.board_images import apply_h, camera_homography, render_board

K = np.array([[600.0, 0, 319.5], [0, 600.0, 239.5], [0, 0, 1]])
SHAPE = (480, 640)
#: board tilts (rvec) for a 9x6 board (10 x 7 squares of side 1, centre at (4, 2.5)), 16 units away
ROTATIONS = [(0.35, -0.25, 0.05), (-0.3, 0.3, 0.1), (0.25, 0.4, -0.15), (-0.4, -0.3, 0.3)]


def board_homography(rvec, centre, distance=16.0):
    R, _ = cv2.Rodrigues(np.array(rvec, float))
    t = np.array([0.0, 0.0, distance]) - R @ np.array([*centre, 0.0])
    return camera_homography(K, rvec, t)


def all_dark_squares(pattern, parity=0):
    """(S, 4, 2) every dark square of the printed board, its outer ring included (inner corner (0, 0) at the
    origin, so the outer squares start at -1)."""
    cols, rows = pattern
    r, c = np.mgrid[-1:rows, -1:cols]
    dark = ((r + c) % 2 == parity).ravel()
    r, c = r.ravel()[dark], c.ravel()[dark]
    return np.stack([np.c_[c, r], np.c_[c + 1, r], np.c_[c + 1, r + 1], np.c_[c, r + 1]], axis=1).astype(float)


def render(pattern, rvec, parity=0, sigma_px=0.5):
    cols, rows = pattern
    h = board_homography(rvec, ((cols - 1) / 2, (rows - 1) / 2))
    quads = apply_h(h, all_dark_squares(pattern, parity))
    assert quads.min() > 5 and quads[..., 0].max() < SHAPE[1] - 5 and quads[..., 1].max() < SHAPE[0] - 5
    return render_board(SHAPE, quads, sigma_px=sigma_px), h


def stored_views(curve, exposures=(1.0, 1.0, 1.0, 1.0), sigma_px: float = 0.5) -> list[np.ndarray]:
    """The views of ``ROTATIONS`` (one per exposure), each linear render (0-255, dark 40, white 210) times its
    exposure on [0, 1], through the tone ``curve`` and stored as 16-bit (full scale 65535)."""
    out = []
    for r, k in zip(ROTATIONS, exposures):
        img, _ = render((9, 6), r, sigma_px=sigma_px)
        out.append(np.round(65535.0 * curve(np.clip(k * img / 255.0, 0.0, 1.0))).astype(np.uint16))
    return out
