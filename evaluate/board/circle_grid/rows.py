"""The circle-grid study's rows: the grids found once per photo, then per row its circle centres, calibration and
leave-one-image-out reprojection.

- ``setup_grids``: ``circles.find_grids`` on every photo (those without the grid are skipped, with why), the blob
  calibration, the circles' radius, each circle's predicted outline and the photo's Canny candidates: shared by
  every row;
- the reference row (``REFERENCE_ROW``): OpenCV's blob centroids, calibrated as plain OpenCV does (flags 0, the
  5-term lens);
- a method row (``method_row``): the method's points on the candidates near each outline (``circles.circle_edges``)
  -> ellipses -> the images of the circles' centres (``corrected``), iterated with the calibration's own lens and
  poses (``circles.fit_centres``); its ellipse residuals with the row's final lens (``CircleEdges
  .ellipse_residuals``);
- ``calibrate_row``: the calibration's per-circle residuals and the leave-one-image-out residuals of the row's
  centres (held fixed: each fold recalibrates on the other photos, ``solvePnP`` finds the held-out pose).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import cv2
import numpy as np

from edgetruth import console, locate
from edgetruth.errors import InputError
from edgetruth.evaluate.board import circles as C
from edgetruth.evaluate.calibration import DEFAULT_DIST_MODEL, DIST_MODELS, solve_points

#: the reference row: OpenCV's own circle centres
REFERENCE_ROW = "opencv_blobs"
REFERENCE_LABEL = "OpenCV's blob centroids (findCirclesGrid)"
#: OpenCV's default lens (k1, k2, p1, p2, k3; calibrateCamera flags 0), as plain OpenCV and ``calibrate`` fit it
DIST_MODEL = DEFAULT_DIST_MODEL
#: the centres a method row measures (``circles.CENTRE_KINDS``)
CENTRES = "corrected"
#: Leave-one-image-out calibrates on the other photos: at least 2 of them
MIN_PHOTOS = 3


@dataclass
class GridSetup:
    """What every row shares (``setup_grids``): the photos where the grid is found (names, images, their blob
    centroids (n, 2)), the others as (name, why), the object points (n, 3), the blob calibration (K, dist,
    poses), the circles' radius (object units), per photo the predicted outlines and the Canny candidates."""

    names: list
    images: list
    blobs: list
    skipped: list
    obj: np.ndarray
    size: tuple
    K: np.ndarray
    dist: np.ndarray
    poses: list
    radius: float
    outlines: list
    cands: list
    blobs_seen: dict


@dataclass
class CircleRow:
    """One row: ``label`` (a method label, or ``REFERENCE_ROW``), ``points`` per photo (n, 2) circle image points
    (NaN where a circle has none); for a method row its ``edges`` (``circles.CircleEdges``) and ``ellipse`` per photo
    (``CircleEdges.ellipse_residuals``), the candidates it refined and the rounds of the centres' fit; after
    ``calibrate_row`` the calibration ``cal`` and ``loo``, or ``failure``."""

    label: str
    points: list
    edges: list | None = None
    ellipse: list | None = None
    converged: int = 0
    candidates: int = 0
    refine_s: float = 0.0
    rounds: int = 0
    moved_px: float = float("nan")
    cal: dict | None = None
    loo: dict | None = None
    failure: str | None = None

    @property
    def is_method(self) -> bool:
        """Whether the row is an edge method's (not the reference's)."""
        return self.edges is not None


def _flags() -> int:
    return DIST_MODELS[DIST_MODEL][0]


def blobs_in(image, full_scale) -> int:
    """How many dark blobs OpenCV's default ``SimpleBlobDetector`` sees in the photo (``circles.as_8bit``)."""
    g8 = C.as_8bit(image, full_scale)
    return len(cv2.SimpleBlobDetector_create(cv2.SimpleBlobDetector_Params()).detect(g8))


def setup_grids(names: list, images: list, scales: list, board, progress: bool = True) -> GridSetup:
    """The grids on every photo and what every row shares (module docstring); one InputError line when the grid is
    found on fewer than ``MIN_PHOTOS`` photos.  ``board``: an ``inputs.CircleBoard``."""
    pattern = board.pattern
    grids = C.find_grids(list(zip(names, images)), pattern, scales)
    n = pattern.cols * pattern.rows
    seen, skipped = {}, []
    for r, img, s in zip(grids.results, images, scales):
        if not r.found:
            seen[r.photo] = blobs_in(img, s)
            skipped.append((r.photo, f"cv2.findCirclesGrid did not find the {pattern.text} grid (its blob detector "
                                     f"sees {seen[r.photo]} dark blobs; the grid has {n})"))
    if len(grids.names) < MIN_PHOTOS:
        raise InputError(f"board study: the {pattern.text} grid was found on {len(grids.names)} of {len(names)} "
                         f"photo(s) ({', '.join(grids.names) or 'none'}); need {MIN_PHOTOS}: check --pattern (COLS "
                         "circles per row, ROWS rows; asymmetric or not) or give more photos of the whole grid")
    obj = C.object_points(pattern.size, board.spacing, pattern.asymmetric).astype(np.float64)
    blobs = [b[0] for b in grids.found]
    poses: list = []
    _, K, dist, _ = solve_points([obj.astype(np.float32)] * len(blobs),
                                 [b.astype(np.float32).reshape(-1, 1, 2) for b in blobs], grids.size, _flags(), None,
                                 poses)
    radius = C.blob_radius_m(grids.found, poses, obj, K)
    outlines = [C.predicted_outlines(obj, radius, rv, tv, K, dist) for rv, tv in poses]
    cands = [locate.candidates(np.asarray(img, np.float64))
             for img in console.track(grids.images, desc="candidates", unit="photo", enabled=progress)]
    return GridSetup(grids.names, grids.images, blobs, skipped, obj, grids.size, K, dist, poses, radius, outlines,
                     cands, seen)


