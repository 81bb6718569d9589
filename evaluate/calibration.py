"""Camera calibration by Zhang's method (OpenCV) on rendered checkerboards, as a real user would,
and on real photographs (``calibrate_photos``, the ``edgetruth calibrate`` command).

Per board image: ``cv2.findChessboardCorners`` (``DETECT_FLAGS``; on an 8-bit copy scaled to the
image's own 0.5/99.5 percentiles), then ``cv2.cornerSubPix`` on the float
image; then one ``cv2.calibrateCamera`` over all boards with the full 5-term
Brown–Conrady model (k1, k2, p1, p2, k3), the OpenCV default.

What the user "knows" is the printed board (pattern size and square size, read
from the dataset's board description); the intrinsics, distortion and corner
positions recorded in the ground truth are used *only* to report the
calibration error next to the recovered values.

The cornerSubPix window: by default (``window_px=None``) 0.4 of the smallest imaged square
side (``subpix_window``), iterated to 1e-4 px, and a corner whose position that window and one of 0.6 of it
put more than ``NARROW_SHIFT_PX`` apart takes the narrower one's (the larger window reached another edge); a
fixed half-window can be asked for (``window_px=5`` is the 11 x 11 px window of OpenCV's own sample and
regression test), and is used as it is.
"""
from __future__ import annotations

import glob
from dataclasses import dataclass, field, replace
from pathlib import Path

import cv2
import numpy as np

from edgetruth import console
from edgetruth.errors import InputError
from edgetruth.evaluate.board_bend import MIN_CORNERS, bend_check
from edgetruth.evaluate.pattern import parse_board_pattern
from edgetruth.evaluate.residual_field import board_point_transfer, image_field_transfer, residual_structure
from edgetruth.fileio import check_input_file, read_json
from edgetruth.image_io import SUFFIXES, read_gray
from edgetruth.opencv_threads import calibrate_camera
from edgetruth.render.dataset.reader import open_dataset
from edgetruth.resources import real_set, shipped_real_set_names


#: cornerSubPix termination: 100 iterations or 1e-4 px.
_SUBPIX_CRITERIA = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 100, 1e-4)

#: The distortion models ``calibrate_photos`` offers -> (cv2.calibrateCamera flags, description).
#: The coefficients a model does not estimate are held at 0; ``dist_coeffs_opencv`` always has 5 terms.
DIST_MODELS = {
    "k1k2k3p1p2": (0, "5-term Brown-Conrady k1, k2, p1, p2, k3, OpenCV's default"),
    "k1k2p1p2": (cv2.CALIB_FIX_K3, "4-term Brown-Conrady k1, k2, p1, p2, k3 = 0"),
    "k1k2": (cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST, "radial k1, k2 only, p1 = p2 = k3 = 0"),
}
DEFAULT_DIST_MODEL = "k1k2k3p1p2"


def free_dist(flags: int) -> tuple[bool, ...]:
    """Which of (k1, k2, p1, p2, k3) cv2.calibrateCamera estimates under ``flags`` (of ``DIST_MODELS``)."""
    tangent = not flags & cv2.CALIB_ZERO_TANGENT_DIST
    return True, True, tangent, tangent, not flags & cv2.CALIB_FIX_K3
ZHANG_METHOD = "Zhang (cv2.calibrateCamera, 5-term Brown-Conrady), cornerSubPix corners"


def to_uint8(image: np.ndarray) -> np.ndarray:
    """A display/detection copy: linear stretch of the 0.5-99.5 percentile range to 0-255."""
    img = np.asarray(image, dtype=np.float64)
    lo, hi = np.percentile(img, [0.5, 99.5])
    if hi <= lo:
        hi = lo + 1.0
    return np.clip((img - lo) * (255.0 / (hi - lo)), 0, 255).astype(np.uint8)


def object_points(pattern_size: tuple[int, int], square_m: float) -> np.ndarray:
    """(N, 3) float32 board points, row-major with x fastest (OpenCV's corner order), z = 0."""
    nx, ny = pattern_size
    gx, gy = np.meshgrid(np.arange(nx), np.arange(ny))
    return np.stack([gx.ravel() * square_m, gy.ravel() * square_m, np.zeros(nx * ny)], 1).astype(np.float32)


