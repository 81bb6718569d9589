"""``--pattern``: which printed board the photos show, as every board command reads it.

- ``COLSxROWS`` (``9x6``): a chessboard's inner corners per row x per column (OpenCV's ``patternSize``;
  a board of 10 x 7 squares is 9x6).
- ``circles:COLSxROWS`` (``circles:7x6``): a symmetric grid of circles, COLS per row, ROWS rows
  (``cv2.findCirclesGrid`` with ``CALIB_CB_SYMMETRIC_GRID``, its ``patternSize``).
- ``circles:COLSxROWS:asymmetric`` (``circles:4x11:asymmetric``): OpenCV's asymmetric grid, COLS circles
  in each row, ROWS rows, every other row shifted by half the spacing (``CALIB_CB_ASYMMETRIC_GRID``).
- ``charuco:COLSxROWS:DICT`` (``charuco:5x7:DICT_4X4_50``): a ChArUco board of COLS x ROWS *squares*
  with the markers of ``cv2.aruco``'s dictionary DICT (``cv2.aruco.CharucoBoard``'s ``size``).

One parser for every command; a command that takes only some kinds passes ``kinds``.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2

from edgetruth.errors import InputError


#: the board kinds ``--pattern`` names, in the order its help lists them
PATTERN_KINDS = ("chessboard", "circles", "charuco")

_HELP = ("give COLSxROWS for a chessboard's inner corners (e.g. 9x6), circles:COLSxROWS or "
         "circles:COLSxROWS:asymmetric for a circle grid (OpenCV's patternSize, e.g. circles:4x11:asymmetric), "
         "or charuco:COLSxROWS:DICT for a ChArUco board of COLS x ROWS squares (e.g. charuco:5x7:DICT_4X4_50)")


@dataclass(frozen=True)
class BoardPattern:
    """A printed board as ``--pattern`` names it.  ``cols``, ``rows``: a chessboard's inner corners, a circle
    grid's circles (per row, rows; OpenCV's ``patternSize``), a ChArUco board's squares.  ``asymmetric``: a
    circle grid's rows shifted by half a spacing every other row.  ``dictionary``: a ChArUco board's
    ``cv2.aruco`` dictionary name (``DICT_4X4_50``)."""

    kind: str
    cols: int
    rows: int
    asymmetric: bool = False
    dictionary: str | None = None

    @property
    def size(self) -> tuple[int, int]:
        """(cols, rows): OpenCV's ``patternSize`` (a ChArUco board: its squares)."""
        return self.cols, self.rows

    @property
    def text(self) -> str:
        """The ``--pattern`` text that parses back to this pattern."""
        n = f"{self.cols}x{self.rows}"
        if self.kind == "chessboard":
            return n
        if self.kind == "circles":
            return f"circles:{n}" + (":asymmetric" if self.asymmetric else "")
        return f"charuco:{n}:{self.dictionary}"

    def to_dict(self) -> dict:
        d = {"kind": self.kind, "pattern_size": [self.cols, self.rows]}
        if self.kind == "circles":
            d["asymmetric"] = self.asymmetric
        if self.kind == "charuco":
            d["dictionary"] = self.dictionary
        return d


def aruco_dictionaries() -> tuple[str, ...]:
    """The predefined dictionary names of the installed ``cv2.aruco`` (``DICT_4X4_50``, ...), sorted."""
    return tuple(sorted(n for n in dir(cv2.aruco) if n.startswith("DICT_") and isinstance(getattr(cv2.aruco, n), int)))


def _counts(text: str, whole: str, option: str, low: int) -> tuple[int, int]:
    parts = text.strip().lower().replace("×", "x").split("x")
    try:
        nx, ny = (int(v) for v in parts)
    except ValueError:
        nx = ny = 0
    if len(parts) != 2 or not (low <= nx <= 1000 and low <= ny <= 1000):
        raise InputError(f"{option} {whole!r}: COLSxROWS must be two counts {low}..1000; {_HELP}")
    return nx, ny


def parse_board_pattern(text: str, option: str = "--pattern", kinds: tuple[str, ...] = PATTERN_KINDS) -> BoardPattern:
    """``--pattern``'s value -> ``BoardPattern``; one ``InputError`` line naming the value and the forms it takes.
    ``kinds``: the board kinds the command takes (one outside them is refused, naming those it takes)."""
    whole = str(text)
    head, sep, rest = whole.strip().partition(":")
    kind = head.strip().lower() if sep else "chessboard"
    if kind not in PATTERN_KINDS:
        raise InputError(f"{option} {whole!r}: unknown board kind {head!r}; {_HELP}")
    if kind not in kinds:
        takes = " or ".join(kinds)
        raise InputError(f"{option} {whole!r}: this command takes a {takes} pattern, not a {kind} one; "
                         f"give {'COLSxROWS (e.g. 9x6)' if kinds == ('chessboard',) else 'one of those'}")
    if kind == "chessboard":
        if sep:
            raise InputError(f"{option} {whole!r}: {_HELP}")
        nx, ny = _counts(head, whole, option, 2)
        return BoardPattern("chessboard", nx, ny)
    size, _, tail = rest.partition(":")
    if kind == "circles":
        flag = tail.strip().lower()
        if flag not in ("", "asymmetric", "symmetric"):
            raise InputError(f"{option} {whole!r}: a circle grid's third part is 'asymmetric' (or nothing for a "
                             "symmetric grid), e.g. circles:4x11:asymmetric")
        nx, ny = _counts(size, whole, option, 2)
        return BoardPattern("circles", nx, ny, asymmetric=flag == "asymmetric")
    nx, ny = _counts(size, whole, option, 2)
    name = tail.strip().upper()
    known = aruco_dictionaries()
    if name not in known:
        raise InputError(f"{option} {whole!r}: give the board's cv2.aruco dictionary as the third part, one of "
                         f"{', '.join(known)} (e.g. charuco:5x7:DICT_4X4_50)")
    return BoardPattern("charuco", nx, ny, dictionary=name)
