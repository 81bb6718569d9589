"""A ChArUco board in a photo: OpenCV's ``CharucoDetector`` corners, and the board as a chessboard grid.

A ChArUco board of ``cols`` x ``rows`` squares (``--pattern charuco:COLSxROWS:DICT``) is a chessboard whose white
squares hold ArUco markers; its (cols - 1) x (rows - 1) inner corners are numbered k = r (cols - 1) + c by
``cv2.aruco``, row-major in the board's own frame (the markers fix its orientation: no turn or mirror to settle).

- ``charuco_corners``: ``cv2.aruco.CharucoDetector(board).detectBoard`` on the photo as it is (8-bit; a 16-bit
  photo stretched to 8 bits, ``calibration.to_uint8``): the markers found, the corners interpolated from them and
  refined by OpenCV's cornerSubPix; (K, 2) in id order, NaN where none was found.
- ``charuco_view``: those corners as the chessboard grid (``chessboard.ChessboardView``) the line fits and the
  board study start from, when every corner is found; the dark squares between the inner corners are the board's
  own (``render.scene.charuco.CharucoBoard``: OpenCV's layout).
- ``charuco_model``: the board study's model of the board; ``chessboard.find_squares`` reads its grid through
  its ``charuco`` (a ``CharucoGrid``) rather than findChessboardCorners.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import cv2
import numpy as np

from edgetruth.errors import InputError
from edgetruth.evaluate.board.detect import chessboard as cb
from edgetruth.evaluate.board.detect.correspond import Correspondence, project, rotation_deg
from edgetruth.evaluate.board.detect.quads import BORDER_PX
from edgetruth.evaluate.calibration import to_uint8
from edgetruth.render.scene.charuco import CharucoBoard


def board_of(pattern, square_m: float, marker_m: float) -> CharucoBoard:
    """The ``CharucoBoard`` of a ``--pattern charuco:COLSxROWS:DICT`` (``evaluate.pattern.BoardPattern``), its square
    and marker side in metres; one ``InputError`` line when they do not make a board."""
    if not (np.isfinite(marker_m) and 0 < marker_m < square_m):
        raise InputError(f"--marker-m {marker_m:g}: the printed marker side (black border included) must be "
                         f"positive and smaller than --square-m {square_m:g}")
    if pattern.cols < 3 or pattern.rows < 3:
        raise InputError(f"--pattern {pattern.text}: a ChArUco board of at least 3x3 squares")
    return CharucoBoard(cols=pattern.cols, rows=pattern.rows, square_m=float(square_m), marker_m=float(marker_m),
                        dictionary=pattern.dictionary, margin_m=0.0)


def detector_input(image: np.ndarray) -> np.ndarray:
    """The 8-bit image OpenCV's detector reads: an 8-bit photo as it is, any other stretched to 8 bits."""
    img = np.asarray(image)
    return img if img.dtype == np.uint8 else to_uint8(img)


def charuco_corners(image: np.ndarray, board: CharucoBoard, detector=None) -> tuple[np.ndarray, int]:
    """OpenCV's ChArUco corners in ``image``: ((K, 2) in id order, NaN where not found; markers found)."""
    det = detector or cv2.aruco.CharucoDetector(board.cv_board())
    cc, ids, _, mids = det.detectBoard(detector_input(image))
    out = np.full(((board.cols - 1) * (board.rows - 1), 2), np.nan)
    if ids is not None and len(ids):
        out[np.ravel(ids)] = np.asarray(cc, np.float64).reshape(-1, 2)
    return out, 0 if mids is None else len(mids)


def parity(board: CharucoBoard) -> int:
    """The chessboard model's parity (``chessboard.chessboard_model``): square (r, c) between the inner corners is
    the board's square (r + 1, c + 1), dark where (r + c) % 2 == parity."""
    dark = {tuple(rc) for rc in board._layout["dark_squares"].tolist()}
    return 0 if (1, 1) in dark else 1


@dataclass(frozen=True)
class CharucoGrid:
    """A ``BoardModel``'s ``charuco``: the board, and how ``chessboard.find_squares`` finds its grid (no import of
    this module there: the board study's modules import one way)."""
    board: CharucoBoard

    def find_squares(self, image: np.ndarray, model) -> cb.ChessboardView | None:
        """The view of OpenCV's corners (``charuco_view``), None unless it finds every one."""
        got = charuco_view(image, self.board, charuco_corners(image, self.board)[0], model)
        return None if got is None else got[1]