def subpix_window(corners: np.ndarray, pattern_size: tuple[int, int]) -> int:
    """cornerSubPix half-window: 0.4 of the smallest imaged square side, clamped to 2..30 px.

    Larger windows average more pixels (measured on the calibration spec: corner RMS error
    0.051 px with a third-of-square window capped at 11 px, 0.048 px with 0.4 of the square);
    below half a square the window never reaches a neighbouring corner.
    """
    nx, ny = pattern_size
    c = corners.reshape(ny, nx, 2)
    dx = np.linalg.norm(np.diff(c, axis=1), axis=2).min()
    dy = np.linalg.norm(np.diff(c, axis=0), axis=2).min()
    return int(np.clip(np.floor(min(dx, dy) / 2.5), 2, 30))


#: ``cv2.findChessboardCorners``' flags, tried in turn until one finds the board: OpenCV's default (an adaptive
#: threshold of the histogram-equalised image), then the adaptive threshold alone, then a global one.  The default
#: loses some noisy renders of a board on a black background (2 of 40 of OpenCV's twin renders at 64 spp, and
#: board studies then left their pairs out) that the next finds; an image it finds is detected as before.
DETECT_FLAGS = (cv2.CALIB_CB_ADAPTIVE_THRESH + cv2.CALIB_CB_NORMALIZE_IMAGE, cv2.CALIB_CB_ADAPTIVE_THRESH, 0)


#: With the automatic window, each corner is refined a second time with a half-window of this fraction of it ...
NARROW_WINDOW_FRACTION = 0.6
#: ... and takes that position when the two differ by more than this (px): the larger window holds another edge
#: than the corner's own two (the cut outer ring of a printed board, its margin, the background beyond).  On
#: OpenCV's twin (13 renders, exact corners) the larger window put 17 of 676 corners, all on the grid's edge,
#: 0.3-3.4 px off (RMS 0.31 px over all); the check takes 19 corners, and the RMS to 0.053 px (max 0.28).  On
#: the calibration spec's 20 renders (a full ring) the two windows differ by at most 0.14 px: nothing changes.
NARROW_SHIFT_PX = 0.25


def detect_corners(image: np.ndarray, pattern_size: tuple[int, int], window_px: int | None = None,
                   info: dict | None = None) -> np.ndarray | None:
    """Subpixel inner corners (N, 2) in OpenCV pixel coordinates, or None if the board is not found
    (``DETECT_FLAGS``).

    ``window_px``: cornerSubPix half-window (OpenCV's winSize; the window is 2 * window_px + 1 px
    wide); None = ``subpix_window`` (0.4 of the smallest imaged square side), with the check of
    ``NARROW_SHIFT_PX`` per corner.  ``info`` (a dict, when given) receives ``window_px`` (the half-window) and
    ``narrowed`` (how many corners took the narrower window's position)."""
    img8 = to_uint8(image)
    for flags in DETECT_FLAGS:
        found, corners = cv2.findChessboardCorners(img8, tuple(pattern_size), flags=flags)
        if found:
            break
    else:
        return None
    win = subpix_window(corners.reshape(-1, 2), pattern_size) if window_px is None else int(window_px)
    img32 = np.asarray(image, dtype=np.float32)

    def refine(half: int) -> np.ndarray:
        out = cv2.cornerSubPix(img32, corners.astype(np.float32).copy(), (half, half), (-1, -1), _SUBPIX_CRITERIA)
        return out.reshape(-1, 2).astype(np.float64)

    refined, narrowed = refine(win), 0
    if window_px is None:
        narrow = refine(max(2, int(round(NARROW_WINDOW_FRACTION * win))))
        moved = np.linalg.norm(refined - narrow, axis=1) > NARROW_SHIFT_PX
        refined[moved], narrowed = narrow[moved], int(moved.sum())
    if info is not None:
        info.update(window_px=win, narrowed=narrowed)
    return refined


