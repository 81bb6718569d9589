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

A distorting lens bends the grid lines in the photo.  ``GridPoints.corners(lens)`` fits them in the undistorted
image instead, where they are straight, and distorts the corners back (``edgetruth calibrate --corners lines``
iterates it with the calibration's own lens, unless ``--line-frame photo``): ``grid_points`` measures a photo's
points once for every refit.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from edgetruth import locate
from edgetruth.evaluate.board.detect import chessboard as cb
from edgetruth.evaluate.board.detect.squares import board_candidates
from edgetruth.evaluate.board.sides.lines import (BAND_PASS1_PX, BAND_PASS2_PX, MIN_POINTS, along_segments, intersect,
                                                  side_fits, square_map, tls_lines)
from edgetruth.evaluate.calibration import distort_px, undistort_px


#: The edge method ``line_corners`` uses unless told otherwise: on rendered boards its corners lie 0.0004 px from
#: the truth on average (tests/evaluate/board/detect/test_chessboard.py), the best of the ERF windows on this camera.
DEFAULT_METHOD = "erf4p_fixed11"


def line_corners(image: np.ndarray, pattern: tuple[int, int], method: str = DEFAULT_METHOD, lens=None,
                 **options) -> np.ndarray | None:
    """(ROWS * COLS, 2) the inner corners of the chessboard of ``pattern`` = (COLS, ROWS) inner corners in
    ``image``, in OpenCV's order, from ``method``'s grid lines (module docstring); NaN where no pair of lines is
    measured; None when OpenCV does not find the board.  ``lens`` = (K, dist): fit the lines where they are
    straight, in the undistorted image (``GridPoints.corners``)."""
    grid = grid_points(image, pattern, method, **options)
    return None if grid is None else grid.corners(lens)


@dataclass
class GridPoints:
    """One photo's board (OpenCV's grid ``view``, its dark squares ``quads`` (S, 4, 2), the ``missing`` inner
    corners no square reaches and their grid-line ``halves``) and one method's refined points on it: what the
    grid lines are fitted to, measured once and refitted for every lens model."""

    model: object
    view: cb.ChessboardView
    quads: np.ndarray
    missing: np.ndarray
    halves: np.ndarray
    x: np.ndarray
    y: np.ndarray
    nx: np.ndarray
    ny: np.ndarray
    converged: np.ndarray
    shape: tuple[int, int]

    def corners(self, lens=None) -> np.ndarray:
        """(ROWS * COLS, 2) the inner corners in OpenCV's order (``line_corners``).

        Without ``lens`` the grid lines are fitted in the photo, where a distorting lens bends them: a line
        fitted through a bent grid line passes on its concave side, so the corners move towards the image
        centre, more the further out (on OpenCV's left01-14 twin, k1 = -0.28: 0.06 px on average, 0.11 px at
        200-300 px from the centre; fx +0.17 %).  With ``lens`` = (K, dist) (OpenCV's model) the points, their
        normals, the squares and the halves are undistorted first, the lines fitted there, where the model
        says they are straight, and the corners distorted back."""
        quads, halves, x, y, nx, ny, shape = self.quads, self.halves, self.x, self.y, self.nx, self.ny, self.shape
        shift = np.zeros(2)
        if lens is not None:
            K, dist = (np.asarray(a, np.float64) for a in lens)
            quads, halves = (undistort_px(a, K, dist) for a in (quads, halves))
            x, y, nx, ny = undistort_points(x, y, nx, ny, K, dist)
            # a canvas for the square map around the undistorted squares (points beyond it clip to its border)
            ok = np.all(np.isfinite(quads), axis=2)
            lo = np.floor(quads[ok].min(axis=0)) - CANVAS_MARGIN_PX if ok.any() else np.zeros(2)
            hi = np.ceil(quads[ok].max(axis=0)) + CANVAS_MARGIN_PX if ok.any() else np.ones(2)
            shift = -lo
            quads, halves = quads + shift, halves + shift
            x, y = x + shift[0], y + shift[1]
            shape = (int(hi[1] - lo[1]) + 1, int(hi[0] - lo[0]) + 1)
        fits = side_fits(quads, square_map(quads, shape), x, y, nx, ny, self.converged)
        slots = cb.junction_corners(cb.junctions(self.model), fits, x, y, nx, ny, self.converged)
        out = to_opencv_order(slots, self.view)
        if len(self.missing):
            out[self.missing] = open_corners(halves, x, y, nx, ny, self.converged)
        if lens is None:
            return out
        return distort_px(out - shift, K, dist)


#: Margin (px) of the undistorted squares' canvas (``GridPoints.corners``): wider than any assignment band.
CANVAS_MARGIN_PX = 16.0


def grid_points(image: np.ndarray, pattern: tuple[int, int], method: str = DEFAULT_METHOD,
                **options) -> GridPoints | None:
    """The board of ``pattern`` in ``image`` and ``method``'s refined points near its squares' sides and the
    sides continued into the outer ring (``GridPoints``); None when OpenCV does not find the board."""
    img = np.asarray(image)
    model = cb.settle_parity([img], cb.chessboard_model(pattern, 1.0))
    view = cb.find_squares(img, model)
    if view is None:
        return None
    quads = np.asarray(view.squares.corners, np.float64)
    # the inner corners no modelled square's slot reaches: the open corners (and any whose square was left out)
    missing = np.flatnonzero(~np.all(np.isfinite(to_opencv_order(np.zeros_like(quads), view)), axis=1))
    halves = open_halves(view.inner, pattern, missing)
    cand = board_candidates(img, quads, chessboard=True, extra_segments=halves.reshape(-1, 2, 2))
    pts = locate.refine(img, cand, method, **options)
    x, y, nx, ny = (np.asarray(v, np.float64) for v in (pts.x, pts.y, pts.nx, pts.ny))
    return GridPoints(model, view, quads, missing, halves, x, y, nx, ny, np.asarray(pts.converged, bool),
                      img.shape[:2])


def undistort_points(x, y, nx, ny, K: np.ndarray, dist: np.ndarray, step_px: float = 0.5):
    """Refined points (x, y) and their unit normals (nx, ny) in the photo -> in the undistorted image: each
    normal turned with the local map (the tangent ``step_px`` along the edge, mapped, turned back a right
    angle)."""
    p = np.stack([x, y], axis=1)
    t = np.stack([-np.asarray(ny), np.asarray(nx)], axis=1)
    q, q2 = undistort_px(p, K, dist), undistort_px(p + step_px * t, K, dist)
    tu = q2 - q
    with np.errstate(invalid="ignore", divide="ignore"):
        tu /= np.linalg.norm(tu, axis=1, keepdims=True)
    return q[:, 0], q[:, 1], tu[:, 1], -tu[:, 0]


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
