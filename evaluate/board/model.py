"""The board model: the squares of a planar target, four corners each, in board units.

File layout (Zhang's ``Model.txt``): one square per line, eight numbers
``x0 y0 x1 y1 x2 y2 x3 y3`` -- its four corners in board units (Zhang's are inches), in
the same cyclic order for every square.  Side ``k`` of a square runs from corner ``k`` to
corner ``k + 1`` (mod 4); corner ``k`` is where sides ``k - 1`` and ``k`` meet.  The board
is the plane Z = 0 of its own frame.
"""
from __future__ import annotations

from dataclasses import dataclass
import numpy as np

from edgetruth.errors import InputError
from edgetruth.fileio import check_input_file

#: Fewest squares a model may have (a homography needs 4 points; the study wants many more).
MIN_SQUARES = 4
#: Largest model file read (bytes): a board of ~10^5 squares; anything larger is not a model.
MAX_MODEL_BYTES = 8 << 20


@dataclass(frozen=True)
class BoardModel:
    """corners: (S, 4, 2) float64, board units; ``source``: where it came from (for reports)."""

    corners: np.ndarray
    source: str
    units: str = "model units"
    #: a chessboard's (COLS, ROWS) inner corners (``chessboard.chessboard_model``), None for a board of separate squares
    pattern: tuple[int, int] | None = None
    #: a chessboard's dark colour class: square (r, c) is dark where (r + c) % 2 == parity
    parity: int = 0
    #: a ChArUco board's ``detect.charuco.CharucoGrid``: its grid comes from OpenCV's CharucoDetector, not
    #: findChessboardCorners; None for any other board
    charuco: object = None

    def __len__(self) -> int:
        return int(self.corners.shape[0])

    @property
    def side_lengths(self) -> np.ndarray:
        """(S, 4) length of side k (corner k -> corner k+1), board units."""
        return np.linalg.norm(np.roll(self.corners, -1, axis=1) - self.corners, axis=2)

    @property
    def square(self) -> float:
        """A chessboard's square side (board units): its first square's first side."""
        return float(np.linalg.norm(self.corners[0, 1] - self.corners[0, 0]))

    @property
    def centres(self) -> np.ndarray:
        return self.corners.mean(axis=1)

    def object_points(self) -> np.ndarray:
        """(S*4, 3) float32 corners on the plane Z = 0 (OpenCV's object points), square-major."""
        c = self.corners.reshape(-1, 2)
        return np.c_[c, np.zeros(len(c))].astype(np.float32)


def signed_areas(quads: np.ndarray) -> np.ndarray:
    """Shoelace signed area of each (…, 4, 2) quad (positive: counter-clockwise in a y-up frame)."""
    x, y = quads[..., 0], quads[..., 1]
    return 0.5 * (x * np.roll(y, -1, axis=-1) - np.roll(x, -1, axis=-1) * y).sum(axis=-1)


def convex(quads: np.ndarray) -> np.ndarray:
    """True where each (…, 4, 2) quad is strictly convex (all turns the same way)."""
    e = np.roll(quads, -1, axis=-2) - quads
    cross = e[..., 0] * np.roll(e, -1, axis=-2)[..., 1] - e[..., 1] * np.roll(e, -1, axis=-2)[..., 0]
    return np.all(cross > 0, axis=-1) | np.all(cross < 0, axis=-1)


def check_model(corners: np.ndarray, source: str) -> BoardModel:
    """A ``BoardModel`` of (S, 4, 2) corners, or one InputError line naming ``source`` and the fix."""
    c = np.asarray(corners, np.float64)
    if c.ndim != 3 or c.shape[1:] != (4, 2):
        raise InputError(f"model {source}: expected (squares, 4, 2) corners, got shape {c.shape}")
    if len(c) < MIN_SQUARES:
        raise InputError(f"model {source}: {len(c)} square(s); a board model needs at least {MIN_SQUARES}")
    if not np.all(np.isfinite(c)):
        raise InputError(f"model {source}: non-finite coordinates; every corner must be a number")
    area = signed_areas(c)
    lengths = np.linalg.norm(np.roll(c, -1, axis=1) - c, axis=2)
    bad = np.flatnonzero(~convex(c) | (np.abs(area) <= 1e-9 * max(1.0, float(np.abs(c).max()) ** 2)))
    if bad.size:
        raise InputError(f"model {source}: square {bad[0] + 1} (line {bad[0] + 1}) is not a convex quadrilateral; "
                         "give its four corners in cyclic order")
    if not (np.all(area > 0) or np.all(area < 0)):
        k = int(np.flatnonzero(np.sign(area) != np.sign(area[0]))[0])
        raise InputError(f"model {source}: square {k + 1} (line {k + 1}) lists its corners in the other "
                         "direction than square 1; give every square's corners in the same cyclic order")
    if lengths.min() <= 0:
        raise InputError(f"model {source}: a square has a side of zero length; check the corners")
    centres = c.mean(axis=1)
    d = np.linalg.norm(centres[:, None] - centres[None], axis=2)
    np.fill_diagonal(d, np.inf)
    i, j = np.unravel_index(np.argmin(d), d.shape)
    if d[i, j] < 0.5 * min(lengths[i].min(), lengths[j].min()):
        raise InputError(f"model {source}: squares {min(i, j) + 1} and {max(i, j) + 1} overlap; "
                         "each line must be a different square")
    return BoardModel(c, source)


def read_model(path) -> BoardModel:
    """Read a model file (one square per line: ``x0 y0 x1 y1 x2 y2 x3 y3``; '#' starts a comment)."""
    p = check_input_file(path, "board model file")
    if p.stat().st_size > MAX_MODEL_BYTES:
        raise InputError(f"model {p}: {p.stat().st_size:,} bytes is far too large for a board model "
                         "(one line of 8 numbers per square); check the file")
    try:
        text = p.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"model {p}: cannot be read as text ({exc.__class__.__name__}); "
                         "give a text file with 8 numbers per line") from None
    rows = []
    for k, line in enumerate(text.splitlines(), start=1):
        body = line.split("#", 1)[0].split()
        if not body:
            continue
        if len(body) != 8:
            raise InputError(f"model {p}: line {k} has {len(body)} values; each line is one square, "
                             "8 numbers (x y of its four corners)")
        try:
            rows.append([float(v) for v in body])
        except ValueError:
            raise InputError(f"model {p}: line {k} holds a value that is not a number; "
                             "each line is 8 numbers (x y of a square's four corners)") from None
    if not rows:
        raise InputError(f"model {p}: no squares; each line is 8 numbers (x y of a square's four corners)")
    return check_model(np.array(rows).reshape(-1, 4, 2), str(p))