@dataclass
class Calibration:
    """A calibrated camera (OpenCV conventions) and how well it was determined.

    Attributes
    ----------
    K : numpy.ndarray
        (3, 3) intrinsics, px: fx, fy, cx, cy (``fx``, ``fy``, ``cx``, ``cy`` properties).
    dist : numpy.ndarray
        (5,) distortion (k1, k2, p1, p2, k3), OpenCV's model.
    image_size : tuple of int
        (width, height), px.
    rms_px : float
        Reprojection RMS, px.
    n_views : int
        Boards used.
    per_view_rms_px : list of float
        Reprojection RMS per view, px.
    used, rejected : list of str
        The images used, and those left out (board not found).
    corner_error_px : dict
        Renders only: detected against true corners, px.
    truth : dict or None
        Renders only: the true intrinsics (``errors()`` compares).
    method : str
        How it was determined, in words.
    residual_structure : dict
        Photos: whether the residuals are noise or a smooth field per view.
    board_bend : dict
        Photos: the calibration refitted with a bent board.
    """

    K: np.ndarray
    dist: np.ndarray  # (k1, k2, p1, p2, k3)
    image_size: tuple[int, int]  # (width, height)
    rms_px: float
    n_views: int
    per_view_rms_px: list[float] = field(default_factory=list)
    used: list[str] = field(default_factory=list)
    rejected: list[str] = field(default_factory=list)
    corner_error_px: dict = field(default_factory=dict)  # detected vs true corners (check only)
    truth: dict | None = None  # true intrinsics from the ground truth (check only)
    method: str = ZHANG_METHOD  # how it was determined, in words
    #: photos only: is the residual noise or a smooth field per view (``residual_field.residual_structure``)
    residual_structure: dict = field(default_factory=dict)
    #: photos only: the calibration refitted with a bent board (``board_bend.bend_check``)
    board_bend: dict = field(default_factory=dict)

    @property
    def fx(self) -> float:
        """K[0, 0]: the focal length along x, px."""
        return float(self.K[0, 0])

    @property
    def fy(self) -> float:
        """K[1, 1]: the focal length along y, px."""
        return float(self.K[1, 1])

    @property
    def cx(self) -> float:
        """K[0, 2]: the principal point's x, px (OpenCV convention)."""
        return float(self.K[0, 2])

    @property
    def cy(self) -> float:
        """K[1, 2]: the principal point's y, px (OpenCV convention)."""
        return float(self.K[1, 2])

    def errors(self) -> dict:
        """Recovered minus true values, for a calibration from renders (needs ``truth``).

        Returns
        -------
        dict
            ``fx_rel_pct``, ``fy_rel_pct`` (%), ``cx_px``, ``cy_px`` (px) and ``dist`` (coefficient differences);
            empty without ``truth``.
        """
        if not self.truth:
            return {}
        t = self.truth
        return {"fx_rel_pct": 100.0 * (self.fx - t["fx_px"]) / t["fx_px"],
                "fy_rel_pct": 100.0 * (self.fy - t["fy_px"]) / t["fy_px"],
                "cx_px": self.cx - t["cx_px"], "cy_px": self.cy - t["cy_px"],
                "dist": (self.dist - np.asarray(t["dist_coeffs_opencv"])).tolist()}

    def to_dict(self) -> dict:
        """The ``calibration.json`` form (docs/formats.md), which ``from_dict`` reads back.

        Returns
        -------
        dict
            ``K``, ``fx_px`` ... ``cy_px``, ``dist_coeffs_opencv``, ``image_size``, ``reprojection_rms_px`` and
            the rest of the fields.
        """
        return {"method": self.method,
                "K": self.K.tolist(), "fx_px": self.fx, "fy_px": self.fy, "cx_px": self.cx, "cy_px": self.cy,
                "dist_coeffs_opencv": self.dist.tolist(), "image_size": list(self.image_size),
                "reprojection_rms_px": self.rms_px, "n_views": self.n_views,
                "per_view_rms_px": self.per_view_rms_px, "used": self.used, "rejected": self.rejected,
                "corner_detection_error_px": self.corner_error_px, "truth": self.truth, "errors": self.errors()} | (
                    {"residual_structure": self.residual_structure} if self.residual_structure else {}) | (
                    {"board_bend": self.board_bend} if self.board_bend else {})

    @classmethod
    def from_dict(cls, d: dict, where: str = "calibration") -> "Calibration":
        """The inverse of ``to_dict`` (a ``calibration.json`` written by ``edgetruth calibrate``, ``run``, ``evaluate``).

        Parameters
        ----------
        d : dict
            The JSON's content: at least ``K`` (3 x 3), ``dist_coeffs_opencv`` and ``image_size``.
        where : str, optional
            What error messages call it (the file).

        Returns
        -------
        Calibration
            The camera.
        """
        try:
            K = np.asarray(d["K"], float)
            dist = np.asarray(d["dist_coeffs_opencv"], float).ravel()
            size = tuple(int(v) for v in d["image_size"])
            if K.shape != (3, 3) or dist.size < 4 or len(size) != 2 or not np.all(np.isfinite(K)):
                raise ValueError("shapes")
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"{where}: not an edgetruth calibration (needs K 3x3, dist_coeffs_opencv, image_size; "
                             f"{type(exc).__name__}: {exc}); pass the calibration.json of a run or a dataset of "
                             "checkerboard renders") from None
        return cls(K=K, dist=np.pad(dist, (0, max(0, 5 - dist.size)))[:5], image_size=size,
                   rms_px=float(d.get("reprojection_rms_px", float("nan"))), n_views=int(d.get("n_views", 0)),
                   per_view_rms_px=list(d.get("per_view_rms_px", [])), used=list(d.get("used", [])),
                   rejected=list(d.get("rejected", [])), corner_error_px=dict(d.get("corner_detection_error_px", {})),
                   truth=d.get("truth"), method=str(d.get("method", ZHANG_METHOD)),
                   residual_structure=dict(d.get("residual_structure", {})), board_bend=dict(d.get("board_bend", {})))


