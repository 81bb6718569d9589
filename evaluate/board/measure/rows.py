"""One row of the board study: a method's side lines on every photo, or a set of given corners,
then the calibration, the leave-one-image-out reprojection and the side lengths of its corners."""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from edgetruth import locate
from edgetruth.errors import InputError
from edgetruth.evaluate.board.calibrate import zhang as cb
from edgetruth.evaluate.board.detect.chessboard import junction_corners
from edgetruth.evaluate.board.model import BoardModel
from edgetruth.evaluate.board.sides.lines import SideFits, side_fits


#: The label of the reference row: the shipped set's own corners in place of a method's.
REFERENCE_ROW = "zhang_corners"
REFERENCE_LABEL = "Zhang's corners"
#: A chessboard's reference row: the cornerSubPix corners OpenCV finds the board by (``chessboard``).
OPENCV_ROW = "opencv_corners"
#: Every reference row (corners given by a set or a corner detector, in place of a method's) -> its label.
REFERENCE_ROWS = {REFERENCE_ROW: REFERENCE_LABEL, OPENCV_ROW: "OpenCV's corners (cornerSubPix)"}


@dataclass
class Row:
    """label: method label in the study's list (or a key of REFERENCE_ROWS); corners: per photo (S, 4, 2), NaN where
    missing; sides: per photo SideFits (None for given corners); converged/candidates: counts over all photos."""

    label: str
    corners: list
    sides: list | None = None
    converged: int = 0
    candidates: int = 0
    refine_s: float = 0.0
    cal: cb.Calibration | None = None
    loo: dict | None = None
    lengths: dict | None = None
    failure: str | None = None
    #: per photo, when kept (``method_row(keep_points=True)``): the refined points' x, y and side labels
    points: list | None = None

    @property
    def is_method(self) -> bool:
        return self.sides is not None


def method_row(label: str, method: str, options: dict, images, cands, quads, smaps, keep_points: bool = False,
               junctions=None) -> Row:
    """Refine each photo's candidates with ``method`` and fit the squares' sides (``quads``: per photo (S, 4, 2)
    detected corners in the model's order, NaN rows for squares not found; ``smaps``: their ``square_map``).
    ``keep_points``: keep each photo's refined points and their side labels (``Row.points``).  ``junctions`` (a
    chessboard's, ``chessboard.junctions``): the row's corners are the junctions' (``chessboard.junction_corners``)
    in place of each square's own."""
    fits, corners, conv, n, spent = [], [], 0, 0, 0.0
    kept = [] if keep_points else None
    for img, cand, q, smap in zip(images, cands, quads, smaps):
        t0 = time.perf_counter()
        pts = locate.refine(img, cand, method, **options)
        spent += time.perf_counter() - t0
        f: SideFits = side_fits(q, smap, pts.x, pts.y, pts.nx, pts.ny, pts.converged)
        fits.append(f)
        if junctions is None:
            corners.append(f.corners)
        else:
            corners.append(junction_corners(junctions, f, pts.x, pts.y, pts.nx, pts.ny, pts.converged))
        conv += int(pts.converged.sum())
        n += len(pts)
        if kept is not None:
            kept.append({"x": np.asarray(pts.x, float), "y": np.asarray(pts.y, float), "label": f.labels})
    return Row(label, corners, fits, conv, n, spent, points=kept)


def calibrate_row(row: Row, model: BoardModel, image_size: tuple[int, int]) -> Row:
    """Fill ``row.cal``, ``row.loo`` and ``row.lengths``; a row whose corners cannot calibrate gets ``failure``."""
    try:
        row.cal = cb.calibrate(model.corners, row.corners, image_size)
        row.loo = cb.leave_one_out(model.corners, row.corners, image_size)
        row.lengths = cb.side_lengths(row.cal, model.corners, row.corners)
    except InputError as exc:
        row.failure = str(exc)
    return row
