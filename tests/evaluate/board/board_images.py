"""Synthetic photos of a board of dark squares with exact side lines (test support, not a test module).

Each square is the intersection of four half-planes; its image under a homography is a convex
quad whose sides are exact lines.  A pixel's value is the exact pixel-area mean of a Gaussian-
blurred step across each side (``edgetruth.render.synthetic.analytic.StepProfile.pixel_mean_straight``),
multiplied over the square's four sides: exact wherever only one side lies within the blurred
pixel's reach (farther than ~4 sigma + 1 px from the other sides), i.e. everywhere the study
takes points (3 px from the corners with sigma <= 0.5 px).
"""
from __future__ import annotations

import numpy as np

from edgetruth.conventions import pixel_centres
from edgetruth.render.synthetic.analytic import StepProfile


def grid_model(cols: int, rows: int, side: float = 1.0, pitch: float = 1.6) -> np.ndarray:
    """(cols*rows, 4, 2) squares, corners clockwise with +y down (as Zhang's), row by row from y = 0."""
    jj, ii = np.meshgrid(np.arange(cols), np.arange(rows))
    x0, y0 = jj.ravel() * pitch, ii.ravel() * pitch
    unit = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float) * side
    return np.stack([x0, y0], axis=1)[:, None, :] + unit[None]


def apply_h(h: np.ndarray, pts: np.ndarray) -> np.ndarray:
    p = np.asarray(pts, float)
    q = p @ h[:, :2].T + h[:, 2]
    return q[..., :2] / q[..., 2:3]


def camera_homography(K: np.ndarray, rvec, tvec) -> np.ndarray:
    """Model plane Z = 0 -> image: K [r1 r2 t]."""
    import cv2

    R, _ = cv2.Rodrigues(np.asarray(rvec, float))
    return K @ np.c_[R[:, 0], R[:, 1], np.asarray(tvec, float)]


def render_board(shape, image_quads: np.ndarray, sigma_px: float = 0.5, dark: float = 40.0,
                 bright: float = 210.0) -> np.ndarray:
    """Float image of dark quads (S, 4, 2, convex, in image px) on a bright background."""
    profile = StepProfile(sigma_px, sigma_px)
    x, y = pixel_centres(shape)
    cover = np.zeros(shape)
    reach = 4 * sigma_px + 2
    for q in np.asarray(image_quads, float):
        x0, y0 = np.floor(q.min(axis=0) - reach).astype(int)
        x1, y1 = np.ceil(q.max(axis=0) + reach).astype(int)
        sl = (slice(max(y0, 0), y1 + 1), slice(max(x0, 0), x1 + 1))
        xs, ys = x[sl], y[sl]
        c = q.mean(axis=0)
        m = np.ones(xs.shape)
        for k in range(4):
            a, b = q[k], q[(k + 1) % 4]
            e = (b - a) / np.linalg.norm(b - a)
            n = np.array([-e[1], e[0]])
            if n @ (c - a) < 0:
                n = -n  # towards the inside
            d0 = (xs - a[0]) * n[0] + (ys - a[1]) * n[1]
            m *= profile.pixel_mean_straight(d0.ravel(), n[0], n[1]).reshape(xs.shape)
        cover[sl] += m
    return bright - (bright - dark) * cover


def side_offsets(normal: np.ndarray, offset: np.ndarray, truth_quads: np.ndarray) -> np.ndarray:
    """(S, 4, 2): distance of each true side's two end corners to the fitted line n.p = d of that side."""
    a = truth_quads
    b = np.roll(truth_quads, -1, axis=1)
    da = (normal * a).sum(axis=2) - offset
    db = (normal * b).sum(axis=2) - offset
    return np.stack([da, db], axis=2)