def load_calibration(ref: str | Path, progress: bool = False) -> Calibration:
    """A calibration from a JSON file or from a dataset of checkerboard renders (calibrated then).

    Parameters
    ----------
    ref : str or pathlib.Path
        A ``calibration.json`` (written by ``edgetruth calibrate``, ``run`` or ``evaluate``: at least ``K``,
        ``dist_coeffs_opencv``, ``image_size``) or a rendered dataset's folder.
    progress : bool, optional
        A progress bar while calibrating a dataset.

    Returns
    -------
    Calibration
        The camera.

    Raises
    ------
    edgetruth.errors.InputError
        Not a calibration, or a dataset without enough boards.
    """
    p = Path(ref)
    if p.is_dir():
        return calibrate_dataset(p, progress=progress)
    return Calibration.from_dict(read_json(p), where=str(p))


#: cv2.undistortPoints' iteration: converged (its default, 5 steps, leaves ~0.1 px at a strong lens's corners).
UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)


def undistort_px(points: np.ndarray, K: np.ndarray, dist: np.ndarray, normalised: bool = False) -> np.ndarray:
    """Distorted pixel coordinates (..., 2) -> undistorted pixel coordinates with the same K (OpenCV's model,
    ``cv2.undistortPoints`` iterated to 1e-12), or normalised ones (x/z, y/z) when ``normalised``; NaN stays NaN."""
    p = np.asarray(points, np.float64)
    out = np.full(p.shape, np.nan)
    flat, res = p.reshape(-1, 2), out.reshape(-1, 2)
    ok = np.all(np.isfinite(flat), axis=1)
    if ok.any():
        K = np.asarray(K, np.float64)
        res[ok] = cv2.undistortPoints(flat[ok].reshape(-1, 1, 2), K, np.asarray(dist, np.float64),
                                      P=None if normalised else K, criteria=UNDISTORT_CRITERIA).reshape(-1, 2)
    return out


def distort_px(points: np.ndarray, K: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Undistorted pixel coordinates (N, 2) -> distorted ones (the forward model, ``cv2.projectPoints``); NaN stays
    NaN."""
    K = np.asarray(K, np.float64)
    p = np.asarray(points, np.float64).reshape(-1, 2)
    out = np.full(p.shape, np.nan)
    ok = np.all(np.isfinite(p), axis=1)
    if ok.any():
        yn = (p[ok, 1] - K[1, 2]) / K[1, 1]
        xn = (p[ok, 0] - K[0, 2] - K[0, 1] * yn) / K[0, 0]
        obj = np.stack([xn, yn, np.ones_like(xn)], axis=1).reshape(-1, 1, 3)
        out[ok] = cv2.projectPoints(obj, np.zeros(3), np.zeros(3), K, np.asarray(dist, np.float64))[0].reshape(-1, 2)
    return out


def _match_order(detected: np.ndarray, true_px: np.ndarray) -> np.ndarray:
    """The detected corners in the true corners' order (OpenCV may start from the opposite end)."""
    fwd = np.linalg.norm(detected - true_px, axis=1).mean()
    rev = np.linalg.norm(detected[::-1] - true_px, axis=1).mean()
    return detected if fwd <= rev else detected[::-1]


def solve_points(obj_list, img_list, size_wh: tuple[int, int], flags: int, residuals: list | None = None,
                 poses: list | None = None):
    """cv2.calibrateCamera (iterated to 1e-12) -> (rms_px, K, dist (5,), per-view RMS px); ``residuals``, when
    given, receives each view's (n, 2) measured minus projected corners (px), ``poses`` its (rvec, tvec)."""
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 200, 1e-12)
    rms, K, dist, rvecs, tvecs = calibrate_camera(obj_list, img_list, tuple(size_wh), None, None, flags=flags,
                                                     criteria=crit)
    per_view = []
    for o, i, r, t in zip(obj_list, img_list, rvecs, tvecs):
        p, _ = cv2.projectPoints(o, r, t, K, dist)
        per_view.append(float(np.sqrt(np.mean(np.sum((p.reshape(-1, 2) - i.reshape(-1, 2)) ** 2, 1)))))
        if residuals is not None:
            residuals.append(i.reshape(-1, 2).astype(np.float64) - p.reshape(-1, 2))
        if poses is not None:
            poses.append((np.ravel(r).astype(float), np.ravel(t).astype(float)))
    dist = np.pad(np.asarray(dist, float).ravel(), (0, 5))[:5]
    return float(rms), np.asarray(K, float), dist, per_view


