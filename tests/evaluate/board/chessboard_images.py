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


#: A strongly barrel-distorting lens for ``render_distorted`` (OpenCV's k1, k2, p1, p2, k3): the image corner is
#: pulled 11 % towards the centre, as OpenCV's left01-14 lens (k1 = -0.28) does.
BARREL = np.array([-0.3, 0.1, 0.0, 0.0, 0.0])


def render_distorted(pattern, rvec, dist=BARREL, sigma_px=0.7):
    """A view of ``render``'s board through the lens ``dist`` (K as ``render``): every pixel centre is undistorted
    (cv2.undistortPoints, converged) and the dark squares' coverage evaluated there as the product of a Gaussian
    edge profile (``sigma_px``) across each side, so the image is 50 % dark exactly on the distorted sides.
    -> (image 0-255 float, the true inner corners (ROWS * COLS, 2) in the image, row-major)."""
    from scipy.special import ndtr

    cols, rows = pattern
    h = board_homography(rvec, ((cols - 1) / 2, (rows - 1) / 2))
    quads = apply_h(h, all_dark_squares(pattern))
    yy, xx = np.mgrid[0:SHAPE[0], 0:SHAPE[1]].astype(float)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
    u = cv2.undistortPoints(np.stack([xx, yy], axis=2).reshape(-1, 1, 2), K, dist, P=K, criteria=crit)
    ux, uy = u[:, 0, 0].reshape(SHAPE), u[:, 0, 1].reshape(SHAPE)
    cover = np.zeros(SHAPE)
    for q in quads:
        c = q.mean(axis=0)
        m = np.ones(SHAPE)
        for k in range(4):
            a, b = q[k], q[(k + 1) % 4]
            e = (b - a) / np.linalg.norm(b - a)
            n = np.array([-e[1], e[0]]) * (1 if np.array([-e[1], e[0]]) @ (c - a) > 0 else -1)
            m *= ndtr(((ux - a[0]) * n[0] + (uy - a[1]) * n[1]) / sigma_px)
        cover += m
    g = np.stack(np.meshgrid(np.arange(cols), np.arange(rows)), axis=2).reshape(-1, 2).astype(float)
    obj = np.c_[apply_h(np.linalg.inv(K) @ h, g), np.ones(len(g))].reshape(-1, 1, 3)
    truth = cv2.projectPoints(obj, np.zeros(3), np.zeros(3), K, dist)[0].reshape(-1, 2)
    return 210.0 - 170.0 * np.clip(cover, 0, 1), truth


def write_views(folder, suffix: str, noise_dn: float = 2.0):
    """The 4 ``ROTATIONS`` views of a 9x6 board (fx 600, σ 0.8 px, dark 40, white 210, Gaussian noise of
    ``noise_dn``) as 8-bit files in ``folder`` (``suffix`` '.png', or '.jpg' at quality 75) -> (paths, each view's
    true inner corners, (54, 2) row-major)."""
    rng = np.random.default_rng(1)
    paths, corners = [], []
    r, c = np.mgrid[0:6, 0:9]
    grid = np.c_[c.ravel(), r.ravel()].astype(float)
    for i, rot in enumerate(ROTATIONS):
        img, h = render((9, 6), rot, sigma_px=0.8)
        img = np.clip(np.round(img + rng.normal(0, noise_dn, img.shape)), 0, 255).astype(np.uint8)
        p = folder / f"v{i}{suffix}"
        cv2.imwrite(str(p), img, [cv2.IMWRITE_JPEG_QUALITY, 75] if suffix == ".jpg" else [])
        paths.append(p)
        corners.append(apply_h(h, grid))
    return paths, corners
