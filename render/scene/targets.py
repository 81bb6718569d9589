"""What stands in front of the camera: the targets T1-T4, the checkerboard and boards of dark squares
(geometry and materials).

Pure data and geometry, no Mitsuba: the spec loader, the ground truth and the
Mitsuba scene all read these definitions.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from edgetruth.errors import InputError
from edgetruth.render.schema import Key, parse_table
# the stand-off and the board's default size live with the shapes (re-exported here)
from edgetruth.render.scene.shapes import BOARD_HALF_SIZE_M, TARGET_STANDOFF_M, Shape  # noqa: F401
from edgetruth.render.scene.target_scene import checkerboard_preset, legacy_targets
BOARD_REFLECTANCE = 0.8  # white matte board (Lambertian albedo)
#: the shipped checkerboard preset (``assets/targets.toml [checkerboard]``): kind = "checkerboard" groups show it
_PRESET, _PRESET_MARGIN_M = checkerboard_preset()
CHECKER_BLACK_REFLECTANCE = _PRESET.material.albedo  # the checkerboard's black squares: matte black print (0.04)

#: Target ids -> shape and material (Lambertian albedos): the presets of the shape catalogue, read from the
#: shipped ``assets/targets.toml`` (``edgetruth.render.scene.shapes``).  A group showing a preset with no scene
#: key of its own renders the fixed scene of ``TargetRig`` (the same BSDFs), so its images are unchanged.
TARGETS = legacy_targets()


@dataclass(frozen=True)
class Checkerboard:
    """``cols`` x ``rows`` squares of ``square_m``; inner corners (cols-1) x (rows-1).  Its squares are the
    catalogue's ``checkerboard`` shape (``shape``; defaults: the shipped preset, 10 x 7 squares of 30 mm), on a
    white plate with ``margin_m`` around them."""

    cols: int = _PRESET.cols
    rows: int = _PRESET.rows
    square_m: float = _PRESET.square_m
    margin_m: float = _PRESET_MARGIN_M

    def shape(self) -> Shape:
        """The catalogue shape of its squares: centred on the plate, unturned, the preset's material."""
        return Shape("checkerboard", rows=self.rows, cols=self.cols, square_m=self.square_m,
                     material=_PRESET.material)

    @property
    def pattern_size(self) -> tuple[int, int]:
        """OpenCV's patternSize (inner corners per row, per column)."""
        return self.cols - 1, self.rows - 1

    @property
    def half_size_m(self) -> tuple[float, float]:
        """Half width and height of the plate (squares plus margin)."""
        return self.cols * self.square_m / 2 + self.margin_m, self.rows * self.square_m / 2 + self.margin_m

    def plate_corners_local(self) -> np.ndarray:
        hx, hy = self.half_size_m
        return np.array([[-hx, -hy, 0.0], [hx, -hy, 0.0], [hx, hy, 0.0], [-hx, hy, 0.0]])

    def inner_corners_local(self, z_m: float = 0.0) -> np.ndarray:
        """Inner corners, row-major (x fastest) like ``cv2.findChessboardCorners``; board centre at 0."""
        xy = self.shape().inner_corners_local()
        return np.column_stack([xy, np.full(len(xy), z_m)])

    def black_quads_local(self, z_m: float) -> np.ndarray:
        """(n, 4, 3) corners of the black squares ((i + j) even is black): the catalogue shape's dark squares
        (``Shape.checker_quads_local``, the same floats as before the catalogue held them: the renders are
        byte-identical), each top-left, top-right, bottom-right, bottom-left, row-major."""
        q = self.shape().checker_quads_local()
        return np.concatenate([q, np.full(q.shape[:2] + (1,), float(z_m))], axis=2)

    def to_dict(self) -> dict:
        return {"cols": self.cols, "rows": self.rows, "square_m": self.square_m, "margin_m": self.margin_m,
                "pattern_size": list(self.pattern_size), "black_square": "(col + row) even, col 0 row 0 at top-left",
                "white_reflectance": BOARD_REFLECTANCE, "black_reflectance": CHECKER_BLACK_REFLECTANCE,
                "material": "Lambertian (diffuse) white plate and black squares"}


