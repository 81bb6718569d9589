"""A chessboard's inner corners from an edge method: where the grid lines through each corner meet.

``line_corners(image, pattern, method)`` does for one photo what the board study does for a chessboard
(docs/board.md, Chessboards): OpenCV's grid finds the board and its dark squares (``chessboard``), the
method refines the Canny candidates near their sides and the sides continued into the outer ring,
and each inner corner is the intersection of the two grid lines through it, each fitted to the
method's points on both its halves (``chessboard.junction_corners``).  The corners come back in
OpenCV's order, so ``edgetruth calibrate --corners lines`` feeds them to the calibration in place of
cornerSubPix's.

An inner corner that touches no dark square between the inner corners (a grid corner whose one
square there is light: 2 of the 4 on a 9x6 board) has no pair of grid lines here and is NaN; so is
one whose lines have too few points.
"""
from __future__ import annotations

import numpy as np

from edgetruth.evaluate.board import chessboard as cb

#: The edge method ``line_corners`` uses unless told otherwise: on rendered boards its corners lie 0.0004 px from
#: the truth on average (tests/evaluate/board/test_chessboard.py), the best of the ERF windows on this camera.
DEFAULT_METHOD = "erf4p_fixed11"


def line_corners(image: np.ndarray, pattern: tuple[int, int], method: str = DEFAULT_METHOD,
                 **options) -> np.ndarray | None:
    """(ROWS * COLS, 2) the inner corners of the chessboard of ``pattern`` = (COLS, ROWS) inner corners in
    ``image``, in OpenCV's order, from ``method``'s grid lines (module docstring); NaN where no pair of lines is
    measured; None when OpenCV does not find the board."""
    from edgetruth import locate
    from edgetruth.evaluate.board.sides import side_fits, square_map
    from edgetruth.evaluate.board.squares import board_candidates

    img = np.asarray(image)
    model = cb.settle_parity([img], cb.chessboard_model(pattern, 1.0))
    view = cb.find_squares(img, model)
    if view is None:
        return None
    quads = view.squares.corners
    cand = board_candidates(img, quads, chessboard=True)
    pts = locate.refine(img, cand, method, **options)
    fits = side_fits(quads, square_map(quads, img.shape), pts.x, pts.y, pts.nx, pts.ny, pts.converged)
    slots = cb.junction_corners(cb.junctions(model), fits, pts.x, pts.y, pts.nx, pts.ny, pts.converged)
    return to_opencv_order(slots, view)


def to_opencv_order(slots: np.ndarray, view: cb.ChessboardView) -> np.ndarray:
    """(ROWS * COLS, 2) the corners of the model's slots (S, 4, 2) at the inner corners they sit on, in OpenCV's
    order (``view.inner``); a slot's inner corner is the one OpenCV's corner at that slot (``view.reference``)
    is, whatever turn put the grid on the model's colours.  NaN where no slot has a corner."""
    inner = np.asarray(view.inner, float)
    ref = np.asarray(view.reference, float).reshape(-1, 2)
    got = np.asarray(slots, float).reshape(-1, 2)
    ok = np.all(np.isfinite(ref), axis=1) & np.all(np.isfinite(got), axis=1)
    out = np.full_like(inner, np.nan)
    if ok.any():
        idx = np.argmin(np.linalg.norm(ref[ok][:, None] - inner[None], axis=2), axis=1)
        out[idx] = got[ok]  # a junction's two slots carry the same corner
    return out
