"""A ChArUco board (``kind = "charuco"``): OpenCV's layout and marker bitmaps as exact dark squares.

OpenCV's ``cv2.aruco.CharucoBoard((cols, rows), square_m, marker_m, dictionary)`` is a chessboard of
``cols`` x ``rows`` squares whose white squares each hold one ArUco marker, ids 0, 1, ... row-major from
the top-left.  Everything dark on it is a union of axis-aligned squares in the board frame: the
chessboard's dark squares, and each marker's dark cells (its bitmap, one cell per bit plus a one-cell
black border, as ``Dictionary.generateImageMarker`` draws it).  So the board renders as a board of dark
squares (``render.scene.targets.SquareBoard``): each marker's dark cells merged into rectangles (runs of
a row, stacked where the rows below repeat them), printed flush on the white plate with exact edges.

The layout (which squares are dark, where each marker sits, its id and corner order) is read from
OpenCV's own board object, the bitmaps from its own dictionary: a detector sees what it expects.  The
truth is computed in float64 here (OpenCV's object points are float32; they agree to 1e-7 m).

Board frame (``model frame``): OpenCV's CharucoBoard frame, origin at the board's top-left outer corner,
x right, y down, z into the board (metres).  Inner (ChArUco) corner id k = r (cols - 1) + c lies at
((c + 1) square_m, (r + 1) square_m); marker corners are top-left, top-right, bottom-right, bottom-left
of its bitmap, as ``cv2.aruco`` returns them.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from edgetruth.errors import InputError
from edgetruth.render.schema import Key, parse_table
from edgetruth.render.scene.targets import BOARD_REFLECTANCE, CHECKER_BLACK_REFLECTANCE, SquareBoard

BORDER_BITS = 1  # CharucoBoard draws its markers with a one-cell black border


def dictionary_names() -> tuple[str, ...]:
    """OpenCV's predefined ArUco dictionaries (``cv2.aruco.DICT_*``)."""
    import cv2

    return tuple(sorted(n for n in dir(cv2.aruco) if n.startswith("DICT_") and isinstance(getattr(cv2.aruco, n), int)))


def get_dictionary(name: str, where: str = "charuco"):
    """``cv2.aruco.getPredefinedDictionary(cv2.aruco.<name>)``; a bad name is an ``InputError``."""
    import cv2

    names = dictionary_names()
    if name not in names:
        raise InputError(f"{where}: dictionary = {name!r} is not one of OpenCV's: {', '.join(names)}")
    return cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))


def merge_cells(dark: np.ndarray) -> list[tuple[int, int, int, int]]:
    """Dark cells of a bitmap (bool (n, n), row-major from the top) as disjoint rectangles
    (r0, c0, r1, c1), cells [r0, r1) x [c0, c1): each row's runs, a run extended down while the rows below
    hold the same run (so neighbouring rectangles share edges, and their union is the dark cells)."""
    dark = np.asarray(dark, dtype=bool)
    n_rows = dark.shape[0]
    runs = []
    for r in range(n_rows):
        d = np.diff(np.r_[0, dark[r].astype(np.int8), 0])
        runs.append(list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1))))
    out, used = [], [set() for _ in range(n_rows)]
    for r in range(n_rows):
        for run in runs[r]:
            if run in used[r]:
                continue
            r1 = r + 1
            while r1 < n_rows and run in runs[r1] and run not in used[r1]:
                used[r1].add(run)
                r1 += 1
            out.append((r, int(run[0]), r1, int(run[1])))
    return out


