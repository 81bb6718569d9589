"""A chessboard as a board of dark squares: its model, and its squares in a photo from OpenCV's corner grid.

A chessboard's dark squares touch at their corners, so the dark-quad finder (``quads``) cannot tell
them apart.  OpenCV's ``findChessboardCorners`` finds the board's inner corners as an ordered grid
instead, and that grid numbers the squares between them.

**Model.**  A board of ``COLS x ROWS`` inner corners (OpenCV's patternSize) has inner corner
``(i, j)`` (row i, column j) at board point (j, i)·square.  The model's squares are the dark ones
*between inner corners*: square ``(r, c)`` has corners (c, r), (c + 1, r), (c + 1, r + 1),
(c, r + 1) (clockwise on screen when the board's +x is to the right and +y down, as Zhang's model),
for r < ROWS − 1 and c < COLS − 1, and it is dark where ``(r + c) % 2 == parity``.  Each of its
corners is an inner corner and each of its sides an edge against a light square.  The board's
outer ring of squares is left out: on many printed boards (OpenCV's own sample photos among them)
the ring is cut by the board's edge, so its squares' outer sides are not where a model of full
squares puts them, and no corner of the grid says where they are.

**Per photo** (``find_squares``):

1. the inner corners (``edgetruth.evaluate.calibration.detect_corners``: findChessboardCorners, then
   cornerSubPix), a grid of ROWS x COLS points in OpenCV's order;
2. which squares are dark: the mean gray at the centres of the two colour classes.  OpenCV's
   order does not know colour, so where the dark class is not the model's the grid is turned by
   180 degrees (when COLS + ROWS is odd) or mirrored (both odd).  A mirror of a planar board is
   a rotation of it in space (x -> -x, z -> -z), so the calibration is the same.  When COLS and
   ROWS are both even, no symmetry swaps the colours: the model's parity is then the photos' own
   (``settle_parity``);
3. each dark square's corners from the grid.  They are cornerSubPix corners, about 0.1 px
   accurate, a first pass for the side fits as the quad finder's vertices are.  A square with a
   corner within ``BORDER_PX`` of the image's border is left out (NaN), as the quad finder does.

The same grid gives the study's reference row, **OpenCV's corners**: every dark square's corners
at their cornerSubPix positions.

**Corners of a method** (``junction_corners``): at each inner corner, where the two grid lines
through it meet, each fitted to the method's points on both its halves; a square's own side lines
would move its corners with any difference in how large dark and light squares print or image.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from edgetruth.errors import InputError
from edgetruth.evaluate.board.detect.correspond import Correspondence, project, rotation_deg
from edgetruth.evaluate.board.detect.quads import BORDER_PX
from edgetruth.evaluate.board.model import MIN_SQUARES, BoardModel, check_model
from edgetruth.evaluate.board.sides.lines import BAND_PASS2_PX, MIN_POINTS, along_segments, intersect, tls_lines
from edgetruth.evaluate.calibration import detect_corners


@dataclass(frozen=True)
class ChessboardView:
    """One photo: ``squares`` the model's squares found (as the quad matcher gives them), ``reference`` (S, 4, 2)
    OpenCV's corners in the model's order, ``parity_seen`` the dark class in OpenCV's order before any turn,
    ``inner`` (ROWS * COLS, 2) the inner corners as OpenCV gives them (its order)."""

    squares: Correspondence
    reference: np.ndarray
    parity_seen: int
    inner: np.ndarray


def chessboard_model(pattern: tuple[int, int], square: float, units: str = "model units", parity: int = 0,
                     source: str | None = None) -> BoardModel:
    """The dark squares between the inner corners of a chessboard of ``pattern`` = (COLS, ROWS) inner corners and
    square side ``square`` (module docstring)."""
    cols, rows = (int(v) for v in pattern)
    if not (np.isfinite(square) and square > 0):
        raise InputError(f"--square {square!r}: give the side of one square, a positive number")
    corners = square_corners(np.stack(np.meshgrid(np.arange(cols), np.arange(rows)), axis=2).astype(np.float64),
                             parity) * float(square)
    if len(corners) < MIN_SQUARES:
        raise InputError(f"--pattern {cols}x{rows}: {len(corners)} dark square(s) between the inner corners; the "
                         f"board study needs {MIN_SQUARES} (at least 4x4 inner corners)")
    model = check_model(corners, source or f"chessboard {cols}x{rows} inner corners, square {square:g}")
    return BoardModel(model.corners, model.source, units, pattern=(cols, rows), parity=int(parity) % 2)


def square_corners(grid: np.ndarray, parity: int) -> np.ndarray:
    """(S, 4, 2) the dark squares' corners (model order) from a (ROWS, COLS, 2) grid of inner corners."""
    rows, cols = grid.shape[0] - 1, grid.shape[1] - 1
    r, c = np.mgrid[0:rows, 0:cols]
    dark = ((r + c) % 2 == parity % 2).ravel()
    r, c = r.ravel()[dark], c.ravel()[dark]
    return np.stack([grid[r, c], grid[r, c + 1], grid[r + 1, c + 1], grid[r + 1, c]], axis=1)


