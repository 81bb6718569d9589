"""Is the board flat?  The bent-board check (``evaluate.board_bend``) on a board study row's corners, for the twin
report's Table 5: real photos, their twin, and the twin's exact outline side by side.

The study calibrates with k1, k2 only, and a bend per view can stand in for lens terms a model leaves out (the
twins are rendered through 5-term lenses), so here the corners are calibrated afresh with OpenCV's full 5-term
model before the check.  A chessboard's junctions are corners of two dark squares: each is used once.
"""
from __future__ import annotations

import numpy as np

from edgetruth.evaluate.board_bend import bend_check
from edgetruth.evaluate.calibration import free_dist, solve_points

MIN_VIEWS = 3


def unique_corners(model_corners: np.ndarray) -> np.ndarray:
    """Indices into the flattened (S * 4) model corners of each distinct board point, first occurrence."""
    flat = np.asarray(model_corners, float).reshape(-1, 2)
    _, first = np.unique(np.round(flat, 9), axis=0, return_index=True)
    return np.sort(first)


def board_flatness(corners: list[np.ndarray], model_corners: np.ndarray, image_size: tuple[int, int],
                   unit_m: float) -> dict:
    """``corners``: per view (S, 4, 2) image corners of the model's squares (NaN where missing); ``model_corners``
    (S, 4, 2) in board units of ``unit_m`` metres; ``image_size`` (width, height).  Returns {"rms_px": the 5-term
    calibration's RMS, "views", "corners", and ``bend_check``'s models}, or {} with too few views or corners."""
    keep = unique_corners(model_corners)
    obj = np.asarray(model_corners, float).reshape(-1, 2)[keep]
    xy, img = [], []
    for c in corners:
        p = np.asarray(c, float).reshape(-1, 2)[keep]
        ok = np.all(np.isfinite(p), axis=1)
        if ok.sum() >= 8:
            xy.append(obj[ok])
            img.append(p[ok].astype(np.float32))
    if len(xy) < MIN_VIEWS:
        return {}
    poses: list = []
    rms, K, dist, _ = solve_points([np.c_[x, np.zeros(len(x))].astype(np.float32) for x in xy], img, image_size, 0,
                                   poses=poses)
    bend = bend_check(xy, img, K, dist, [r for r, _ in poses], [t for _, t in poses], free_dist(0), unit_m=unit_m)
    if not bend:
        return {}
    return {"rms_px": float(rms), "views": len(xy), "corners": int(sum(len(x) for x in xy)), **bend}
