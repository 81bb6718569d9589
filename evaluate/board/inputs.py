"""What the board study reads: photos (files, folders or a shipped set's name), the model, the reference.

The model is a file of separate squares (``--model``), a chessboard (``--pattern COLSxROWS``,
``--square SIZE``; ``chessboard``), or a circle grid (``--pattern circles:COLSxROWS[:asymmetric]``, ``--square
SIZE`` required: OpenCV's squareSize, ``CircleBoard``).  ``resolve_inputs`` checks everything it can before any work
starts (paths exist and are files, a shipped set is known, at least ``MIN_PHOTOS`` photos, no
photo twice, one model given) and returns a ``BoardInputs``; ``load_photos`` then reads every
photo (decodable, gray, one size).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from edgetruth.errors import InputError
from edgetruth.evaluate.board.detect.charuco import board_of, charuco_model
from edgetruth.evaluate.board.detect.chessboard import chessboard_model
from edgetruth.evaluate.board.model import BoardModel, read_model
from edgetruth.evaluate.board.reference import read_corners, read_zhang_calibration, shipped_set
from edgetruth.evaluate.calibration import parse_pattern
from edgetruth.evaluate.pattern import BoardPattern, parse_board_pattern
from edgetruth.fileio import check_input_file
from edgetruth.image_io import SUFFIXES, read_gray_scaled
from edgetruth.resources import shipped_real_set_names


#: Leave-one-image-out calibrates on the other photos: Zhang's method needs at least 2 views.
MIN_PHOTOS = 3
#: File types read from a folder (``edgetruth.image_io`` reads them).
PHOTO_SUFFIXES = SUFFIXES


@dataclass(frozen=True)
class CircleBoard:
    """A circle grid as the board study reads it (``--pattern circles:COLSxROWS[:asymmetric] --square SIZE``).

    Attributes
    ----------
    pattern : BoardPattern
        The circles pattern (OpenCV's patternSize, asymmetric or not).
    spacing : float
        OpenCV's squareSize, in ``units``: circle (row i, column j) at (j s, i s), or for an asymmetric grid at
        ((2 j + i % 2) s, i s), so s is the row spacing and half the distance between neighbours in a row
        (``evaluate.board.circles.object_points``).
    units : str
        The unit of ``spacing``.
    source : str
        Where the board came from (for reports).
    diameter : float or None
        The printed circles' diameter in ``units`` where known (a shipped set's), else None.
    """

    pattern: BoardPattern
    spacing: float
    units: str
    source: str
    diameter: float | None = None


@dataclass
class BoardInputs:
    photos: list[Path]
    #: the board of squares; None for a circle grid (``circles``)
    model: BoardModel | None
    #: per photo (S, 4, 2) reference corners (a shipped set's own), else None
    reference_corners: list[np.ndarray] | None = None
    #: the set's published intrinsics {'fx', ..., 'k2'} and where they come from, else None
    reference_calibration: dict | None = None
    set_name: str | None = None
    notes: list[str] = field(default_factory=list)
    #: a circle grid's board (``CircleBoard``), None for a board of squares
    circles: CircleBoard | None = None

    @property
    def names(self) -> list[str]:
        return [p.name for p in self.photos]


def _shipped_names() -> list[str]:
    return shipped_real_set_names()


def board_model(model_path: str | None, pattern: str | None, square: str | float | None,
                marker: str | float | None = None) -> BoardModel:
    """The model the user gave: a model file, or a chessboard (``--pattern``, ``--square``; side lengths in squares
    when no square size is given), or a ChArUco board (``--pattern charuco:COLSxROWS:DICT``, ``--marker`` in the
    unit of ``--square``).  One InputError line when there is none, or both."""
    if marker is not None and not str(pattern or "").lower().startswith("charuco:"):
        raise InputError("--marker: only a ChArUco board (--pattern charuco:COLSxROWS:DICT) has markers; drop it")
    if model_path is not None and pattern is not None:
        raise InputError("board study: --model and --pattern both given; give --model FILE for a board of separate "
                         "squares or --pattern COLSxROWS for a chessboard")
    if square is not None and pattern is None:
        raise InputError("--square: only a chessboard (--pattern COLSxROWS) takes a square size; a model file gives "
                         "its squares' corners in its own units")
    if pattern is not None:
        size = 1.0
        if square is not None:
            try:
                size = float(square)
            except ValueError:
                size = float("nan")
            if not (size > 0 and np.isfinite(size)):
                raise InputError(f"--square {square!r}: give the side of one square, a positive number (in the unit "
                                 "side lengths should be reported in)")
        units = "squares" if square is None else "board units"
        if str(pattern).lower().startswith("charuco:"):
            return _charuco_model(pattern, size, units, marker)
        return chessboard_model(parse_pattern(pattern), size, units)
    if model_path is None:
        raise InputError("board study: no board model; give --model FILE (one square per line: x y of its "
                         "four corners) or, for a chessboard, --pattern COLSxROWS (inner corners)")
    return read_model(model_path)


def is_circles(pattern) -> bool:
    """Whether ``--pattern`` names a circle grid (``circles:...``)."""
    return str(pattern or "").strip().lower().startswith("circles:")


def circle_board(pattern: str, square, marker=None, model_path: str | None = None, units: str = "board units",
                 source: str | None = None, diameter: float | None = None) -> CircleBoard:
    """The circle grid the user gave (``--pattern circles:COLSxROWS[:asymmetric] --square SIZE``); one InputError
    line when ``--square`` is missing or not a positive number, or ``--model`` or ``--marker`` is given too."""
    bp = parse_board_pattern(pattern, kinds=("chessboard", "circles", "charuco"))
    if model_path is not None:
        raise InputError(f"board study: --model and --pattern {bp.text} both given; a circle grid needs only "
                         "--pattern and --square; drop --model")
    if marker is not None:
        raise InputError("--marker: only a ChArUco board (--pattern charuco:COLSxROWS:DICT) has markers; drop it")
    if square is None:
        raise InputError(f"--pattern {bp.text}: give --square SIZE, OpenCV's squareSize: the distance between "
                         "neighbouring circle centres" + (", for an asymmetric grid the row spacing (half the distance "
                                                          "between neighbours in a row)" if bp.asymmetric else "")
                         + ", e.g. --square 25")
    try:
        size = float(square)
    except ValueError:
        size = float("nan")
    if not (size > 0 and np.isfinite(size)):
        raise InputError(f"--square {square!r}: give the circle spacing (OpenCV's squareSize), a positive number")
    return CircleBoard(bp, size, units, source or f"--pattern {bp.text} --square {square}", diameter)


def _charuco_model(pattern: str, size: float, units: str, marker) -> BoardModel:
    """A ChArUco board's model (``detect.charuco.charuco_model``): squares of ``size``, markers of ``marker`` (the
    same unit)."""
    bp = parse_board_pattern(pattern, kinds=("chessboard", "charuco"))
    if marker is None:
        raise InputError(f"--pattern {pattern}: give --marker, the printed side of one marker (its black border "
                         "included) in the unit of --square (in squares without --square, e.g. 0.75)")
    try:
        m = float(marker)
    except ValueError:
        m = float("nan")
    return charuco_model(board_of(bp, size, m), size, units)


def resolve_inputs(items: list[str], model_path: str | None = None, pattern: str | None = None,
                   square: str | float | None = None, marker: str | float | None = None) -> BoardInputs:
    """Photos, folders or one shipped set name -> ``BoardInputs`` (one InputError line on bad input).  The model:
    ``model_path`` (separate squares) or ``pattern``/``square`` (a chessboard), or the shipped set's own."""
    if not items:
        raise InputError("board study: no photos; give photo files, folders, or a shipped set name "
                         f"({', '.join(_shipped_names())})")
    shipped = [s for s in items if not Path(s).exists() and s in _shipped_names()]
    if shipped:
        name = shipped[0]
        if len(items) > 1:
            raise InputError(f"{name}: a shipped set is studied on its own; give either {name} or photo paths")
        given = [f for f, v in (("--model", model_path), ("--pattern", pattern), ("--square", square)) if v is not None]
        if given:
            raise InputError(f"{name}: the shipped set supplies its own model; drop {' and '.join(given)}")
        s = shipped_set(name)
        if s is not None and "circles" in s:
            b = s["circles"]
            board = circle_board(str(b["pattern"]), b["square"], units=str(b["units"]), source=s["source"],
                                 diameter=float(b["diameter"]) if "diameter" in b else None)
            return BoardInputs(list(s["photos"]), None, set_name=name, circles=board)
        if s is not None and "chessboard" in s:
            b = s["chessboard"]
            if str(b["pattern"]).strip().lower().startswith("charuco:"):  # a ChArUco board: its marker side too
                if "marker" not in b:
                    raise InputError(f"{s['source']}: a ChArUco pattern needs marker = SIDE (the printed marker, its "
                                     "black border included, in the unit of square)")
                model = _charuco_model(str(b["pattern"]), float(b["square"]), str(b["units"]), b["marker"])
                model = replace(model, source=f"{model.source} ({s['source']})")
                return BoardInputs(list(s["photos"]), model, set_name=name)
            model = chessboard_model(parse_pattern(str(b["pattern"])), float(b["square"]), str(b["units"]),
                                     source=s["source"])
            return BoardInputs(list(s["photos"]), model, set_name=name)
        if s is None:
            raise InputError(f"{name}: this shipped set has no board model (Model.txt); the board study "
                             "needs one (give the photos with --model FILE)")
        model = read_model(s["model"])
        if name == "zhang1998":
            model = replace(model, units="in")  # assets/real/README.md: Zhang's model is in inches
        ref_cal = None
        if s["calibration"] is not None:
            ref_cal = read_zhang_calibration(s["calibration"])
            ref_cal["source"] = f"{name}/{s['calibration'].name}"
        return BoardInputs(list(s["photos"]), model, [read_corners(c, len(model)) for c in s["corners"]],
                           ref_cal, name)
    photos: list[Path] = []
    for item in items:
        p = Path(item)
        if p.is_dir():
            found = sorted(q for q in p.iterdir() if q.suffix.lower() in PHOTO_SUFFIXES and q.is_file())
            if not found:
                raise InputError(f"{p}: folder holds no photos ({', '.join(PHOTO_SUFFIXES)}); give photo files")
            photos += found
        elif not p.exists() and not p.suffix and item.isidentifier():
            raise InputError(f"{item}: no such photo, folder or shipped set; shipped sets: "
                             f"{', '.join(_shipped_names())}")
        else:
            photos.append(check_input_file(p, "photo"))
    seen = {}
    for p in photos:
        key = p.resolve()
        if key in seen:
            raise InputError(f"{p}: given twice (also as {seen[key]}); give each photo once")
        seen[key] = p
    if len(photos) < MIN_PHOTOS:
        raise InputError(f"board study: {len(photos)} photo(s); calibration with leave-one-image-out needs at "
                         f"least {MIN_PHOTOS} photos of the board")
    if is_circles(pattern):
        return BoardInputs(photos, None, circles=circle_board(pattern, square, marker, model_path))
    return BoardInputs(photos, board_model(model_path, pattern, square, marker))


def load_photos(photos: list[Path], channel: str = "luma") -> list[np.ndarray]:
    """Every photo as a 2-D array (``edgetruth.image_io.read_gray``), all of one size."""
    return load_photos_scaled(photos, channel)[0]


def load_photos_scaled(photos: list[Path], channel: str = "luma") -> tuple[list[np.ndarray], list[float]]:
    """``load_photos``, and each photo's full scale of stored values (``image_io.full_scale``)."""
    images, scales = [], []
    for p in photos:
        img, scale = read_gray_scaled(p, channel=channel)
        scales.append(scale)
        if img.ndim != 2:
            raise InputError(f"{p}: expected a gray image, got an array of shape {img.shape}; give a 2-D image")
        if images and img.shape != images[0].shape:
            raise InputError(f"{p}: {img.shape[1]}x{img.shape[0]} px, but {photos[0].name} is "
                             f"{images[0].shape[1]}x{images[0].shape[0]}; every photo must come from one camera "
                             "at one resolution")
        images.append(img)
    return images, scales