@dataclass(frozen=True)
class CharucoBoard:
    """OpenCV's ChArUco board of ``cols`` x ``rows`` squares (its ``size``), squares of ``square_m``,
    markers of ``marker_m`` (black border included) from ``dictionary``, ``legacy`` = OpenCV's legacy
    pattern flag (``setLegacyPattern``: the layout before OpenCV 4.6 for an even number of rows), on a
    white plate with ``margin_m`` around the squares."""

    cols: int = 5
    rows: int = 7
    square_m: float = 0.04
    marker_m: float = 0.02
    dictionary: str = "DICT_4X4_50"
    legacy: bool = False
    margin_m: float = 0.01
    square_reflectance: float = CHECKER_BLACK_REFLECTANCE
    board_reflectance: float = BOARD_REFLECTANCE

    def cv_board(self):
        """The ``cv2.aruco.CharucoBoard`` this board is."""
        import cv2

        board = cv2.aruco.CharucoBoard((self.cols, self.rows), self.square_m, self.marker_m,
                                       get_dictionary(self.dictionary))
        board.setLegacyPattern(self.legacy)
        return board

    @functools.cached_property
    def _layout(self) -> dict:
        """Marker ids, the square each sits in, its bitmap's dark cells; the chessboard's dark squares."""
        board = self.cv_board()
        ids = np.asarray(board.getIds(), dtype=np.int64).ravel()
        obj = np.asarray(board.getObjPoints(), dtype=np.float64).reshape(-1, 4, 3)
        cells = np.floor(obj[:, :, :2].mean(axis=1) / self.square_m).astype(np.int64)  # (col, row) of its square
        d = board.getDictionary()
        n = d.markerSize + 2 * BORDER_BITS
        bitmaps = np.stack([d.generateImageMarker(int(i), n, borderBits=BORDER_BITS) == 0 for i in ids])
        holds = np.zeros((self.rows, self.cols), dtype=bool)
        holds[cells[:, 1], cells[:, 0]] = True
        return {"ids": ids, "cells": cells, "bitmaps": bitmaps, "bits": n, "cv_object_points": obj,
                "dark_squares": np.argwhere(~holds)}  # (row, col), row-major: every square without a marker

    @property
    def marker_ids(self) -> np.ndarray:
        return self._layout["ids"]

    @property
    def pattern_size(self) -> tuple[int, int]:
        """Inner corners per row, per column (as a chessboard's patternSize)."""
        return self.cols - 1, self.rows - 1

    def corner_object_points(self) -> np.ndarray:
        """(N, 3) ChArUco corners in the board frame (float64), id order (row-major, x fastest)."""
        r, c = np.divmod(np.arange((self.rows - 1) * (self.cols - 1)), self.cols - 1)
        return np.column_stack([(c + 1) * self.square_m, (r + 1) * self.square_m, np.zeros(len(r))])

    def marker_object_points(self) -> np.ndarray:
        """(M, 4, 3) marker corners in the board frame (float64): top-left, top-right, bottom-right,
        bottom-left of the bitmap, in ``marker_ids`` order."""
        cells = self._layout["cells"]
        off = 0.5 * (self.square_m - self.marker_m)
        tl = cells * self.square_m + off
        unit = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]) * self.marker_m
        xy = tl[:, None, :] + unit[None]
        return np.concatenate([xy, np.zeros(xy.shape[:2] + (1,))], axis=2)

    def dark_quads_model(self) -> np.ndarray:
        """(K, 4, 2) every dark rectangle in the board frame: first the chessboard's dark squares (row-major),
        then each marker's merged dark cells (``merge_cells``), marker by marker; corners top-left, top-right,
        bottom-right, bottom-left."""
        sq, lay = self.square_m, self._layout
        rects = [(c * sq, r * sq, (c + 1) * sq, (r + 1) * sq) for r, c in lay["dark_squares"]]
        cell = self.marker_m / lay["bits"]
        for tl, bitmap in zip(self.marker_object_points()[:, 0, :2], lay["bitmaps"]):
            rects += [(tl[0] + c0 * cell, tl[1] + r0 * cell, tl[0] + c1 * cell, tl[1] + r1 * cell)
                      for r0, c0, r1, c1 in merge_cells(bitmap)]
        x0, y0, x1, y1 = np.asarray(rects, dtype=np.float64).T
        return np.stack([np.c_[x0, y0], np.c_[x1, y0], np.c_[x1, y1], np.c_[x0, y1]], axis=1)

    @functools.cached_property
    def squares(self) -> SquareBoard:
        """The board as a board of dark squares (what renders): model frame = the board frame, plate = the
        squares plus ``margin_m``."""
        quads = tuple(tuple(map(tuple, q)) for q in self.dark_quads_model().tolist())
        return SquareBoard(quads_model_m=quads, source=self.describe(), margin_m=self.margin_m,
                           square_reflectance=self.square_reflectance, board_reflectance=self.board_reflectance)

    def describe(self) -> str:
        return (f"ChArUco {self.cols}x{self.rows} squares of {self.square_m:g} m, markers {self.marker_m:g} m "
                f"{self.dictionary}{' (legacy pattern)' if self.legacy else ''}")

    def to_dict(self) -> dict:
        return {"cols": self.cols, "rows": self.rows, "square_m": self.square_m, "marker_m": self.marker_m,
                "dictionary": self.dictionary, "legacy_pattern": self.legacy, "margin_m": self.margin_m,
                "border_bits": BORDER_BITS, "marker_bits": int(self._layout["bits"] - 2 * BORDER_BITS),
                "square_reflectance": self.square_reflectance, "board_reflectance": self.board_reflectance,
                "n_markers": int(len(self.marker_ids)), "n_dark_rectangles": int(self.squares.n_squares),
                "opencv": "cv2.aruco.CharucoBoard((cols, rows), square_m, marker_m, dictionary), "
                          "setLegacyPattern(legacy_pattern)",
                "material": "Lambertian (diffuse) white plate; dark squares and marker cells printed flush"}

    def resolved(self) -> dict:
        """Every value that determines the images (for the spec's identity hash)."""
        return {**self.to_dict(), "quads_model_m": self.dark_quads_model().tolist()}


