"""ChArUco boards in photos: OpenCV's ``CharucoDetector`` corners (the reference) and edgetruth's line corners.

A ChArUco board of ``cols`` x ``rows`` squares (``--pattern charuco:COLSxROWS:DICT``) is a chessboard whose white
squares hold ArUco markers; its (cols - 1) x (rows - 1) inner corners are numbered k = r (cols - 1) + c by
``cv2.aruco``, row-major in the board's own frame (the markers fix its orientation: no turn or mirror to settle).

- **OpenCV's corners** (``detect.charuco.charuco_corners``): ``cv2.aruco.CharucoDetector(board).detectBoard``:
  the markers found, the corners interpolated from them and refined by OpenCV's cornerSubPix.  A photo's corners
  are those it finds (a partial view counts); as ``calibrate`` lays them out, (K, 2) in id order with NaN where
  none was found.
- **edgetruth's corners** (``charuco_grid_points``): as the chessboard path does (``grid_corners``): each inner
  corner where the two grid lines through it meet, each fitted to an edge method's points on both its halves.
  OpenCV's corners are the chessboard grid the line fit starts from (``chessboard.ChessboardView``), so a
  photo takes part when OpenCV finds every corner.  The squares between the inner corners that are dark are the
  board's own (``render.scene.charuco.CharucoBoard``: OpenCV's layout); the markers' sides lie
  (square - marker) / 2 from the squares' sides (inside an 11-point edge window).

Object points: inner corner k at (c, r) * square_m (``calibration.object_points``), OpenCV's
((c + 1), (r + 1)) * square_m less one square: the same K and distortion, poses one square apart.
"""
from __future__ import annotations

import cv2
import numpy as np

from edgetruth import locate
from edgetruth.errors import InputError
from edgetruth.evaluate import method_order as mo
from edgetruth.evaluate.board.detect.charuco import (board_of, charuco_corners, charuco_view,  # noqa: F401
                                                     detector_input, parity)
from edgetruth.evaluate.board.detect.squares import board_candidates
from edgetruth.evaluate.board.measure.grid_corners import (DEFAULT_METHOD as GRID_METHOD, GridPoints, open_halves,
                                                           to_opencv_order)
from edgetruth.locate.registry import camera_free
from edgetruth.render.scene.charuco import CharucoBoard

#: The edge method of ``--corners lines`` on a ChArUco board: the chessboard path's (``grid_corners``).  The markers'
#: sides lie (square - marker) / 2 beside the squares' sides, inside its 11-point window; on renders it measured
#: closer to the truth than the 5-point windows all the same (docs/board.md, ChArUco boards).
DEFAULT_METHOD = GRID_METHOD


def charuco_grid_points(image: np.ndarray, board: CharucoBoard, method: str = DEFAULT_METHOD, detector=None,
                        **options):
    """``grid_corners.GridPoints`` of a ChArUco photo (module docstring), or None unless OpenCV finds every corner."""
    img = np.asarray(image)
    corners, _ = charuco_corners(img, board, detector)
    got = charuco_view(img, board, corners)
    if got is None:
        return None
    model, view = got
    pattern = model.pattern
    quads = np.asarray(view.squares.corners, np.float64)
    missing = np.flatnonzero(~np.all(np.isfinite(to_opencv_order(np.zeros_like(quads), view)), axis=1))
    halves = open_halves(view.inner, pattern, missing)
    cand = board_candidates(img, quads, chessboard=True, extra_segments=halves.reshape(-1, 2, 2))
    pts = locate.refine(img, cand, method, **options)
    x, y, nx, ny = (np.asarray(v, np.float64) for v in (pts.x, pts.y, pts.nx, pts.ny))
    return GridPoints(model, view, quads, missing, halves, x, y, nx, ny, np.asarray(pts.converged, bool),
                      img.shape[:2])


def corner_finder(board: CharucoBoard, corners: str, line_frame: str | None = None):
    """``calibrate --corners`` on a ChArUco board -> (corner_finder, label, undistort_lines) for
    ``calibration.calibrate_photos``: 'subpix' = OpenCV's CharucoDetector corners; 'lines[:METHOD]' = edgetruth's
    line corners (fitted in the undistorted image unless ``line_frame`` is 'photo')."""
    detector = cv2.aruco.CharucoDetector(board.cv_board())
    kind, _, spec = str(corners).partition(":")
    if kind == "subpix" and not spec:
        if line_frame is not None:
            raise InputError(f"--line-frame {line_frame}: only with --corners lines; add --corners lines or drop it")
        return (lambda photo, pattern: charuco_corners(photo, board, detector)[0],
                "OpenCV's ChArUco corners (cv2.aruco.CharucoDetector.detectBoard: markers, interpolation, "
                "cornerSubPix)", False)
    if kind != "lines":
        raise InputError(f"--corners {corners!r}: give 'subpix' or 'lines' (or lines:METHOD, e.g. lines:canny_devernay)")
    spec = spec or DEFAULT_METHOD
    method, options = mo.resolve(spec, mo.study_options())
    locate.get_method(method)
    if not camera_free([method]):
        raise InputError(f"--corners {corners!r}: {method} needs a camera model, which a calibration does not have "
                         "yet; choose another method (`edgetruth methods`)")
    undistort = line_frame != "photo"

    def finder(image, pattern):
        grid = charuco_grid_points(image, board, method, detector, **options)
        if grid is None or undistort:
            return grid
        return grid.corners()

    return finder, (f"corners where the grid lines of {spec}'s points meet, from OpenCV's ChArUco corners "
                    "(edgetruth.evaluate.board.charuco)"), undistort