def calibrate(views: list[tuple[str, np.ndarray]], pattern_size: tuple[int, int], square_m: float,
              truths: list[dict] | None = None, flags: int = 0, progress=None) -> Calibration:
    """Zhang's calibration from ``views`` = [(name, image), ...].

    ``truths`` (optional, same order): the ground-truth dicts of the views, used only to
    report corner-detection errors and the true intrinsics.
    """
    if not views:
        raise InputError("calibration: no checkerboard images; the spec needs a checkerboard group")
    obj = object_points(pattern_size, square_m)
    obj_list, img_list, used, rejected, corner_err = [], [], [], [], []
    shape = None
    it = views if progress is None else progress(views)
    for k, (name, image) in enumerate(it):
        shape = image.shape
        corners = detect_corners(image, pattern_size)
        if corners is None:
            rejected.append(name)
            continue
        obj_list.append(obj)
        img_list.append(corners.astype(np.float32).reshape(-1, 1, 2))
        used.append(name)
        if truths is not None and "corners" in truths[k]:
            tp = np.asarray(truths[k]["corners"]["distorted_px"])
            corner_err.append(np.linalg.norm(_match_order(corners, tp) - tp, axis=1))
    if len(used) < 3:
        raise InputError(f"calibration: the board was found in only {len(used)} of {len(views)} images "
                         f"(need >= 3); check the pattern size {tuple(pattern_size)}")
    h, w = shape
    rms, K, dist, per_view = solve_points(obj_list, img_list, (w, h), flags)
    cerr = {}
    if corner_err:
        e = np.concatenate(corner_err)
        cerr = {"mean": float(e.mean()), "rms": float(np.sqrt(np.mean(e ** 2))), "max": float(e.max())}
    truth = None
    if truths:
        cam = truths[0].get("camera", {})
        truth = {k: cam[k] for k in ("fx_px", "fy_px", "cx_px", "cy_px", "dist_coeffs_opencv") if k in cam}
    return Calibration(K=np.asarray(K, float), dist=np.asarray(dist, float).ravel()[:5], image_size=(w, h),
                       rms_px=float(rms), n_views=len(used), per_view_rms_px=per_view, used=used,
                       rejected=rejected, corner_error_px=cerr, truth=truth)


def calibrate_dataset(out_dir: str | Path, names: list[str] | None = None, progress: bool = False) -> Calibration:
    """Calibrate from every checkerboard image of a rendered dataset (``edgetruth.render.dataset.image`` layout)."""
    ds = open_dataset(out_dir)
    boards = [s for s in ds.checkerboards() if names is None or s.name in set(names)]
    if not boards:
        raise InputError(f"{out_dir}: no checkerboard images to calibrate from; render a spec with a "
                         "kind = \"checkerboard\" group (e.g. `edgetruth render calibration`)")
    views = [(s.name, s.image.astype(np.float64)) for s in boards]
    truths = [s.truth for s in boards]
    board = truths[0]["checkerboard"]

    return calibrate(views, tuple(board["pattern_size"]), float(board["square_m"]), truths,
                     progress=lambda it: console.track(it, desc="calibrate", unit="board", enabled=progress))