_CB = CharucoBoard()
CHARUCO_KEYS = [
    Key("cols", "int", _CB.cols, "squares", "squares per row (OpenCV's size[0], squaresX)", 3, 100),
    Key("rows", "int", _CB.rows, "squares", "squares per column (OpenCV's size[1], squaresY)", 3, 100),
    Key("square_m", "float", _CB.square_m, "m", "side of one chessboard square (squareLength)", 1e-4, 10.0),
    Key("marker_m", "float", _CB.marker_m, "m", "side of one marker, its black border included (markerLength; "
        "< square_m)", 1e-5, 10.0),
    Key("dictionary", "str", _CB.dictionary, "", "OpenCV's predefined ArUco dictionary (cv2.aruco.DICT_*)"),
    Key("legacy", "bool", _CB.legacy, "", "OpenCV's legacy pattern (setLegacyPattern: boards made before "
        "OpenCV 4.6, which differ for an even number of rows)"),
    Key("margin_m", "float", _CB.margin_m, "m", "white plate around the squares", 0.0, 10.0),
    Key("square_reflectance", "float", _CB.square_reflectance, "", "Lambertian albedo of the dark squares and "
        "marker cells (matte black print)", 0.0, 1.0),
    Key("board_reflectance", "float", _CB.board_reflectance, "", "Lambertian albedo of the plate (white paper)",
        0.0, 1.0),
]


def charuco_board_from_dict(d: dict, where: str) -> CharucoBoard:
    """A ``CharucoBoard`` from a spec's ``charuco = {...}`` table, every value checked."""
    v = parse_table(d, CHARUCO_KEYS, where)
    if v["marker_m"] >= v["square_m"]:
        raise InputError(f"{where}: marker_m = {v['marker_m']:g} >= square_m = {v['square_m']:g}: a marker sits "
                         "inside its square; make marker_m smaller")
    dictionary = get_dictionary(v["dictionary"], where)
    n_markers = (v["cols"] * v["rows"]) // 2
    n_dict = len(dictionary.bytesList)
    if n_markers > n_dict:
        raise InputError(f"{where}: a {v['cols']}x{v['rows']} board needs {n_markers} markers and "
                         f"{v['dictionary']} has {n_dict}; use a larger dictionary or a smaller board")
    return CharucoBoard(**v)
