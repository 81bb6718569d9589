"""The model's squares in a photo, whatever the board: separate squares by their dark quads and a homography
(``quads``, ``correspond``), a chessboard by OpenCV's grid of its inner corners (``chessboard``)."""
from __future__ import annotations

import numpy as np

from edgetruth.evaluate.board import chessboard as cb
from edgetruth.evaluate.board.correspond import Correspondence, match_squares
from edgetruth.evaluate.board.model import BoardModel
from edgetruth.evaluate.board.quads import find_quads


def board_squares(image: np.ndarray, model: BoardModel) -> tuple[Correspondence | None, np.ndarray | None]:
    """The model's squares found in ``image`` (None when the board is not found) and, for a chessboard, OpenCV's
    corners in the model's order (S, 4, 2) (else None).  A chessboard's model should have its parity settled on
    the photos first (``chessboard.settle_parity``)."""
    if model.pattern is None:
        return match_squares(model, find_quads(image)), None
    view = cb.find_squares(image, model)
    return (None, None) if view is None else (view.squares, view.reference)


def board_candidates(image: np.ndarray, corners: np.ndarray, chessboard: bool):
    """The Canny candidates worth refining (``locate.candidates``): those within ``sides.CANDIDATE_MARGIN_PX`` of a
    found square's side (``corners`` (S, 4, 2), NaN rows for squares not found) and, on a chessboard, of those
    sides continued past their corners (``chessboard.grid_segments``: its grid lines run on into the outer ring)."""
    from edgetruth import locate
    from edgetruth.evaluate.board.sides import CANDIDATE_MARGIN_PX, near_segments, near_sides

    cand = locate.candidates(image)
    near = near_sides(corners, cand.x, cand.y, CANDIDATE_MARGIN_PX)
    if chessboard:
        near |= near_segments(cb.grid_segments(corners), cand.x, cand.y, CANDIDATE_MARGIN_PX)
    return cand.subset(near)
