"""A shipped set's own answers: Zhang's corners (``dataN.txt``) and his published calibration.

``dataN.txt``: one square per line, its four corners ``x y`` in pixels, in the model's order
(OpenCV's pixel-centre convention to within ~0.1 px, see assets/real/README.md).
``calibration-result-zhang-withdistortion.txt``: ``alpha gamma beta u0 v0``, then ``k1 k2``,
then per view a 3x3 rotation (rows) and a translation (board units).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from edgetruth.errors import InputError
from edgetruth.fileio import check_input_file, read_toml
from edgetruth.image_io import SUFFIXES
from edgetruth.resources import real_set


ZHANG_CALIBRATION = "calibration-result-zhang-withdistortion.txt"


def read_corners(path, n_squares: int) -> np.ndarray:
    """(S, 4, 2) corners of one photo from a ``dataN.txt``."""
    p = check_input_file(path, "corner file")
    try:
        v = np.array(p.read_text().split(), dtype=np.float64)
    except ValueError:
        raise InputError(f"{p}: holds a value that is not a number; expected 8 numbers per square") from None
    if v.size != 8 * n_squares or not np.all(np.isfinite(v)):
        raise InputError(f"{p}: {v.size} finite values, expected {8 * n_squares} (8 per square of the model)")
    return v.reshape(n_squares, 4, 2)


def read_zhang_calibration(path) -> dict:
    """{'fx','fy','cx','cy','k1','k2','skew'} of Zhang's published result, plus 'poses' [(R, t)]."""
    p = check_input_file(path, "calibration file")
    try:
        v = np.array(p.read_text().split(), dtype=np.float64)
    except ValueError:
        raise InputError(f"{p}: holds a value that is not a number; expected Zhang's calibration layout") from None
    if v.size < 7 or (v.size - 7) % 12:
        raise InputError(f"{p}: {v.size} values; expected 5 intrinsics, k1 k2, then 12 per view")
    alpha, gamma, beta, u0, v0, k1, k2 = v[:7]
    poses = [(v[7 + 12 * i: 16 + 12 * i].reshape(3, 3), v[16 + 12 * i: 19 + 12 * i]) for i in range((v.size - 7) // 12)]
    return {"fx": float(alpha), "fy": float(beta), "cx": float(u0), "cy": float(v0), "k1": float(k1),
            "k2": float(k2), "skew": float(gamma), "poses": poses}


#: A shipped chessboard, ChArUco or circle-grid set's board (TOML): ``pattern = "COLSxROWS"`` (a chessboard's inner
#: corners), ``"charuco:COLSxROWS:DICT"`` (a ChArUco board's squares) or ``"circles:COLSxROWS[:asymmetric]"`` (a circle
#: grid), ``square`` (a chessboard's square; a circle grid's spacing, OpenCV's squareSize), ``units``; for a ChArUco
#: board ``marker`` (the printed marker's side, in the unit of ``square``), for a circle grid optionally ``diameter``.
CHESSBOARD_FILE = "board.toml"


def shipped_set(name: str) -> dict | None:
    """{'photos': [...], 'model': Path, 'corners': [Path per photo], 'calibration': Path} of a shipped set that
    has a board model (``Model.txt``); {'photos': [...], 'chessboard': {'pattern', 'square', 'units'}, 'source'}
    of one that has a chessboard (``board.toml``), or 'circles' in place of 'chessboard' for a circle grid's
    (``pattern = "circles:..."``); else None."""
    root = Path(real_set(name))
    model = root / "Model.txt"
    if (root / CHESSBOARD_FILE).is_file():
        board = read_toml(root / CHESSBOARD_FILE)

        photos = sorted(p for p in root.iterdir() if p.suffix.lower() in SUFFIXES and p.is_file())
        key = "circles" if str(board.get("pattern", "")).strip().lower().startswith("circles:") else "chessboard"
        return {"name": name, "photos": photos, key: board, "source": f"{name}/{CHESSBOARD_FILE}"}
    if not model.is_file():
        return None
    photos = sorted(root.glob("CalibIm*.png"), key=lambda q: int("".join(ch for ch in q.stem if ch.isdigit()) or 0))
    corners = [root / f"data{''.join(ch for ch in q.stem if ch.isdigit())}.txt" for q in photos]
    cal = root / ZHANG_CALIBRATION
    return {"name": name, "photos": photos, "model": model, "corners": corners,
            "calibration": cal if cal.is_file() else None}