_C = Checkerboard()
CHECKERBOARD_KEYS = [
    Key("cols", "int", _C.cols, "squares", "squares per row", 3, 100),
    Key("rows", "int", _C.rows, "squares", "squares per column", 3, 100),
    Key("square_m", "float", _C.square_m, "m", "side of one square", 1e-4, 1.0),
    Key("margin_m", "float", _C.margin_m, "m", "white margin around the squares", 0.0, 1.0),
]


# --- a board of dark squares ------------------------------------------------------------------
#: The model file each shipped real photo set holds (``assets/real/<name>/``).
MODEL_FILE = "Model.txt"
MAX_SQUARES = 10_000


@dataclass(frozen=True)
class SquareBoard:
    """Dark quads (squares, or any convex quads) printed flush on a white plate, as on Zhang's board.

    ``quads_model_m``: per square its 4 corners (x, y) in the *model frame* (metres; x right, y down, z
    into the board, as a board frame), in the model's order.  Rendering and sampled poses use the
    board frame centred on the squares' bounding box (``centre_model_m``); an explicit pose maps the
    model frame.  The plate is ``plate_size_m`` (centred on the squares) or their bounding box plus
    ``margin_m`` on every side.
    """

    quads_model_m: tuple
    source: str = "pattern"
    margin_m: float = 0.02
    plate_size_m: tuple | None = None
    square_reflectance: float = CHECKER_BLACK_REFLECTANCE
    board_reflectance: float = BOARD_REFLECTANCE
    model_unit_m: float = 1.0

    @classmethod
    def pattern(cls, cols: int = 8, rows: int = 8, side_m: float = 0.02, pitch_m: float = 0.035, **kw) -> "SquareBoard":
        """``rows`` x ``cols`` squares of ``side_m`` every ``pitch_m``, row-major from the top-left square;
        model origin at its top-left corner; corners top-left, top-right, bottom-right, bottom-left."""
        quads = []
        for j in range(rows):
            for i in range(cols):
                x0, y0 = i * pitch_m, j * pitch_m
                quads.append(((x0, y0), (x0 + side_m, y0), (x0 + side_m, y0 + side_m), (x0, y0 + side_m)))
        return cls(quads_model_m=tuple(quads), source=f"pattern {rows} x {cols}, side {side_m:g} m, pitch {pitch_m:g} m",
                   **kw)

    @classmethod
    def chessboard(cls, cols: int, rows: int, side_m: float, ring: tuple = (1.0, 1.0), **kw) -> "SquareBoard":
        """The dark squares of a chessboard of ``cols`` x ``rows`` *inner* corners (OpenCV's patternSize), inner
        corner (i, j) (row i, column j) at (j, i) * side_m.  First the dark squares between inner corners, in the
        board study's chessboard model order (``edgetruth.evaluate.board.detect.chessboard.chessboard_model``, parity 0:
        square (r, c) dark where r + c is even; row-major; corners (c, r), (c+1, r), (c+1, r+1), (c, r+1)), so a
        render's first squares are the study's model; then the dark squares of the outer ring, row-major, each cut
        to ``ring`` = [x, y] of a square's side beyond the outermost inner corners (1: whole squares; printed
        boards are often cut there)."""
        quads = []
        cells = [(r, c) for r in range(rows - 1) for c in range(cols - 1)]
        ring_cells = [(r, c) for r in range(-1, rows) for c in range(-1, cols)
                      if r in (-1, rows - 1) or c in (-1, cols - 1)]
        for r, c in cells + ring_cells:
            if (r + c) % 2:
                continue
            x0 = c * side_m if c >= 0 else -ring[0] * side_m
            x1 = (c + 1) * side_m if c < cols - 1 else (cols - 1 + ring[0]) * side_m
            y0 = r * side_m if r >= 0 else -ring[1] * side_m
            y1 = (r + 1) * side_m if r < rows - 1 else (rows - 1 + ring[1]) * side_m
            quads.append(((x0, y0), (x1, y0), (x1, y1), (x0, y1)))
        return cls(quads_model_m=tuple(quads), source=f"chessboard {cols}x{rows} inner corners, side {side_m:g} m, "
                   f"outer ring {ring[0]:g} x {ring[1]:g} of a side", **kw)

    @property
    def quads_model(self) -> np.ndarray:
        """(n, 4, 2) corners in the model frame, metres."""
        return np.asarray(self.quads_model_m, dtype=np.float64).reshape(-1, 4, 2)

    @property
    def n_squares(self) -> int:
        return len(self.quads_model_m)

    @property
    def centre_model_m(self) -> np.ndarray:
        """Centre of the squares' bounding box in the model frame (x, y, 0): the board frame's origin."""
        q = self.quads_model.reshape(-1, 2)
        return np.r_[0.5 * (q.min(0) + q.max(0)), 0.0]

    @property
    def half_size_m(self) -> tuple[float, float]:
        """Half width and height of the plate."""
        if self.plate_size_m is not None:
            return 0.5 * self.plate_size_m[0], 0.5 * self.plate_size_m[1]
        q = self.quads_model.reshape(-1, 2)
        ext = 0.5 * (q.max(0) - q.min(0)) + self.margin_m
        return float(ext[0]), float(ext[1])

    def model_points(self, z_m: float = 0.0) -> np.ndarray:
        """(n, 4, 3) corners in the model frame at z."""
        q = self.quads_model
        return np.concatenate([q, np.full(q.shape[:2] + (1,), z_m)], axis=2)

    def quads_local(self, z_m: float = 0.0) -> np.ndarray:
        """(n, 4, 3) corners in the centred board frame, model order."""
        return self.model_points(z_m) - self.centre_model_m

    def black_quads_local(self, z_m: float) -> np.ndarray:
        """(n, 4, 3) corners for the mesh, each wound like the checkerboard's (positive shoelace area in
        the board's x right, y down axes: its triangles face the camera)."""
        q = self.quads_local(z_m)
        x, y = q[..., 0], q[..., 1]
        area2 = np.sum(x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y, axis=1)
        q[area2 < 0] = q[area2 < 0][:, ::-1]
        return q

    def plate_corners_local(self) -> np.ndarray:
        hx, hy = self.half_size_m
        return np.array([[-hx, -hy, 0.0], [hx, -hy, 0.0], [hx, hy, 0.0], [-hx, hy, 0.0]])

    def to_dict(self) -> dict:
        return {"source": self.source, "n_squares": self.n_squares, "model_unit_m": self.model_unit_m,
                "plate_size_m": [2 * v for v in self.half_size_m],
                "plate_centre_model_m": self.centre_model_m.tolist(),
                "square_reflectance": self.square_reflectance, "board_reflectance": self.board_reflectance,
                "material": "Lambertian (diffuse) white plate and dark squares, printed flush"}

    def resolved(self) -> dict:
        """Every value that determines the images (for the spec's identity hash)."""
        return {**self.to_dict(), "quads_model_m": self.quads_model.tolist(), "margin_m": self.margin_m}


