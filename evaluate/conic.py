"""Ellipses from edge points, and their centres corrected for perspective.

``fit_ellipse(x, y)``: the direct least-squares ellipse (Fitzgibbon, Pilu & Fisher 1999, in the numerically
stable form of Halíř & Flusser 1998) of points on one closed edge, on coordinates centred and scaled to
unit spread first (float64 throughout), as the 3 x 3 conic matrix in pixels; ``conic_centre`` of it
(``edgetruth.render.scene.circle_conic``).

A circle's image ellipse is centred off the image of the circle's centre (the perspective bias; exact closed
form in ``render.scene.circle_conic``).  ``corrected_centres`` removes it given a pose: measured ellipse centre
minus the bias the pose predicts for a circle of that radius -- the centre of the projected circle from the pose
and the conic.  In a calibration the pose comes from the previous round (``evaluate.board.circles``).
"""
from __future__ import annotations

import numpy as np

from edgetruth.render.scene import circle_conic as cc

#: fewer edge points than this on a circle: no ellipse
MIN_POINTS = 12


def fit_ellipse(x, y) -> np.ndarray | None:
    """(3, 3) the conic [[a, b/2, d/2], [b/2, c, e/2], [d/2, e/2, f]] (unit Frobenius norm, a + c > 0) of the
    direct least-squares ellipse through points (x, y) px; None with fewer than ``MIN_POINTS`` finite points or
    no ellipse."""
    x, y = np.asarray(x, np.float64).ravel(), np.asarray(y, np.float64).ravel()
    ok = np.isfinite(x) & np.isfinite(y)
    x, y = x[ok], y[ok]
    if len(x) < MIN_POINTS:
        return None
    mx, my = x.mean(), y.mean()
    s = max(float(np.sqrt(np.mean((x - mx) ** 2 + (y - my) ** 2))), 1e-12)
    u, v = (x - mx) / s, (y - my) / s
    d1 = np.column_stack([u * u, u * v, v * v])
    d2 = np.column_stack([u, v, np.ones_like(u)])
    s1, s2, s3 = d1.T @ d1, d1.T @ d2, d2.T @ d2
    try:
        t = -np.linalg.solve(s3, s2.T)
    except np.linalg.LinAlgError:
        return None
    m = s1 + s2 @ t
    m = np.array([m[2] / 2.0, -m[1], m[0] / 2.0])  # C1^-1 M, C1 the ellipse constraint 4ac - b^2 = 1
    w, vec = np.linalg.eig(m)
    vec = np.real(vec)
    cond = 4.0 * vec[0] * vec[2] - vec[1] ** 2
    pick = np.flatnonzero(cond > 0)
    if not len(pick):
        return None
    a1 = vec[:, pick[np.argmin(np.abs(np.real(w[pick])))]]
    a, b, c = a1
    d, e, f = t @ a1
    q = np.array([[a, b / 2, d / 2], [b / 2, c, e / 2], [d / 2, e / 2, f]])
    # back to pixels: u = (x - mx) / s  ->  Q_px = N^T Q N with N mapping (x, y, 1) to (u, v, 1)
    n = np.array([[1 / s, 0, -mx / s], [0, 1 / s, -my / s], [0, 0, 1]])
    q = n.T @ q @ n
    q /= np.linalg.norm(q)
    return q if q[0, 0] + q[1, 1] > 0 else -q


def ellipse_centre(x, y) -> np.ndarray:
    """(2,) the centre of ``fit_ellipse``'s ellipse; NaN when there is none."""
    q = fit_ellipse(x, y)
    return np.full(2, np.nan) if q is None else cc.conic_centre(q[None])[0]


def algebraic_residual_px(q: np.ndarray, x, y) -> np.ndarray:
    """First-order geometric distance (px) of points to the conic ``q``: (p Q p) / |grad(p Q p)|."""
    p = np.column_stack([np.ravel(x), np.ravel(y), np.ones(np.size(x))])
    val = np.einsum("ni,ij,nj->n", p, q, p)
    grad = 2.0 * (p @ q)[:, :2]
    return val / np.maximum(np.linalg.norm(grad, axis=1), 1e-300)


def corrected_centres(centres_px: np.ndarray, K, R, t, centres_board_xy: np.ndarray, radius_m: float,
                      z_m: float = 0.0) -> np.ndarray:
    """(n, 2) measured ellipse centres (undistorted px) minus the perspective bias a circle of ``radius_m`` at
    ``centres_board_xy`` (its board frame, X_cam = R X + t) has under the pinhole K: the images of the circles'
    centres, as far as pose and K are right."""
    return np.asarray(centres_px, np.float64) - cc.centre_bias_px(K, R, t, centres_board_xy, radius_m, z_m)