def reference_row(setup: GridSetup) -> CircleRow:
    """OpenCV's blob centroids as a row."""
    return CircleRow(REFERENCE_ROW, [np.asarray(b, np.float64) for b in setup.blobs])


def method_row(label: str, method: str, options: dict, setup: GridSetup) -> CircleRow:
    """The method's corrected circle centres on every photo (module docstring); a row whose centres cannot
    calibrate gets ``failure``."""
    t0 = time.perf_counter()
    edges = [C.circle_edges(img, b, o, method, cand=c, **options)
             for img, b, o, c in zip(setup.images, setup.blobs, setup.outlines, setup.cands)]
    row = CircleRow(label, [np.full_like(b, np.nan) for b in setup.blobs], edges=edges,
                    converged=sum(len(e.x) for e in edges), candidates=sum(e.n_candidates for e in edges),
                    refine_s=time.perf_counter() - t0)
    try:
        fit = C.fit_centres(edges, CENTRES, setup.obj.astype(np.float32), setup.size, _flags(), setup.K, setup.dist,
                            setup.poses, setup.blobs)
    except (cv2.error, ValueError) as exc:
        row.failure = f"the centres did not calibrate ({str(exc).strip().splitlines()[-1][:120]})"
        return row
    row.points, row.rounds, row.moved_px = fit.points, fit.rounds, fit.moved_px
    return row


def _calibrate(obj: np.ndarray, points: list, size, flags: int) -> dict:
    """Calibrate on ``points`` (per photo (n, 2), NaN rows left out): {'rms_px', 'K', 'dist', 'poses',
    'per_view_rms_px', 'residual_px': per photo (n,) residual lengths, NaN where missing}."""
    ok = [np.all(np.isfinite(p), axis=1) for p in points]
    residuals, poses = [], []
    rms, K, dist, per_view = solve_points([obj[m].astype(np.float32) for m in ok],
                                          [p[m].astype(np.float32).reshape(-1, 1, 2) for p, m in zip(points, ok)],
                                          size, flags, residuals, poses)
    res = []
    for m, r in zip(ok, residuals):
        v = np.full(len(m), np.nan)
        v[m] = np.linalg.norm(r, axis=1)
        res.append(v)
    return {"rms_px": rms, "K": K, "dist": dist, "poses": poses, "per_view_rms_px": per_view, "residual_px": res}


def intrinsics(K, dist) -> dict:
    """{'fx', 'fy', 'cx', 'cy', 'k1', 'k2', 'p1', 'p2', 'k3'} of a calibration."""
    d = np.asarray(dist, float).ravel()
    return {"fx": float(K[0, 0]), "fy": float(K[1, 1]), "cx": float(K[0, 2]), "cy": float(K[1, 2]),
            "k1": float(d[0]), "k2": float(d[1]), "p1": float(d[2]), "p2": float(d[3]), "k3": float(d[4])}


def leave_one_out(obj: np.ndarray, points: list, size, flags: int) -> dict:
    """Each photo's centres reprojected with the lens calibrated on the other photos and the pose ``solvePnP``
    finds: {'rms_px', 'per_view_rms_px', 'residual_px': per photo (n,), 'intrinsics': per fold}."""
    residuals, per_view, folds = [], [], []
    for i, p in enumerate(points):
        fold = _calibrate(obj, [q for j, q in enumerate(points) if j != i], size, flags)
        m = np.all(np.isfinite(p), axis=1)
        res = np.full(len(p), np.nan)
        good, rvec, tvec = cv2.solvePnP(obj[m].astype(np.float32), p[m].astype(np.float32), fold["K"],
                                        fold["dist"], flags=cv2.SOLVEPNP_ITERATIVE)
        if good:
            proj, _ = cv2.projectPoints(obj[m].astype(np.float32), rvec, tvec, fold["K"], fold["dist"])
            res[m] = np.linalg.norm(proj.reshape(-1, 2) - p[m], axis=1)
        residuals.append(res)
        per_view.append(_rms(res))
        folds.append(intrinsics(fold["K"], fold["dist"]))
    return {"rms_px": _rms(np.concatenate(residuals)), "per_view_rms_px": per_view, "residual_px": residuals,
            "intrinsics": folds}


def _rms(v) -> float:
    v = np.asarray(v, float)
    v = v[np.isfinite(v)]
    return float(np.sqrt(np.mean(v * v))) if v.size else float("nan")


def calibrate_row(row: CircleRow, setup: GridSetup) -> CircleRow:
    """Fill ``row.cal`` and ``row.loo`` (and a method row's ``ellipse`` with the row's own lens); a row whose
    centres cannot calibrate gets ``failure``."""
    if row.failure is not None:
        return row
    try:
        row.cal = _calibrate(setup.obj, row.points, setup.size, _flags())
        row.loo = leave_one_out(setup.obj, row.points, setup.size, _flags())
    except (cv2.error, ValueError) as exc:
        row.cal = row.loo = None
        row.failure = f"the centres did not calibrate ({str(exc).strip().splitlines()[-1][:120]})"
        return row
    if row.is_method:
        row.ellipse = [e.ellipse_residuals(row.cal["K"], row.cal["dist"]) for e in row.edges]
    return row