_SQ = SquareBoard.pattern()
SQUARES_KEYS = [
    Key("model", "str", "", "", "the squares' corners from a model file: a shipped real photo set's name "
        f"(zhang1998: its {MODEL_FILE}) or a path (relative to the spec's folder); one square per line, "
        "x y of its 4 corners (8 numbers) in model_unit_m, in the model's frame (x right, y down on the "
        "board); empty: the pattern rows x cols"),
    Key("model_unit_m", "float", None, "m", "length of the model file's unit (0.0254: inches); required "
        "with model", 1e-9, 1e3),
    Key("chessboard", "str", "", "COLSxROWS", "a chessboard of COLS x ROWS inner corners (OpenCV's patternSize, e.g. "
        "9x6) with squares of side_m: its dark squares, first those between the inner corners in the board study's "
        "model order, then the outer ring's (cut to ring); empty: no chessboard"),
    Key("ring", "vec2", [1.0, 1.0], "side", "chessboard: how much of a square the outer ring shows beyond the "
        "outermost inner corners, [along x, along y] (1: whole squares)", 0.05, 1.0),
    Key("cols", "int", 8, "squares", "pattern: squares per row", 1, 1000),
    Key("rows", "int", 8, "squares", "pattern: squares per column", 1, 1000),
    Key("side_m", "float", 0.02, "m", "pattern or chessboard: side of one square", 1e-5, 10.0),
    Key("pitch_m", "float", 0.035, "m", "pattern: distance between neighbouring squares' corners (>= side_m)",
        1e-5, 10.0),
    Key("margin_m", "float", _SQ.margin_m, "m", "white plate around the squares' bounding box", 0.0, 10.0),
    Key("plate_size_m", "vec2", None, "m", "[width, height] of the white plate, centred on the squares' "
        "bounding box (replaces margin_m)", 1e-4, 100.0),
    Key("square_reflectance", "float", _SQ.square_reflectance, "", "Lambertian albedo of the squares (matte "
        "black print)", 0.0, 1.0),
    Key("board_reflectance", "float", _SQ.board_reflectance, "", "Lambertian albedo of the plate (white "
        "paper)", 0.0, 1.0),
]
_PATTERN_KEYS = ("cols", "rows", "side_m", "pitch_m")