def dark_class(image: np.ndarray, grid: np.ndarray) -> int:
    """0 or 1: the colour class ((r + c) % 2 of the square (r, c) between inner corners) whose centres are darker
    on average."""
    img = np.asarray(image, np.float64)
    h, w = img.shape
    centre = 0.25 * (grid[:-1, :-1] + grid[1:, :-1] + grid[:-1, 1:] + grid[1:, 1:])
    r, c = np.mgrid[0:centre.shape[0], 0:centre.shape[1]]
    x = np.clip(np.round(centre[..., 0]), 0, w - 1).astype(int)
    y = np.clip(np.round(centre[..., 1]), 0, h - 1).astype(int)
    v = img[y, x]
    cls = (r + c) % 2
    return int(v[cls == 1].mean() < v[cls == 0].mean())


def _turned(grid: np.ndarray) -> tuple[np.ndarray, bool] | None:
    """The (ROWS, COLS, 2) grid under a symmetry of the board that swaps the colour classes of the squares between
    its corners, and whether it mirrors; None when there is none (COLS and ROWS both even)."""
    rows, cols = grid.shape[:2]
    if (rows + cols) % 2:
        return grid[::-1, ::-1], False  # 180 degrees: (r, c) -> (ROWS-2-r, COLS-2-c), r + c changes by an odd number
    if cols % 2:  # both odd
        return grid[:, ::-1], True  # c -> COLS-2-c, r + c changes by COLS - 2 - 2c, odd
    return None  # both even: r + c keeps its parity under every symmetry


def _detect(image: np.ndarray, pattern: tuple[int, int]) -> np.ndarray | None:
    return detect_corners(image, tuple(pattern))


def find_squares(image: np.ndarray, model: BoardModel) -> ChessboardView | None:
    """The model's dark squares in ``image`` (module docstring), or None when OpenCV does not find the board."""
    if model.charuco is not None:  # a ChArUco board: OpenCV's CharucoDetector gives the grid (detect.charuco)
        return model.charuco.find_squares(image, model)
    cols, rows = model.pattern
    inner = _detect(image, model.pattern)
    if inner is None:
        return None
    grid = inner.reshape(rows, cols, 2)
    seen = dark_class(image, grid)
    mirrored = False
    if seen != model.parity and (turned := _turned(grid)) is not None:
        grid, mirrored = turned
    corners = square_corners(grid, model.parity)
    h, w = np.asarray(image).shape
    inside = ((corners[..., 0] >= BORDER_PX) & (corners[..., 1] >= BORDER_PX)
              & (corners[..., 0] <= w - 1 - BORDER_PX) & (corners[..., 1] <= h - 1 - BORDER_PX))
    found = inside.all(axis=1)
    corners[~found] = np.nan
    reference = corners.copy()
    # the inner corners about one homography of the board: how far the lens bends the grid
    r, c = np.mgrid[0:rows, 0:cols]
    src = np.c_[c.ravel(), r.ravel()] * model.square  # model units
    hom, _ = cv2.findHomography(src, grid.reshape(-1, 2), 0)
    residual = float(np.sqrt(np.mean(np.sum((project(hom, src) - grid.reshape(-1, 2)) ** 2, axis=1))))
    return ChessboardView(Correspondence(corners, found, hom, residual, mirrored, rotation_deg(hom, model)),
                          reference, seen, inner)