def use_bent_board(cal: Calibration, results: list, model: str = "quadratic") -> Calibration:
    """``edgetruth calibrate --board bent|common``: the calibration with the board bent per view, or by one shape
    common to every view (``model`` = "common"; ``cal.board_bend[model]``,
    ``evaluate/board_bend.py``) in place of the flat one: K, distortion, RMS and each photo's RMS (``results``,
    ``PhotoResult``, updated).  Every found photo must have taken part (``board_bend.MIN_CORNERS`` corners)."""
    b = cal.board_bend.get(model)
    if not b or b["views"] != cal.n_views:
        few = [r.photo for r in results if r.found and r.corners < MIN_CORNERS]
        flag = "common" if model == "common" else "bent"
        raise InputError(f"--board {flag}: {', '.join(few) or 'some photos'} measured fewer than {MIN_CORNERS} "
                         f"corners, and the bent fits need {MIN_CORNERS} a photo; leave those photos out or use "
                         "--board flat")
    i = b["intrinsics_bent"]
    K = np.array([[i["fx_px"], 0.0, i["cx_px"]], [0.0, i["fy_px"], i["cy_px"]], [0.0, 0.0, 1.0]])
    for r, v in zip([r for r in results if r.found], b["per_view_rms_bent_px"]):
        r.rms_px = v
    how = ("the board bent the same way in every photo (one quadratic height" if model == "common" else
           f"the board bent per photo ({model} height")
    return replace(cal, K=K, dist=np.asarray(i["dist_coeffs_opencv"], float), rms_px=b["rms_bent_px"],
                   per_view_rms_px=list(b["per_view_rms_bent_px"]),
                   method=cal.method + f", {how}, evaluate/board_bend.py)")


# --- real photographs ----------------------------------------------------------------------------------
def parse_pattern(text: str, option: str = "--pattern") -> tuple[int, int]:
    """``"9x6"`` -> (9, 6): inner corners per row x per column (OpenCV's patternSize).  A circle grid or ChArUco
    pattern (``circles:4x11:asymmetric``; ``edgetruth.evaluate.pattern``) is refused, saying this reads a
    chessboard."""
    if ":" in str(text):
        parse_board_pattern(text, option, kinds=("chessboard",))  # raises: a chessboard pattern has no ':'
    parts = str(text).strip().lower().replace("×", "x").split("x")
    try:
        nx, ny = (int(v) for v in parts)
    except ValueError:
        nx = ny = 0
    if len(parts) != 2 or not (2 <= nx <= 1000 and 2 <= ny <= 1000):
        raise InputError(f"{option} {text!r}: give the board's inner corners as COLSxROWS, e.g. 9x6 "
                         "(corners where four squares meet, each count 2..1000; a 10 x 7-square board is 9x6)")
    return nx, ny


def find_photos(refs) -> list[tuple[str, Path]]:
    """[(name, path)] of the photos that ``refs`` name, in order, each file once.

    A ref is an image file, a folder (every image inside, sorted by name, not recursive), a glob
    pattern (``photos/*.jpg``: the image files it matches, sorted), or the name of a shipped real set (``opencv_left``;
    ``edgetruth.resources.real_set``).  Names are the ref as given (a folder's or a set's files as
    ``FOLDER/FILE``).  Raises ``InputError`` for a ref that names nothing.
    """
    def images_in(folder: Path, label: str) -> list[tuple[str, Path]]:
        files = sorted(f for f in folder.iterdir() if f.suffix.lower() in SUFFIXES and f.is_file())
        if not files:
            raise InputError(f"{label}: no images in this folder ({', '.join(SUFFIXES)}); give photo files")
        return [(f"{label.rstrip('/')}/{f.name}", f) for f in files]

    out, seen = [], set()
    for ref in refs:
        ref = str(ref)
        p = Path(ref)
        if p.is_dir():
            found = images_in(p, ref)
        elif p.exists() or p.is_symlink():
            found = [(ref, check_input_file(p, "photo"))]
        elif any(ch in ref for ch in "*?["):
            found = [(m, Path(m)) for m in sorted(glob.glob(ref))
                     if Path(m).is_file() and Path(m).suffix.lower() in SUFFIXES]
            if not found:
                raise InputError(f"{ref}: no image file matches this pattern ({', '.join(SUFFIXES)}); check the path")
        elif "/" not in ref and ref in shipped_real_set_names():
            found = images_in(real_set(ref), ref)
        else:
            raise InputError(f"{ref}: no such photo, folder or shipped photo set (shipped: "
                             f"{', '.join(shipped_real_set_names()) or 'none'}); check the path")
        for name, path in found:
            key = path.resolve()
            if key not in seen:
                seen.add(key)
                out.append((name, path))
    if not out:
        raise InputError("no photos given; pass image files, folders, globs or a shipped set such as opencv_left")
    return out


