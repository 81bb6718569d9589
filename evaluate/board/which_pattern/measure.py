"""Each cell of a "which pattern?" dataset calibrated with each of its pattern's detectors, against the exact truth.

A cell is one design cell (one pattern at one focus and light, on every pose slot).  Its detectors:

- chessboard: ``subpix`` (OpenCV's findChessboardCorners + cornerSubPix) and ``lines`` (the corners where the grid
  lines of the edge method's points meet, fitted in the undistorted image: ``measure.grid_corners``);
- circle grid: ``blobs`` (cv2.findCirclesGrid's centroids), ``conic`` (the centres of ellipses fitted to the edge
  method's points) and ``corrected`` (the images of the circles' centres from those ellipses: ``board.circles``);
- ChArUco: ``subpix`` (cv2.aruco.CharucoDetector's corners) and ``lines`` (``board.charuco``).

Per (cell, detector): the calibration's fx, fy (% of the truth), cx, cy (px) and distortion-field errors, its
reprojection RMS, and each used view's image points against the true points (the nearest true point: a detected
point is far closer to its own than to a neighbour), px.  For circle grids, per circle: the measured centre's
offset from the true centre image and the closed-form perspective bias (the truth's ``bias_undistorted_px``).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from edgetruth.errors import InputError
from edgetruth.evaluate import method_order as mo
from edgetruth.evaluate.board import charuco as ch
from edgetruth.evaluate.board.circles import calibrate_circles
from edgetruth.evaluate.board.measure.grid_corners import grid_points
from edgetruth.evaluate.calibration import calibrate_photos, undistort_px
from edgetruth.evaluate.pattern import parse_board_pattern

#: the edge method of every edge-based detector (the board commands' default: ``grid_corners.DEFAULT_METHOD``)
EDGE_METHOD = "erf4p_fixed11"
#: detectors per board kind, the reference (OpenCV's own) first
DETECTORS = {"checkerboard": ("subpix", "lines"), "circles_grid": ("blobs", "conic", "corrected"),
             "charuco": ("subpix", "lines")}
PATTERN_NAMES = {"checkerboard": "chessboard", "circles_grid": "circle grid", "charuco": "ChArUco"}
#: the distortion field is compared on this grid of pixel centres (columns x rows over the image)
FIELD_GRID = (33, 27)


@dataclass
class Cell:
    """One design cell: its name (the dataset's group), board kind, factor levels and views (dataset samples)."""

    name: str
    kind: str
    levels: dict
    views: list = field(default_factory=list)


def cells_of(dataset) -> list[Cell]:
    """The board cells of a rendered dataset, in the spec's order."""
    cells: dict[str, Cell] = {}
    for s in dataset:
        if s.kind not in DETECTORS:
            continue
        c = cells.get(s.group)
        if c is None:
            levels = (s.truth.get("design") or {}).get("levels") or {"cell": s.group}
            c = cells[s.group] = Cell(s.group, s.kind, dict(levels))
        c.views.append(s)
    return list(cells.values())


def true_points(truth: dict, kind: str) -> np.ndarray:
    """(n, 2) the true image points (distorted px) of a board view: inner corners or circle centres."""
    if kind == "checkerboard":
        return np.asarray(truth["corners"]["distorted_px"], float)
    if kind == "circles_grid":
        return np.asarray(truth["circles"]["centre_distorted_px"], float)
    return np.asarray(truth["charuco"]["corners"]["distorted_px"], float)


def point_errors_px(points: np.ndarray, truth_px: np.ndarray) -> np.ndarray:
    """Distance (px) of each finite measured point to the nearest true point."""
    p = np.asarray(points, float).reshape(-1, 2)
    p = p[np.all(np.isfinite(p), axis=1)]
    if not len(p):
        return np.zeros(0)
    d, _ = cKDTree(truth_px).query(p)
    return d


def distortion_field_error_px(K, dist, K_true, dist_true, size_wh) -> dict:
    """How far the calibrated lens's distortion field lies from the true one over the image: at each grid pixel
    p, d(p) = p - K undistort(p) with each model's own K, and the RMS and max of |d_cal - d_true| (px)."""
    w, h = size_wh
    gx, gy = np.meshgrid(np.linspace(0, w - 1, FIELD_GRID[0]), np.linspace(0, h - 1, FIELD_GRID[1]))
    p = np.column_stack([gx.ravel(), gy.ravel()])
    d_cal = p - undistort_px(p, np.asarray(K, float), np.asarray(dist, float))
    d_true = p - undistort_px(p, np.asarray(K_true, float), np.asarray(dist_true, float))
    e = np.linalg.norm(d_cal - d_true, axis=1)
    return {"rms": float(np.sqrt(np.mean(e ** 2))), "max": float(e.max())}


def _board_pattern(cell: Cell):
    t = cell.views[0].truth
    if cell.kind == "checkerboard":
        b = t["checkerboard"]
        return tuple(b["pattern_size"]), float(b["square_m"])
    if cell.kind == "circles_grid":
        c = t["circles"]
        text = f"circles:{c['cols']}x{c['rows']}" + (":asymmetric" if c["asymmetric"] else "")
        return parse_board_pattern(text, kinds=("circles",)), float(c["spacing_m"])
    c = t["charuco"]
    pattern = parse_board_pattern(f"charuco:{c['cols']}x{c['rows']}:{c['dictionary']}", kinds=("charuco",))
    return ch.board_of(pattern, float(c["square_m"]), float(c["marker_m"])), float(c["square_m"])


def _calibrate(cell: Cell, detector: str, method: str):
    """-> (Calibration, {view name: (m, 2) image points as calibrated})."""
    board, square_m = _board_pattern(cell)
    if cell.kind == "circles_grid":
        views = [(s.name, s.image.astype(np.float64)) for s in cell.views]
        centres = detector if detector == "blobs" else f"{detector}:{method}"
        cal, results, info = calibrate_circles(views, board, square_m, centres=centres)
        used = [r.photo for r in results if r.found]
        return cal, dict(zip(used, info["image_points"]))
    photos = [(s.name, s.dataset.path / f"{s.name}.png") for s in cell.views]
    finder, undistort, label, pattern = None, False, None, board
    if cell.kind == "charuco":
        finder, label, undistort = ch.corner_finder(board, "subpix" if detector == "subpix" else f"lines:{method}")
        pattern = (board.cols - 1, board.rows - 1)
    elif detector == "lines":
        m, options = mo.resolve(method, mo.study_options())
        finder, undistort = (lambda photo, size: grid_points(photo, size, m, **options)), True
        label = f"corners where the grid lines of {method}'s points meet"
    pts: list = []
    cal, _ = calibrate_photos(photos, pattern, square_m, corner_finder=finder, corner_label=label,
                              undistort_lines=undistort, points=pts)
    return cal, dict(pts)


def tilt_deg(truth: dict) -> float:
    """The angle (deg) between the board's normal and the optical axis."""
    R = np.asarray(truth["pose"]["R_cam_from_board"], float)
    return float(np.degrees(np.arccos(np.clip(abs(R[2, 2]), 0.0, 1.0))))


def failed_row(cell: Cell, detector: str, method: str, why: str) -> dict:
    """The row of a (cell, detector) that could not calibrate (the board found in fewer than 3 views): NaN
    figures and the reason, so the report lists it as measured."""
    nan = float("nan")
    return {"cell": cell.name, "pattern": PATTERN_NAMES[cell.kind], "kind": cell.kind, "levels": cell.levels,
            "detector": detector, "method": None if detector in ("subpix", "blobs") else method, "n_views": 0,
            "of_views": len(cell.views), "n_points": 0, "reprojection_rms_px": nan, "fx_pct": nan, "fy_pct": nan,
            "cx_px": nan, "cy_px": nan, "max_focal_error_pct": nan, "distortion_field_px": {"rms": nan, "max": nan},
            "point_rms_px": nan, "per_view": {}, "circles": [], "failed": why}


def measure_cell(cell: Cell, detector: str, method: str = EDGE_METHOD) -> dict:
    """One (cell, detector): the calibration against the truth, per view its points' errors, and (circle grids)
    per circle its offset beside the closed-form bias; ``failed_row`` when it cannot calibrate."""
    try:
        cal, points = _calibrate(cell, detector, method)
    except InputError as exc:
        return failed_row(cell, detector, method, str(exc))
    cam = cell.views[0].truth["camera"]
    K_true, dist_true = np.asarray(cam["K"], float), np.asarray(cam["dist_coeffs_opencv"], float)
    per_view, circles = {}, []
    for s in cell.views:
        if s.name not in points:
            continue
        truth_px = true_points(s.truth, cell.kind)
        e = point_errors_px(points[s.name], truth_px)
        per_view[s.name] = {"slot": s.truth["design"]["slot"], "points": int(e.size),
                            "rms_px": float(np.sqrt(np.mean(e ** 2))) if e.size else float("nan"),
                            "tilt_deg": tilt_deg(s.truth), "distance_m": float(s.truth["true_distance_m"])}
        if cell.kind == "circles_grid":
            p = np.asarray(points[s.name], float)
            p = p[np.all(np.isfinite(p), axis=1)]
            off, idx = cKDTree(truth_px).query(p)  # each measured centre beside its own circle's truth
            closed = np.linalg.norm(np.asarray(s.truth["circles"]["bias_undistorted_px"], float), axis=1)[idx]
            circles += [{"view": s.name, "tilt_deg": per_view[s.name]["tilt_deg"], "offset_px": float(o),
                         "closed_form_bias_px": float(c)} for o, c in zip(off, closed)]
    t = cell.views[0].truth
    w, h = int(cam["width_px"]), int(cam["height_px"])
    err = {"fx_pct": 100.0 * (cal.fx / cam["fx_px"] - 1.0), "fy_pct": 100.0 * (cal.fy / cam["fy_px"] - 1.0),
           "cx_px": cal.cx - cam["cx_px"], "cy_px": cal.cy - cam["cy_px"]}
    rms = [v["rms_px"] for v in per_view.values()]
    return {"cell": cell.name, "pattern": PATTERN_NAMES[cell.kind], "kind": cell.kind, "levels": cell.levels,
            "detector": detector, "method": None if detector in ("subpix", "blobs") else method,
            "n_views": cal.n_views, "of_views": len(cell.views), "n_points": int(sum(v["points"] for v in
                                                                                  per_view.values())),
            "reprojection_rms_px": cal.rms_px, **err,
            "max_focal_error_pct": max(abs(err["fx_pct"]), abs(err["fy_pct"])),
            "distortion_field_px": distortion_field_error_px(cal.K, cal.dist, K_true, dist_true, (w, h)),
            "point_rms_px": float(np.sqrt(np.nanmean(np.square(rms)))) if rms else float("nan"),
            "per_view": per_view, "circles": circles, "K": cal.K.tolist(), "dist": cal.dist.tolist(),
            "focus_distance_m": float(t["camera"]["focus_distance_m"])}
