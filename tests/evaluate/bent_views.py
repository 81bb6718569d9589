"""Analytic views of a 9x6 chessboard, flat or curled per view, projected by cv2.projectPoints (the truth the
bent-board check and its solver are tested against)."""
from __future__ import annotations

import cv2
import numpy as np

from edgetruth.evaluate.board_bend import monomials
from edgetruth.evaluate.calibration import object_points

SQUARE_M = 0.025
K_TRUE = np.array([[530.0, 0, 330], [0, 531.0, 245], [0, 0, 1]])
DIST_TRUE = np.array([-0.28, 0.06, 0.002, -0.0005, 0.1])


def view_poses(n_views: int, rng) -> list[tuple[np.ndarray, np.ndarray]]:
    """Board poses 0.35-0.5 m away, tilted up to ~35 degrees, the board's centre near the optical axis."""
    out = []
    for _ in range(n_views):
        r = rng.uniform(-0.6, 0.6, 3) * np.array([1, 1, 0.3])
        R, _ = cv2.Rodrigues(r)
        centre = np.array([4, 2.5, 0]) * SQUARE_M
        t = np.array([rng.uniform(-0.03, 0.03), rng.uniform(-0.03, 0.03), rng.uniform(0.35, 0.5)]) - R @ centre
        out.append((r, t))
    return out


def curled_views(curl_mm: np.ndarray, noise_px: float, seed: int = 3):
    """13 views of a 9x6 board, view v's height z = curl_mm[v] * (x̂², x̂ŷ, ŷ²) (mm at the normalised edge),
    projected by cv2.projectPoints with K_TRUE, DIST_TRUE, plus Gaussian noise; and the flat calibration of them."""
    rng = np.random.default_rng(seed)
    obj = object_points((9, 6), SQUARE_M).astype(np.float64)
    terms, s = monomials(obj[:, :2])
    images = []
    for (r, t), c in zip(view_poses(len(curl_mm), rng), curl_mm):
        bent = obj.copy()
        bent[:, 2] = terms @ (np.asarray(c) * 1e-3)
        p, _ = cv2.projectPoints(bent, r, t, K_TRUE, DIST_TRUE)
        images.append((p[:, 0] + rng.normal(0, noise_px, (len(obj), 2))).astype(np.float32))
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 200, 1e-12)
    rms, K, dist, rv, tv = cv2.calibrateCamera([obj.astype(np.float32)] * len(images), images, (640, 480), None,
                                               None, criteria=crit)
    return [obj[:, :2]] * len(images), images, K, dist.ravel(), rv, tv, terms, s