@dataclass
class PhotoResult:
    """What became of one photo in ``calibrate_photos``."""

    photo: str
    found: bool
    corners: int
    rms_px: float | None = None  # its reprojection RMS under the calibration (found boards only)
    subpix_window_px: int | None = None  # cornerSubPix half-window used
    subpix_narrowed: int | None = None  # corners that took the narrower window (``detect_corners``)

    def to_dict(self) -> dict:
        return {"photo": self.photo, "found": self.found, "corners": self.corners, "rms_px": self.rms_px,
                "subpix_window_px": self.subpix_window_px, "subpix_narrowed": self.subpix_narrowed}


#: ``calibrate_photos(undistort_lines=True)`` stops refitting when no corner moves by more than this (px) ...
STRAIGHTEN_TOL_PX = 1e-4
#: ... or after this many refits.
STRAIGHTEN_MAX_PASSES = 10


def _straighten(grids, obj, obj_list, img_list, size, flags, K, dist) -> tuple[int, float]:
    """Refit every photo's corners with the lens (K, dist) and recalibrate, until no corner moves by more than
    ``STRAIGHTEN_TOL_PX`` (``calibrate_photos``); ``obj_list`` and ``img_list`` are updated in place.  -> (passes,
    the largest distance (px) a corner moved from the photo-frame fit)."""
    first = [np.asarray(i, float).reshape(-1, 2).copy() for i in img_list]
    passes = 0
    for passes in range(1, STRAIGHTEN_MAX_PASSES + 1):
        step = 0.0
        for v, grid in enumerate(grids):
            c = grid.corners((K, dist))
            ok = np.all(np.isfinite(c), axis=1)
            old = np.asarray(img_list[v], float).reshape(-1, 2)
            if len(old) == ok.sum():
                step = max(step, float(np.abs(c[ok] - old).max()))
            else:  # the refit measured a different set of corners
                step = np.inf
            obj_list[v], img_list[v] = obj[ok], c[ok].astype(np.float32).reshape(-1, 1, 2)
        if step <= STRAIGHTEN_TOL_PX:
            break
        _, K, dist, _ = solve_points(obj_list, img_list, size, flags)
    moved = max((float(np.abs(np.asarray(i, float).reshape(-1, 2) - f).max()) for i, f in zip(img_list, first)
                 if len(f) == len(np.asarray(i).reshape(-1, 2))), default=0.0)
    return passes, moved


#: Fewest measured corners a photo needs to take part in a calibration (a homography needs 4; some to spare).
MIN_CORNERS_PER_PHOTO = 6


