"""A chessboard's inner corners from an edge method: where the grid lines through each corner meet.

``line_corners(image, pattern, method)`` does for one photo what the board study does for a chessboard
(docs/board.md, Chessboards): OpenCV's grid finds the board and its dark squares (``chessboard``), the
method refines the Canny candidates near their sides and the sides continued into the outer ring,
and each inner corner is the intersection of the two grid lines through it, each fitted to the
method's points on both its halves (``chessboard.junction_corners``).  The corners come back in
OpenCV's order, so ``edgetruth calibrate --corners lines`` feeds them to the calibration in place of
cornerSubPix's.

An inner corner that touches no dark square between the inner corners (a grid corner whose one
square there is light: 2 of the 4 on a 9x6 board) is an *open corner*: its two dark squares lie in
the outer ring.  Its grid lines are fitted to the points on the two grid segments either side of it
along each line (``open_corners``), the outer one running into the ring.  A corner whose lines have
too few points is NaN.
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
    # the inner corners no modelled square's slot reaches: the open corners (and any whose square was left out)
    missing = np.flatnonzero(~np.all(np.isfinite(to_opencv_order(np.zeros_like(quads), view)), axis=1))
    halves = open_halves(view.inner, pattern, missing)
    cand = board_candidates(img, quads, chessboard=True, extra_segments=halves.reshape(-1, 2, 2))
    pts = locate.refine(img, cand, method, **options)
    fits = side_fits(quads, square_map(quads, img.shape), pts.x, pts.y, pts.nx, pts.ny, pts.converged)
    slots = cb.junction_corners(cb.junctions(model), fits, pts.x, pts.y, pts.nx, pts.ny, pts.converged)
    out = to_opencv_order(slots, view)
    if len(missing):
        out[missing] = open_corners(halves, pts.x, pts.y, pts.nx, pts.ny, pts.converged)
    return out


def open_halves(inner: np.ndarray, pattern: tuple[int, int], which: np.ndarray) -> np.ndarray:
    """(M, 2, 2, 2) for each inner corner ``which`` (OpenCV's order), its two grid lines (along the grid's rows,
    then its columns), each as its two halves (start at the corner, end at the next inner corner; past the grid's
    edge, the mirror of the corner on the other side), from OpenCV's corners ``inner``."""
    cols, rows = pattern
    grid = np.asarray(inner, float).reshape(rows, cols, 2)
    out = np.empty((len(which), 2, 2, 2, 2))
    for m, idx in enumerate(np.asarray(which, int)):
        i, j = divmod(int(idx), cols)
        p = grid[i, j]
        for a, (di, dj) in enumerate(((0, 1), (1, 0))):
            for b, sign in enumerate((-1, 1)):
                ii, jj = i + sign * di, j + sign * dj
                q = grid[ii, jj] if 0 <= ii < rows and 0 <= jj < cols else 2 * p - grid[i - sign * di, j - sign * dj]
                out[m, a, b] = (p, q)
    return out


def open_corners(halves: np.ndarray, x, y, nx, ny, converged) -> np.ndarray:
    """(M, 2) the corner where each open corner's two grid lines meet (``open_halves``), each line the
    total-least-squares line of the method's points on both its halves: the points within ``BAND_PASS1_PX`` of the
    chord, then within ``BAND_PASS2_PX`` of the line that gives, their foot ``CORNER_EXCLUSION_PX`` from either
    end of the half, their normal within ``MAX_NORMAL_ANGLE_DEG`` of the chord's.  NaN where a half has fewer than
    ``MIN_POINTS`` points.  The two halves of a line have the dark square on opposite sides, so whatever makes dark
    squares image larger or smaller moves them by opposite amounts, and the line is free of it."""
    from edgetruth.evaluate.board.sides import (BAND_PASS1_PX, BAND_PASS2_PX, MIN_POINTS, along_segments, intersect,
                                                tls_lines)

    h = np.asarray(halves, float).reshape(-1, 2, 2)  # (4M, 2, 2): every half, two per line, two lines per corner
    x, y, nx, ny = (np.asarray(v, float) for v in (x, y, nx, ny))
    p, q = h[:, 0], h[:, 1]
    length = np.linalg.norm(q - p, axis=1)
    u = (q - p) / length[:, None]
    chord_n = np.stack([-u[:, 1], u[:, 0]], axis=1)
    along = along_segments(p, u, length, chord_n, x, y, nx, ny, converged)
    n_lines = len(h) // 2
    line_n = np.repeat(chord_n[0::2], 2, axis=0)  # pass 1: the chord through the corner
    line_d = (line_n * p).sum(axis=1)
    for band in (BAND_PASS1_PX, BAND_PASS2_PX):
        dist = np.abs(line_n[:, :1] * x[None] + line_n[:, 1:] * y[None] - line_d[:, None])
        hi, pi = np.nonzero(along & (dist <= band))
        n, d, _, _ = tls_lines(hi // 2, x[pi], y[pi], n_lines)
        line_n, line_d = np.repeat(n, 2, axis=0), np.repeat(d, 2)
    count = np.bincount(hi, minlength=len(h)).reshape(n_lines, 2)
    bad = (count < MIN_POINTS).any(axis=1)
    n[bad], d[bad] = np.nan, np.nan
    return intersect(n[0::2], d[0::2], n[1::2], d[1::2])


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