def settle_parity(images, model: BoardModel) -> BoardModel:
    """The model with the photos' dark class when COLS and ROWS are both even (no symmetry of the board swaps its
    colours, so which class is dark is a fact of the print): the class most photos show.  Any other board's model
    is returned as it is (a ChArUco board's too: its layout fixes the parity)."""
    if model.charuco is not None:
        return model
    cols, rows = model.pattern
    if _turned(np.zeros((rows, cols, 2))) is not None:
        return model
    seen = [dark_class(img, g.reshape(rows, cols, 2)) for img in images
            if (g := _detect(img, model.pattern)) is not None]
    parity = int(np.mean(seen) > 0.5) if seen else model.parity
    if parity == model.parity:
        return model
    return chessboard_model(model.pattern, model.square, model.units, parity, model.source)


# --- corners at the junctions -----------------------------------------------------------------------
@dataclass(frozen=True)
class Junctions:
    """The inner corners two of the model's dark squares share.  ``slots`` (J, 2): the flat corner index
    ``4 * square + k`` of either square's corner there; ``lines`` (J, 2, 2): for each of the two grid lines through
    the junction, the side labels ``4 * square + side`` of its two halves, one side of either square."""

    slots: np.ndarray
    lines: np.ndarray


def junctions(model: BoardModel) -> Junctions:
    """Where the model's dark squares meet, corner to corner, and which of their sides line up there."""
    c = np.asarray(model.corners)
    key = np.round(c.reshape(-1, 2) / model.square).astype(np.int64)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    slots, lines = [], []
    for g in np.flatnonzero(counts == 2):
        a, b = np.flatnonzero(inverse == g)
        sides = []
        for slot in (a, b):  # the two sides of a square that meet at its corner k: side k - 1 (ends), side k (starts)
            s, k = divmod(int(slot), 4)
            sides.append({_axis(c[s], kk): 4 * s + kk for kk in ((k - 1) % 4, k)})
        slots.append((a, b))
        lines.append([(sides[0][ax], sides[1][ax]) for ax in ("x", "y")])
    return Junctions(np.array(slots, np.int64).reshape(-1, 2), np.array(lines, np.int64).reshape(-1, 2, 2))


def _axis(square: np.ndarray, k: int) -> str:
    """'x' for a side of the model's square along the board's x axis, 'y' along its y axis."""
    e = square[(k + 1) % 4] - square[k]
    return "x" if abs(e[0]) > abs(e[1]) else "y"


