"""Measure, on OpenCV's left01-14 photos, what a digital twin of them needs (not packaged; prints JSON).

Run from the checkout: ``python tools/twins/opencv_left_measure.py > /tmp/opencv_left_twin.json``;
``tools/twins/opencv_left_scene.py`` turns the JSON into ``scenes/opencv_left_twin.toml``.

- **Camera.**  Zhang's calibration (``calibrate_photos``, 5-term Brown-Conrady) on the 54 line corners of
  every photo, their grid lines fitted in the undistorted image (``grid_corners.grid_points``, ERF4P-fixed11:
  what ``edgetruth calibrate opencv_left --corners lines`` gives, RMS 0.155 px; fitted straight in the photo
  the lines make fx 0.17 % long, docs/formats.md).
- **Poses.**  ``cv2.solvePnP`` (iterative, with that K and distortion) on the same corners (each photo's grid
  refitted with the final lens), in the order of the board study's chessboard model (its 20 dark squares,
  unit = one square), so the twin's chessboard (``[spec.squares] chessboard``, parity 0) puts its dark squares
  where the photo's are.
- **Outer ring.**  How far the cut outer ring reaches beyond the outermost inner corners: along the middle
  of each ring square, the point where the stored value crosses halfway from dark to white, in squares.
- **Levels.**  ``levels.square_levels`` at the squares' centres (median, noise SD, saturated flag).
- **Blur.**  ``photo_model.measure_photo``: the ERF σ (px) per orientation on the stored values.
- **JPEG.**  Every photo's luminance quantisation table is the IJG (Annex K) table at quality 50 exactly.
"""
from __future__ import annotations

import json

import cv2
import numpy as np

from edgetruth.evaluate.board import chessboard as cb
from edgetruth.evaluate.board.grid_corners import grid_points
from edgetruth.evaluate.board.inputs import resolve_inputs
from edgetruth.evaluate.board.levels import saturated, square_levels
from edgetruth.evaluate.board.photo_model import measure_photo
from edgetruth.evaluate.calibration import calibrate_photos
from edgetruth.image_io import read_gray

PATTERN = (9, 6)


def model_order(view, lc: np.ndarray) -> np.ndarray:
    """The model's (S, 4, 2) square corners at the line corners (``lc``, OpenCV order)."""
    q = view.squares.corners.reshape(-1, 2)
    d = np.linalg.norm(q[:, None, :] - view.inner[None, :, :], axis=2)
    k = np.argmin(d, axis=1)
    assert np.all(d[np.arange(len(q)), k] < 1e-6), "a model corner is not one of OpenCV's inner corners"
    return lc[k].reshape(view.squares.corners.shape)


def ring_reach(img, K, dist, rvec, tvec, cols: int, rows: int) -> dict:
    """Median reach (in squares) of the dark ring squares beyond the outermost inner corners, along x and y."""
    reach = {"x": [], "y": []}
    s = np.linspace(0.0, 1.2, 241)
    for r in range(-1, rows):
        for c in range(-1, cols):
            if (r + c) % 2 or not (r in (-1, rows - 1) or c in (-1, cols - 1)):
                continue
            for axis, edge in (("x", c == -1), ("x", c == cols - 1), ("y", r == -1), ("y", r == rows - 1)):
                if not edge or (axis == "x" and r in (-1, rows - 1)) or (axis == "y" and c in (-1, cols - 1)):
                    continue  # corners of the ring: skip (both cuts meet there)
                if axis == "x":
                    x = -s if c == -1 else (cols - 1) + s
                    y = np.full_like(s, r + 0.5)
                else:
                    y = -s if r == -1 else (rows - 1) + s
                    x = np.full_like(s, c + 0.5)
                p, _ = cv2.projectPoints(np.stack([x, y, 0 * x], 1), rvec, tvec, K, dist)
                p = p.reshape(-1, 2)
                ok = (p[:, 0] >= 0) & (p[:, 0] <= img.shape[1] - 1) & (p[:, 1] >= 0) & (p[:, 1] <= img.shape[0] - 1)
                if not ok.all():
                    continue
                v = cv2.remap(img.astype(np.float32), p[:, 0:1].astype(np.float32), p[:, 1:2].astype(np.float32),
                              cv2.INTER_LINEAR).ravel()
                dark, white = np.median(v[20:60]), np.max(v)
                half = 0.5 * (dark + white)
                above = np.flatnonzero(v[20:] > half)
                if above.size:
                    reach[axis].append(float(s[20 + above[0]]))
    return {k: float(np.median(v)) if v else float("nan") for k, v in reach.items()}


def main() -> None:
    inp = resolve_inputs(["opencv_left"])
    model = cb.chessboard_model(PATTERN, 1.0)
    rows = []
    cal, _ = calibrate_photos([(p.name, p) for p in inp.photos], PATTERN, 1.0, corner_finder=grid_points,
                              undistort_lines=True)
    rms, K, dist = cal.rms_px, cal.K, cal.dist
    for p in inp.photos:
        img = read_gray(p)
        view = cb.find_squares(img, model)
        lc = grid_points(img, PATTERN).corners((K, dist))
        mc = model_order(view, lc)
        board = np.c_[model.corners.reshape(-1, 2), np.zeros(mc.size // 2)]
        ok, rvec, tvec = cv2.solvePnP(board, mc.reshape(-1, 2), K, dist, flags=cv2.SOLVEPNP_ITERATIVE)
        proj, _ = cv2.projectPoints(board, rvec, tvec, K, dist)
        res = np.linalg.norm(proj.reshape(-1, 2) - mc.reshape(-1, 2), axis=1)
        lev = square_levels(img, view.squares.corners)
        pm = measure_photo(img, model, p.name, p)
        rows.append({
            "photo": p.name, "R": cv2.Rodrigues(rvec)[0].tolist(), "t_squares": tvec.ravel().tolist(),
            "pose_rms_px": float(np.sqrt(np.mean(res ** 2))),
            "ring": ring_reach(img, K, dist, rvec, tvec, *PATTERN),
            "dark": lev.dark, "white": lev.white, "dark_sd": lev.dark_sd, "white_sd": lev.white_sd,
            "white_saturated": bool(saturated(lev)),
            "sigma_x_px": pm["blur"]["vertical"]["sigma_px"], "sigma_y_px": pm["blur"]["horizontal"]["sigma_px"],
        })
    print(json.dumps({"rms_px": rms, "K": K.tolist(), "dist": dist.ravel().tolist(), "photos": rows}, indent=1))


if __name__ == "__main__":
    main()