def resolve_model_path(ref: str, base_dir: Path | None = None) -> Path:
    """A model reference: a shipped real set's name (its ``Model.txt``) or a file path (relative to
    ``base_dir``)."""
    if Path(ref).suffix == "" and "/" not in ref and "\\" not in ref:
        from edgetruth.resources import real_set, shipped_real_set_names

        try:
            return real_set(ref) / MODEL_FILE
        except InputError:
            raise InputError(f"no shipped real set {ref!r} (shipped: {', '.join(shipped_real_set_names())}); "
                             "give a set's name or a model file's path (with its suffix)") from None
    p = Path(ref).expanduser()
    if not p.is_absolute() and base_dir is not None:
        p = base_dir / p
    return p


def read_square_model(path: Path, unit_m: float, where: str) -> tuple:
    """The quads of a model file (Zhang's ``Model.txt`` layout: per line x y of 4 corners), metres."""
    try:
        text = Path(path).read_text()
    except OSError as exc:
        raise InputError(f"{where}: cannot read model file {path} ({exc.strerror or exc}); fix the path "
                         "(relative to the spec's folder) or use a shipped set's name") from None
    quads = []
    for n, line in enumerate(text.splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        try:
            v = [float(x) for x in line.split()]
        except ValueError:
            v = []
        if len(v) != 8 or not all(math.isfinite(x) for x in v):
            raise InputError(f"{where}: {path} line {n}: expected 8 numbers (x y of 4 corners), got {line[:60]!r}")
        quads.append(tuple((v[2 * k] * unit_m, v[2 * k + 1] * unit_m) for k in range(4)))
    if not quads:
        raise InputError(f"{where}: {path} holds no squares (one square per line: x y of 4 corners)")
    if len(quads) > MAX_SQUARES:
        raise InputError(f"{where}: {path} holds {len(quads)} squares; at most {MAX_SQUARES}")
    return tuple(quads)


def _check_quads(quads: np.ndarray, where: str) -> None:
    """Each quad convex and not degenerate (the renderer splits it along a diagonal; its sides are lines)."""
    for i, q in enumerate(quads):
        e = np.roll(q, -1, axis=0) - q
        cross = e[:, 0] * np.roll(e, -1, axis=0)[:, 1] - e[:, 1] * np.roll(e, -1, axis=0)[:, 0]
        scale = float(np.max(np.linalg.norm(e, axis=1))) ** 2
        if scale == 0 or not (np.all(cross > 1e-9 * scale) or np.all(cross < -1e-9 * scale)):
            raise InputError(f"{where}: square {i}: its 4 corners are not a convex quad in order "
                             f"({np.round(q, 6).tolist()} m); list them around the square")


def square_board_from_dict(d: dict, base_dir: Path | None, where: str) -> SquareBoard:
    """A ``SquareBoard`` from a spec's ``squares = {...}`` table, every value checked."""
    v = parse_table(d, SQUARES_KEYS, where)
    common = {"margin_m": v["margin_m"], "plate_size_m": v["plate_size_m"],
              "square_reflectance": v["square_reflectance"], "board_reflectance": v["board_reflectance"]}
    if v["chessboard"] and v["model"]:
        raise InputError(f"{where}: model and chessboard both given; give a model file or a chessboard, not both")
    if "ring" in d and not v["chessboard"]:
        raise InputError(f"{where}: ring applies to a chessboard; remove it or add chessboard = \"COLSxROWS\"")
    if v["chessboard"]:
        clash = [k for k in ("cols", "rows", "pitch_m", "model_unit_m") if k in d]
        if clash:
            raise InputError(f"{where}: chessboard = {v['chessboard']!r} and {', '.join(clash)}: a chessboard takes "
                             "side_m (and ring) only; remove them")
        try:
            cols, rows = (int(s) for s in v["chessboard"].lower().split("x"))
            if cols < 2 or rows < 2:
                raise ValueError
        except ValueError:
            raise InputError(f"{where}: chessboard = {v['chessboard']!r}: give COLSxROWS inner corners, two "
                             "integers >= 2 (e.g. \"9x6\")") from None
        if (cols + 1) * (rows + 1) > 2 * MAX_SQUARES:
            raise InputError(f"{where}: chessboard = {v['chessboard']!r}: more than {MAX_SQUARES} dark squares")
        board = SquareBoard.chessboard(cols, rows, v["side_m"], tuple(v["ring"]), **common)
    elif v["model"]:
        clash = [k for k in _PATTERN_KEYS if k in d]
        if clash:
            raise InputError(f"{where}: model = {v['model']!r} and {', '.join(clash)}: give a model file or a "
                             "pattern (rows, cols, side_m, pitch_m), not both")
        if v["model_unit_m"] is None:
            raise InputError(f"{where}: model = {v['model']!r} needs model_unit_m (the file's unit in metres, "
                             "e.g. 0.0254 for inches); add it")
        try:
            path = resolve_model_path(v["model"], base_dir)
        except InputError as exc:
            raise InputError(f"{where}: model = {v['model']!r}: {exc}") from None
        quads = read_square_model(path, v["model_unit_m"], where)
        board = SquareBoard(quads_model_m=quads, source=f"model {v['model']} ({len(quads)} squares)",
                            model_unit_m=v["model_unit_m"], **common)
    else:
        if v["model_unit_m"] is not None:
            raise InputError(f"{where}: model_unit_m applies to a model file; remove it or add model")
        if v["pitch_m"] < v["side_m"]:
            raise InputError(f"{where}: pitch_m = {v['pitch_m']:g} < side_m = {v['side_m']:g}: squares would "
                             "overlap; make pitch_m >= side_m")
        if v["rows"] * v["cols"] > MAX_SQUARES:
            raise InputError(f"{where}: rows x cols = {v['rows'] * v['cols']} squares; at most {MAX_SQUARES}")
        board = SquareBoard.pattern(v["cols"], v["rows"], v["side_m"], v["pitch_m"], **common)
    _check_quads(board.quads_model, where)
    if v["plate_size_m"] is not None:
        q = board.quads_model.reshape(-1, 2)
        if np.any(np.asarray(v["plate_size_m"]) < q.max(0) - q.min(0) - 1e-12):
            ext = q.max(0) - q.min(0)
            raise InputError(f"{where}: plate_size_m = {list(v['plate_size_m'])} is smaller than the squares "
                             f"({ext[0]:.6g} x {ext[1]:.6g} m); make the plate at least as large")
    return board