def charuco_model(board: CharucoBoard, square: float = 1.0, units: str = "squares"):
    """The board study's model of a ChArUco board (``chessboard.chessboard_model`` of its inner corners, the board's
    parity, ``charuco`` its ``CharucoGrid``)."""
    source = (f"ChArUco {board.cols}x{board.rows} squares, markers {board.marker_m / board.square_m:.4g} of a square, "
              f"{board.dictionary}")
    model = cb.chessboard_model((board.cols - 1, board.rows - 1), square, units, parity=parity(board), source=source)
    return replace(model, charuco=CharucoGrid(board))


def charuco_view(image: np.ndarray, board: CharucoBoard, corners: np.ndarray,
                 model=None) -> tuple[object, cb.ChessboardView] | None:
    """(model, view): OpenCV's corners of every inner corner as the chessboard grid ``grid_corners`` fits on;
    None unless every corner was found.  ``model``: the chessboard model (default ``charuco_model``, squares)."""
    if not np.all(np.isfinite(corners)):
        return None
    pattern = (board.cols - 1, board.rows - 1)
    model = charuco_model(board) if model is None else model
    grid = np.asarray(corners, np.float64).reshape(pattern[1], pattern[0], 2)
    quads = cb.square_corners(grid, model.parity)
    h, w = np.asarray(image).shape[:2]
    found = np.all((quads[..., 0] >= BORDER_PX) & (quads[..., 1] >= BORDER_PX) & (quads[..., 0] <= w - 1 - BORDER_PX)
                   & (quads[..., 1] <= h - 1 - BORDER_PX), axis=1)
    quads[~found] = np.nan
    r, c = np.mgrid[0:pattern[1], 0:pattern[0]]
    src = np.c_[c.ravel(), r.ravel()] * model.square  # model units
    hom, _ = cv2.findHomography(src, grid.reshape(-1, 2), 0)
    residual = float(np.sqrt(np.mean(np.sum((project(hom, src) - grid.reshape(-1, 2)) ** 2, axis=1))))
    view = cb.ChessboardView(Correspondence(quads, found, hom, residual, False, rotation_deg(hom, model)),
                             quads.copy(), model.parity, grid.reshape(-1, 2))
    return model, view


#: a photo takes part in plain OpenCV's calibration with at least this many corners (calibrateCamera's DLT start)
PLAIN_MIN_CORNERS = 6


def plain_opencv_calibration(photos: list, board: CharucoBoard) -> dict | None:
    """Plain OpenCV's calibration of a ChArUco photo set, as its tutorial does it: each photo file read by
    ``cv2.imread(..., IMREAD_GRAYSCALE)``, ``CharucoDetector.detectBoard`` on it, ``board.matchImagePoints`` on the corners found (each inner corner once; a partial view counts, with
    ``PLAIN_MIN_CORNERS`` or more), ``cv2.calibrateCamera`` with flags 0 (k1, k2, p1, p2, k3).  {fx, fy, cx, cy, k1,
    k2, p1, p2, k3, rms_px, photos, corners, source}, or None with fewer than 3 photos."""
    cvb = board.cv_board()
    det = cv2.aruco.CharucoDetector(cvb)
    obj, img, used, size = [], [], [], None
    for path in photos:
        g8 = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        if g8 is None:
            continue
        size = g8.shape[::-1]
        cc, ids, _, _ = det.detectBoard(g8)
        if ids is None or len(ids) < PLAIN_MIN_CORNERS:
            continue
        o, i = cvb.matchImagePoints(cc, ids)
        obj.append(o.astype(np.float32))
        img.append(i.astype(np.float32))
        used.append(Path(path).name)
    if len(used) < 3:
        return None
    rms, K, dist, _, _ = cv2.calibrateCamera(obj, img, size, None, None, flags=0)
    d = np.ravel(dist)
    n = int(sum(len(o) for o in obj))
    return {"fx": float(K[0, 0]), "fy": float(K[1, 1]), "cx": float(K[0, 2]), "cy": float(K[1, 2]),
            **{k: float(v) for k, v in zip(("k1", "k2", "p1", "p2", "k3"), d[:5])}, "rms_px": float(rms),
            "photos": used, "corners": n,
            "source": f"plain OpenCV (CharucoDetector, matchImagePoints, calibrateCamera flags 0; {len(used)} photos, "
                      f"{n} corners): RMS {rms:.4f} px"}