def calibrate_photos(photos: list[tuple[str, Path]], pattern_size: tuple[int, int], square_m: float,
                     model: str = DEFAULT_DIST_MODEL, window_px: int | None = None, channel: str = "luma",
                     progress=None, corner_finder=None, corner_label: str | None = None,
                     undistort_lines: bool = False, points: list | None = None) -> tuple[Calibration, list[PhotoResult]]:
    """Zhang's calibration from real photos of a chessboard: ``photos`` = [(name, path)] (``find_photos``).

    Each photo is read with ``edgetruth.image_io.read_gray(path, channel)``; its corners with
    ``detect_corners(image, pattern_size, window_px)``, or with ``corner_finder(image, pattern_size)`` when given:
    (COLS * ROWS, 2) in OpenCV's order, NaN where it measured none, None when the board is not found (e.g.
    ``edgetruth.evaluate.board.measure.grid_corners.line_corners``); ``corner_label`` then names it in the calibration's
    method line.  ``undistort_lines``: ``corner_finder`` returns a photo's grid (``.corners(lens)``, e.g.
    ``grid_corners.grid_points``) and the corners are refitted with the calibration's own lens, where the grid
    lines are straight, and the camera recalibrated, until no corner moves by ``STRAIGHTEN_TOL_PX``.  ``points``
    (a list, optional) receives per used photo (name, its (m, 2) image points as calibrated, px).  Each photo
    uses its measured corners (at least ``MIN_CORNERS_PER_PHOTO``).  A photo where the board is not found is
    kept in the results (``found = False``) and left out of the fit; fewer than 3 boards, or photos
    of different sizes, raise ``InputError``.  ``square_m`` (metres) scales the board, hence the
    poses only: K and the distortion do not depend on it.
    """
    if model not in DIST_MODELS:
        raise InputError(f"model {model!r}: unknown distortion model; choose one of {', '.join(DIST_MODELS)}")
    if not (np.isfinite(square_m) and square_m > 0):
        raise InputError(f"square side {square_m!r} m: must be a positive number of metres")
    if window_px is not None and int(window_px) < 1:
        raise InputError(f"cornerSubPix window {window_px!r}: must be at least 1 px")
    nx, ny = pattern_size
    obj = object_points(pattern_size, square_m)
    results: list[PhotoResult] = []
    obj_list, img_list, grids, size, first = [], [], [], None, None
    it = photos if progress is None else progress(photos)
    for name, path in it:
        image = read_gray(path, channel)
        h, w = image.shape[:2]
        if size is None:
            size, first = (w, h), name
        elif (w, h) != size:
            raise InputError(f"{name}: {w} x {h} px, but {first} is {size[0]} x {size[1]} px; calibrate photos of "
                             "one camera at one resolution and orientation")
        info: dict = {}
        corners = detect_corners(image, pattern_size, window_px, info) if corner_finder is None else \
            corner_finder(image, pattern_size)
        grid = None
        if undistort_lines and corners is not None:
            grid, corners = corners, corners.corners()
        ok = None if corners is None else np.all(np.isfinite(corners), axis=1)
        if corners is None or ok.sum() < MIN_CORNERS_PER_PHOTO:
            results.append(PhotoResult(name, False, 0))
            continue
        results.append(PhotoResult(name, True, int(ok.sum()), subpix_window_px=info.get("window_px"),
                                   subpix_narrowed=info.get("narrowed")))
        obj_list.append(obj[ok])
        img_list.append(corners[ok].astype(np.float32).reshape(-1, 1, 2))
        grids.append(grid)
    used = [r.photo for r in results if r.found]
    if len(used) < 3:
        missing = ", ".join(r.photo for r in results if not r.found)
        raise InputError(f"the {nx}x{ny} board was found in only {len(used)} of {len(results)} photos (need >= 3; "
                         f"not found: {missing or 'none'}); check --pattern counts the inner corners (COLSxROWS) -- "
                         "a board of separate squares (zhang1998's) has none: run `edgetruth study board` on it")

    flags, words = DIST_MODELS[model]
    residuals: list = []
    poses: list = []
    rms, K, dist, per_view = solve_points(obj_list, img_list, size, flags, residuals, poses)
    straightened = ""
    if undistort_lines:
        passes, moved = _straighten(grids, obj, obj_list, img_list, size, flags, K, dist)
        residuals, poses = [], []
        rms, K, dist, per_view = solve_points(obj_list, img_list, size, flags, residuals, poses)
        straightened = (f", grid lines fitted in the undistorted image (the calibration's own lens, {passes} "
                        f"refits; the corners moved by up to {moved:.3f} px)")
    for r, v in zip([r for r in results if r.found], per_view):
        r.rms_px = v
    if points is not None:
        points.extend((name, np.asarray(i, float).reshape(-1, 2)) for name, i in zip(used, img_list))
    narrowed = sum(r.subpix_narrowed or 0 for r in results if r.found)
    window = (f"0.4 of the smallest imaged square side; {narrowed} corner(s) moved more than {NARROW_SHIFT_PX} px "
              f"with {NARROW_WINDOW_FRACTION} of it and took that" if window_px is None else
              f"half-window {int(window_px)} px")
    corners_used = (corner_label or f"cornerSubPix corners ({window})") + straightened
    cal = Calibration(K=K, dist=dist, image_size=size, rms_px=rms, n_views=len(used), per_view_rms_px=per_view,
                      used=used, rejected=[r.photo for r in results if not r.found],
                      method=f"Zhang (cv2.calibrateCamera, {words}), {corners_used}",
                      residual_structure={**residual_structure([o[:, :2] for o in obj_list], residuals, square_m),
                                          **image_field_transfer(img_list, residuals, size),
                                          **board_point_transfer([o[:, :2] for o in obj_list], residuals, K, dist,
                                                                 [r for r, _ in poses], [t for _, t in poses])},
                      board_bend=bend_check([o[:, :2] for o in obj_list], img_list, K, dist, [r for r, _ in poses],
                                            [t for _, t in poses], free_dist(flags)))
    return cal, results
