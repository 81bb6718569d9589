"""The model's squares in a photo, whatever the board: separate squares by their dark quads and a homography
(``quads``, ``correspond``), a chessboard by OpenCV's grid of its inner corners (``chessboard``); and, for a set of
photos, the squares and the Canny candidates beside their sides that every method of the study refines
(``locate_squares``)."""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from edgetruth import console, locate
from edgetruth.evaluate.board.detect import chessboard as cb
from edgetruth.evaluate.board.detect.correspond import Correspondence, match_squares
from edgetruth.evaluate.board.detect.levels import SquareLevels, saturated, square_levels
from edgetruth.evaluate.board.detect.quads import find_quads
from edgetruth.evaluate.board.model import BoardModel
from edgetruth.evaluate.board.sides.lines import CANDIDATE_MARGIN_PX, near_segments, near_sides, square_map


if TYPE_CHECKING:
    from edgetruth.evaluate.board.inputs import BoardInputs

#: A photo on which fewer than this share of the model's squares are found is left out (with a warning).
MIN_FOUND_SHARE = 0.5


def board_squares(image: np.ndarray, model: BoardModel) -> tuple[Correspondence | None, np.ndarray | None]:
    """The model's squares found in ``image`` (None when the board is not found) and, for a chessboard, OpenCV's
    corners in the model's order (S, 4, 2) (else None).  A chessboard's model should have its parity settled on
    the photos first (``chessboard.settle_parity``)."""
    if model.pattern is None:
        return match_squares(model, find_quads(image)), None
    view = cb.find_squares(image, model)
    return (None, None) if view is None else (view.squares, view.reference)


def board_candidates(image: np.ndarray, corners: np.ndarray, chessboard: bool, extra_segments=None):
    """The Canny candidates worth refining (``locate.candidates``): those within ``sides.CANDIDATE_MARGIN_PX`` of a
    found square's side (``corners`` (S, 4, 2), NaN rows for squares not found) and, on a chessboard, of those
    sides continued past their corners (``chessboard.grid_segments``: its grid lines run on into the outer ring),
    and of ``extra_segments`` (M, 2, 2) when given."""
    cand = locate.candidates(image)
    near = near_sides(corners, cand.x, cand.y, CANDIDATE_MARGIN_PX)
    if chessboard:
        near |= near_segments(cb.grid_segments(corners), cand.x, cand.y, CANDIDATE_MARGIN_PX)
    if extra_segments is not None and len(extra_segments):
        near |= near_segments(extra_segments, cand.x, cand.y, CANDIDATE_MARGIN_PX)
    return cand.subset(near)


def find_board(inp: BoardInputs, images, progress: bool):
    """Per photo, the model's squares (``squares.board_squares``) and, for a chessboard, OpenCV's corners in the
    model's order (else None); and the model, whose chessboard parity the photos may settle."""
    model = inp.model if inp.model.pattern is None else cb.settle_parity(images, inp.model)
    photos = console.track(images, desc="squares", unit="photo", enabled=progress)
    found, refs = zip(*(board_squares(img, model) for img in photos))
    return list(found), (list(refs) if model.pattern is not None else None), model


def locate_squares(inp: BoardInputs, images, progress: bool):
    """Per photo: the Canny candidates near the detected squares' sides, the detected quads in the model's order,
    their square map, and a line for the report; photos with too few squares are left out.  Also, per photo, the
    reference corners OpenCV found a chessboard by (None for other boards), and the model (``find_board``)."""
    cands, quads, smaps, table, keep = [], [], [], [], []
    found_all, refs, model = find_board(inp, images, progress)
    n_sq = len(model)
    for i, (name, img, c) in enumerate(zip(inp.names, images, found_all)):
        found = 0 if c is None else int(c.found.sum())
        line = {"photo": name, "squares_found": found, "squares_total": n_sq,
                "missing": "all" if c is None else " ".join(map(str, c.missing)),
                "quad_residual_px": c.residual_px if c is not None else float("nan"),
                "candidates_near_sides": "", "used": "no"}
        if model.pattern is not None:  # a chessboard: its flat levels, and whether its white is saturated
            lv = square_levels(img, c.corners) if c is not None else SquareLevels(*(float("nan"),) * 4)
            line.update({"dark_level": lv.dark, "white_level": lv.white, "dark_sd": lv.dark_sd,
                         "white_sd": lv.white_sd, "white_saturated": "yes" if saturated(lv) else "no"})
        table.append(line)
        if found < MIN_FOUND_SHARE * n_sq:
            console.warn(f"{name}: found {found} of the model's {n_sq} squares; photo left out")
            continue
        cand = board_candidates(img, c.corners, model.pattern is not None)
        line.update({"candidates_near_sides": len(cand), "used": "yes"})
        cands.append(cand)
        quads.append(c.corners)
        smaps.append(square_map(c.corners, img.shape))
        keep.append(i)
    return cands, quads, smaps, table, keep, refs, model