def junction_corners(j: Junctions, sides, x, y, nx, ny, converged) -> np.ndarray:
    """(S, 4, 2) a corner at every corner slot of the model, from one photo's side fits ``sides``
    (``sides.SideFits``, with its point labels) and the method's points: the intersection of the two grid lines
    through the inner corner, each the total-least-squares line of the points on both its halves.

    - At a junction two of the model's squares share (``j``), a grid line's halves are one side of either square
      (each with ``sides.MIN_POINTS`` points, or the corner is NaN); both slots get the same corner.
    - At an inner corner on the grid's border, the other dark square is in the board's outer ring, which the
      model leaves out (it may be cut by the board's edge).  There a grid line's far half is the square's side
      continued past the corner: the points within ``sides.BAND_PASS2_PX`` of the side's own line, their foot
      ``sides.CORNER_EXCLUSION_PX`` to one side length minus that past the corner, their normal within
      ``sides.MAX_NORMAL_ANGLE_DEG`` of the side's (at least ``sides.MIN_POINTS`` of them, or the corner is NaN).

    A dark square's own side lines lie off the inner corner by whatever makes dark squares print or image larger
    or smaller than light ones (ink spread, blur on a tone curve); the two halves of a grid line lie off by
    opposite amounts, so a line through both is free of it."""
    x, y, nx, ny = (np.asarray(v, float) for v in (x, y, nx, ny))
    n_sq = len(sides.n_points)
    labels = np.asarray(sides.labels, np.int64)
    covered = np.asarray(sides.n_points).ravel() >= MIN_POINTS
    # every grid line: its own half (a side label) and its far half (a side label, or -1: the side continued)
    border = np.setdiff1d(np.arange(4 * n_sq), j.slots.ravel())
    s_b, k_b = np.divmod(border, 4)
    own_b = np.stack([4 * s_b + (k_b - 1) % 4, 4 * s_b + k_b], axis=1)  # side k-1 ends at corner k, side k starts
    halves = np.concatenate([j.lines.reshape(-1, 2), np.c_[own_b.ravel(), np.full(own_b.size, -1)]])
    n_lines = len(halves)
    # (point, line) pairs from the labels: a side is a half of at most two grid lines, one at each of its ends
    member = np.full((4 * n_sq, 2), -1, np.int64)
    for li, pair in enumerate(halves):
        for lab in pair[pair >= 0]:
            member[lab, int(member[lab, 0] >= 0)] = li
    has = np.flatnonzero(labels >= 0)
    pair_pt, pair_line = [], []
    for col in (0, 1):
        m = member[labels[has], col]
        pair_pt.append(has[m >= 0])
        pair_line.append(m[m >= 0])
    # the far halves past the border corners: points along each own side's line continued past the corner
    ext = np.flatnonzero(halves[:, 1] < 0)
    lab = halves[ext, 0]
    s_e, m_e = np.divmod(lab, 4)
    start, end = sides.corners[s_e, m_e], sides.corners[s_e, (m_e + 1) % 4]
    n_e, d_e = sides.normal[s_e, m_e], sides.offset[s_e, m_e]
    length = np.linalg.norm(end - start, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        u = (end - start) / length[:, None]
    at_end = np.tile([True, False], len(border))  # side k - 1 ends at the corner, side k starts there
    pivot = np.where(at_end[:, None], end, start)
    out_dir = np.where(at_end[:, None], u, -u)
    with np.errstate(invalid="ignore"):
        dist = np.abs(n_e[:, :1] * x[None] + n_e[:, 1:] * y[None] - d_e[:, None])
        near = (dist <= BAND_PASS2_PX) & along_segments(pivot, out_dir, length, n_e, x, y, nx, ny, converged)
    li, pi = np.nonzero(near)
    far_count = np.bincount(li, minlength=len(ext))
    pair_pt.append(pi)
    pair_line.append(ext[li])
    pt, g = np.concatenate(pair_pt), np.concatenate(pair_line)
    n, d, _, _ = tls_lines(g, x[pt], y[pt], n_lines)
    good = covered[halves[:, 0]]
    good &= np.where(halves[:, 1] >= 0, covered[np.maximum(halves[:, 1], 0)], True)
    good[ext] &= far_count >= MIN_POINTS
    n[~good], d[~good] = np.nan, np.nan
    out = np.full((4 * n_sq, 2), np.nan)
    nj = len(j.slots)
    if nj:
        corner = intersect(n[0:2 * nj:2], d[0:2 * nj:2], n[1:2 * nj:2], d[1:2 * nj:2])
        out[j.slots[:, 0]] = corner
        out[j.slots[:, 1]] = corner
    if len(border):
        nb_, db_ = n[2 * nj:].reshape(-1, 2, 2), d[2 * nj:].reshape(-1, 2)
        out[border] = intersect(nb_[:, 0], db_[:, 0], nb_[:, 1], db_[:, 1])
    return out.reshape(n_sq, 4, 2)


def grid_segments(corners: np.ndarray) -> np.ndarray:
    """(M, 2, 2) every side of the found squares (S, 4, 2) continued one side length past both its corners: where a
    junction's grid lines run, the board's outer ring included, so the candidates there are refined too."""
    c = np.asarray(corners, float)
    c = c[np.all(np.isfinite(c), axis=(1, 2))]
    a, b = c, np.roll(c, -1, axis=1)
    return np.stack([2 * a - b, 2 * b - a], axis=2).reshape(-1, 2, 2)


def junction_split(j: Junctions, square_corners_px: np.ndarray) -> np.ndarray:
    """(J,) the distance (px) between the two squares' own corners at each junction (from their own side lines)."""
    c = np.asarray(square_corners_px).reshape(-1, 2)
    return np.linalg.norm(c[j.slots[:, 0]] - c[j.slots[:, 1]], axis=1)

