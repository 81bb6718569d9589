"""Circle grids in photos: OpenCV's blob centroids (the reference) and edgetruth's ellipse centres, plain and
corrected for perspective, and Zhang's calibration from either (``edgetruth calibrate --pattern circles:...``).

- **blobs**: ``cv2.findCirclesGrid`` (its default ``SimpleBlobDetector``: dark blobs) on the photo as 8 bits,
  the centroids it returns, in its order (OpenCV's object points: ``object_points``).
- **conic**: each circle's edge, an edge method's points on the Canny candidates within ``BAND_PX`` of the circle
  as the blob calibration predicts it, undistorted with the calibration's lens, fitted by an ellipse
  (``evaluate.conic.fit_ellipse``); its centre, distorted back, is the circle's image point.  Under perspective
  that centre is not the image of the circle's centre (``render.scene.circle_conic``): it moves by up to
  ~r²/f px.
- **corrected**: the image of the circle's centre from the same ellipse and the board plane's orientation, the
  pole of the plane's vanishing line (``evaluate.conic.centre_image``; exact for a circle on that plane).

The lens and the poses the points are undistorted and corrected with are the calibration's own: each round
refits the ellipses with the last round's lens and pose and recalibrates, until no centre moves by ``TOL_PX``
(at most ``MAX_ROUNDS``).  The edge points are measured once.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from edgetruth import locate
from edgetruth.errors import InputError
from edgetruth.evaluate.board_bend import bend_check
from edgetruth.evaluate.calibration import (DEFAULT_DIST_MODEL, DIST_MODELS, Calibration, PhotoResult, distort_px,
                                            free_dist, solve_points, undistort_px)
from edgetruth.evaluate.conic import algebraic_residual_px, centre_image, fit_ellipse
from edgetruth.evaluate.residual_field import board_point_transfer, image_field_transfer, residual_structure
from edgetruth.render.edge_truth import closed_polyline_signed_distance
from edgetruth.render.scene.circle_conic import conic_centre

#: the edge method unless told otherwise (as the chessboard's grid lines: ``grid_corners.DEFAULT_METHOD``)
DEFAULT_METHOD = "erf4p_fixed11"
CENTRE_KINDS = ("blobs", "conic", "corrected")
#: candidates this close (px) to the predicted outline are refined
BAND_PX = 2.5
#: edge points farther than this (px) from the first ellipse are dropped before the refit
OUTLIER_PX = 0.5
#: angles sampled on each predicted outline
OUTLINE_SAMPLES = 96
MAX_ROUNDS = 8
TOL_PX = 1e-4


def object_points(pattern_size: tuple[int, int], spacing_m: float, asymmetric: bool) -> np.ndarray:
    """(n, 3) float32 OpenCV's object points: circle (row i, column j) at (j s, i s), or asymmetric
    ((2 j + i % 2) s, i s) (OpenCV's calibration sample), row-major."""
    cols, rows = pattern_size
    i, j = np.divmod(np.arange(cols * rows), cols)
    x = (2 * j + i % 2) if asymmetric else j
    return np.column_stack([x * spacing_m, i * spacing_m, np.zeros(cols * rows)]).astype(np.float32)


def as_8bit(image: np.ndarray, full_scale: float | None = None) -> np.ndarray:
    """The photo as OpenCV's detectors take it: an 8-bit photo (``full_scale`` 255, or uint8) as it is (its gray
    rounded), any other its 99.5th percentile at 255 (a render's white lies well below its file's full scale)."""
    img = np.asarray(image)
    if img.dtype == np.uint8:
        return img
    if full_scale == 255:
        return np.clip(np.rint(img), 0, 255).astype(np.uint8)
    f = img.astype(np.float64)
    top = float(np.percentile(f, 99.5)) or 1.0
    return np.clip(np.rint(f / top * 255.0), 0, 255).astype(np.uint8)


def find_blobs(image: np.ndarray, pattern_size: tuple[int, int], asymmetric: bool, full_scale: float | None = None):
    """(centroids (n, 2) in OpenCV's order, diameters (n,) px of the blobs at them) or None when
    ``cv2.findCirclesGrid`` does not find the grid."""

    g8 = as_8bit(image, full_scale)
    flags = cv2.CALIB_CB_ASYMMETRIC_GRID if asymmetric else cv2.CALIB_CB_SYMMETRIC_GRID
    ok, centres = cv2.findCirclesGrid(g8, tuple(int(v) for v in pattern_size), flags=flags)
    if not ok:
        return None
    c = centres.reshape(-1, 2).astype(np.float64)
    kp = cv2.SimpleBlobDetector_create(cv2.SimpleBlobDetector_Params()).detect(g8)
    pts = np.array([k.pt for k in kp]).reshape(-1, 2)
    size = np.array([k.size for k in kp])
    near = np.argmin(np.linalg.norm(pts[None] - c[:, None], axis=2), axis=1) if len(pts) else None
    return c, (size[near] if near is not None else np.full(len(c), np.nan))


@dataclass
class CircleEdges:
    """One photo's edge points on its circles: ``x``, ``y`` (px, the photo) and ``label`` (the circle, OpenCV's
    order) of the method's converged points; ``blobs`` the reference centroids."""

    blobs: np.ndarray
    x: np.ndarray
    y: np.ndarray
    label: np.ndarray
    #: the candidates within ``BAND_PX`` of an outline, refined or not
    n_candidates: int = 0

    def _fits(self, K, dist):
        """Per circle (its points undistorted with (K, dist), the ellipse or None, the mask of the points it was
        refitted to): fitted, the points beyond ``OUTLIER_PX`` of it dropped, refitted."""
        p = undistort_px(np.column_stack([self.x, self.y]), K, dist)
        out = []
        for k in range(len(self.blobs)):
            sel = p[self.label == k]
            q = fit_ellipse(sel[:, 0], sel[:, 1])
            keep = np.zeros(len(sel), bool)
            if q is not None:
                keep = np.abs(algebraic_residual_px(q, sel[:, 0], sel[:, 1])) <= OUTLIER_PX
                q = fit_ellipse(sel[keep, 0], sel[keep, 1])
            out.append((sel, q, keep))
        return out

    def conics(self, K, dist) -> list:
        """Per circle the ellipse (3, 3; undistorted px) of its points undistorted with (K, dist), or None: fitted,
        the points beyond ``OUTLIER_PX`` of it dropped, refitted."""
        return [q for _, q, _ in self._fits(K, dist)]

    def ellipse_residuals(self, K, dist) -> dict:
        """Per circle, how far its points (undistorted with (K, dist)) lie from their own ellipse (``conics``):
        {'rms_px': (n,) RMS first-order geometric distance over the points the ellipse was refitted to, NaN
        without an ellipse; 'n_fit': (n,) those points; 'n_points': (n,) the circle's points}."""
        rms, n_fit, n_all = [], [], []
        for sel, q, keep in self._fits(K, dist):
            n_all.append(len(sel))
            n_fit.append(int(keep.sum()) if q is not None else 0)
            if q is None or not keep.any():
                rms.append(np.nan)
                continue
            d = algebraic_residual_px(q, sel[keep, 0], sel[keep, 1])
            rms.append(float(np.sqrt(np.mean(d * d))))
        return {"rms_px": np.array(rms), "n_fit": np.array(n_fit), "n_points": np.array(n_all)}


def predicted_outlines(obj: np.ndarray, radius_m: float, rvec, tvec, K, dist) -> np.ndarray:
    """(n, OUTLINE_SAMPLES, 2) each circle of ``radius_m`` around the object points, projected (distorted)."""

    a = 2.0 * np.pi * np.arange(OUTLINE_SAMPLES) / OUTLINE_SAMPLES
    ring = np.column_stack([radius_m * np.cos(a), radius_m * np.sin(a), np.zeros_like(a)])
    pts = (np.asarray(obj, np.float64)[:, None] + ring[None]).reshape(-1, 3)
    img, _ = cv2.projectPoints(pts, np.asarray(rvec, np.float64), np.asarray(tvec, np.float64), K, dist)
    return img.reshape(len(obj), OUTLINE_SAMPLES, 2)


def circle_edges(image: np.ndarray, blobs: np.ndarray, outlines: np.ndarray, method: str = DEFAULT_METHOD,
                 cand=None, **options) -> CircleEdges:
    """The method's points on the Canny candidates within ``BAND_PX`` of each predicted outline (n, m, 2);
    ``cand``: the photo's ``locate.candidates``, when already found (else found here)."""
    img = np.asarray(image, np.float64)
    cand = locate.candidates(img) if cand is None else cand
    label = np.full(len(cand), -1)
    for k, poly in enumerate(outlines):
        lo, hi = poly.min(axis=0) - BAND_PX - 1, poly.max(axis=0) + BAND_PX + 1
        box = np.flatnonzero((cand.x >= lo[0]) & (cand.x <= hi[0]) & (cand.y >= lo[1]) & (cand.y <= hi[1]))
        if len(box):
            d = np.abs(closed_polyline_signed_distance(poly, cand.x[box], cand.y[box]))
            label[box[d <= BAND_PX]] = k
    sel = np.flatnonzero(label >= 0)
    pts = locate.refine(img, cand.subset(sel), method, **options)
    x, y = np.asarray(pts.x, np.float64), np.asarray(pts.y, np.float64)
    ok = np.asarray(pts.converged, bool) & np.isfinite(x) & np.isfinite(y)
    return CircleEdges(blobs, x[ok], y[ok], label[sel][ok], len(sel))


def image_points(edges: CircleEdges, kind: str, K, dist, rvec=None) -> np.ndarray:
    """(n, 2) the circles' image points (px, the photo; NaN where a circle has no ellipse) of ``kind``: 'conic'
    (the ellipse's centre) or 'corrected' (the image of the circle's centre for the board plane of ``rvec``)."""


    qs = edges.conics(K, dist)
    out = np.full((len(qs), 2), np.nan)
    ok = np.array([q is not None for q in qs])
    if not ok.any():
        return out
    q = np.stack([qs[k] for k in np.flatnonzero(ok)])
    if kind == "conic":
        und = conic_centre(q)
    else:
        normal = cv2.Rodrigues(np.asarray(rvec, np.float64))[0][:, 2]
        und = centre_image(q, K, normal)
    out[ok] = distort_px(und, K, dist)
    return out


def parse_centres(text: str) -> tuple[str, str]:
    """``--centres``: 'blobs', 'conic[:METHOD]' or 'corrected[:METHOD]' -> (kind, method)."""
    kind, _, method = str(text).strip().partition(":")
    if kind not in CENTRE_KINDS or (kind == "blobs" and method):
        raise InputError(f"--centres {text!r}: give 'blobs' (OpenCV's findCirclesGrid centroids), 'conic[:METHOD]' "
                         "(an edge method's ellipse centres) or 'corrected[:METHOD]' (those corrected for "
                         f"perspective), METHOD an edge method (default {DEFAULT_METHOD})")
    return kind, method or DEFAULT_METHOD


@dataclass
class Grids:
    """``find_grids``' answer: per view its ``PhotoResult`` (found or not); for the views where the grid is found,
    in order, their names, images and ``find_blobs`` answers; the views' size (w, h)."""

    results: list
    names: list
    images: list
    found: list
    size: tuple


def find_grids(views, pattern, full_scales=None, progress=None) -> Grids:
    """``find_blobs`` on every view of ``views`` = [(name, image)] (``full_scales``: per view its file's full
    scale, ``as_8bit``), all of one size (else one InputError line); ``pattern`` a circles ``BoardPattern``."""
    results, names, images, found, size, first = [], [], [], [], None, None
    scales = list(full_scales) if full_scales is not None else [None] * len(views)
    for (name, image), scale in zip(views if progress is None else progress(views), scales):
        h, w = np.shape(image)[:2]
        if size is None:
            size, first = (w, h), name
        elif (w, h) != size:
            raise InputError(f"{name}: {w} x {h} px, but {first} is {size[0]} x {size[1]} px; calibrate photos of "
                             "one camera at one resolution and orientation")
        b = find_blobs(image, pattern.size, pattern.asymmetric, scale)
        results.append(PhotoResult(name, b is not None, 0 if b is None else len(b[0])))
        if b is not None:
            names.append(name)
            images.append(image)
            found.append(b)
    return Grids(results, names, images, found, size)


def blob_radius_m(found: list, poses: list, obj: np.ndarray, K) -> float:
    """The circles' radius on the board (object units) from the blobs' diameters (``find_blobs``) at the depths of
    the blob calibration's ``poses``: their median."""
    r_m = []
    for (c, dia), (rv, tv) in zip(found, poses):
        R = cv2.Rodrigues(rv)[0]
        z = (obj.astype(np.float64) @ R.T + tv)[:, 2]
        r_m.append(0.5 * dia * z / K[0, 0])
    return float(np.nanmedian(np.concatenate(r_m)))


@dataclass
class CentreFit:
    """``fit_centres``' answer: per view (n, 2) image points (NaN where a circle has no ellipse) and the mask of
    the finite ones, the last calibration (rms_px, K, dist (5,), per-view RMS, poses) and the rounds it took."""

    points: list
    ok: list
    rms_px: float
    K: np.ndarray
    dist: np.ndarray
    per_view: list
    poses: list
    rounds: int
    moved_px: float


def fit_centres(edges: list, kind: str, obj: np.ndarray, size, flags: int, K, dist, poses, start: list) -> CentreFit:
    """The circles' image points of ``kind`` ('conic' or 'corrected', ``image_points``) from each view's ``edges``,
    refitted with each round's lens and poses and recalibrated (``solve_points`` under ``flags``) until no point
    moves by ``TOL_PX`` (at most ``MAX_ROUNDS``), starting from the lens ``K``, ``dist``, ``poses`` and points
    ``start`` (per view (n, 2)) of an earlier calibration."""
    pts, moved, rms, per_view, ok, rnd = start, np.inf, float("nan"), [], [], 0
    for rnd in range(1, MAX_ROUNDS + 1):
        new = [image_points(e, kind, K, dist, rv) for e, (rv, _) in zip(edges, poses)]
        moved = max(float(np.nanmax(np.linalg.norm(a - b, axis=1))) for a, b in zip(new, pts))
        pts = new
        ok = [np.all(np.isfinite(p), axis=1) for p in pts]
        poses = []
        rms, K, dist, per_view = solve_points([obj[m] for m in ok], [p[m].astype(np.float32).reshape(-1, 1, 2)
                                                                     for p, m in zip(pts, ok)], size, flags, None,
                                              poses)
        if moved < TOL_PX:
            break
    return CentreFit(pts, ok, rms, K, dist, per_view, poses, rnd, moved)


def calibrate_circles(views, pattern, spacing_m: float, centres: str = "blobs", model: str | None = None,
                      progress=None, full_scales=None):
    """Zhang's calibration from circle-grid ``views`` = [(name, image)] (``full_scales``: per view its file's full
    scale, ``as_8bit``; None: renders): ``pattern`` a circles ``BoardPattern``,
    ``spacing_m`` OpenCV's squareSize, ``centres`` as ``parse_centres``.  -> (Calibration, [PhotoResult],
    info {rounds, moved_px, radius_m, centres, method, image_points: per used view (n, 2)})."""
    kind, method = parse_centres(centres)
    if kind != "blobs":
        locate.get_method(method)
    model = model or DEFAULT_DIST_MODEL
    if model not in DIST_MODELS:
        raise InputError(f"model {model!r}: unknown distortion model; choose one of {', '.join(DIST_MODELS)}")
    flags, words = DIST_MODELS[model]
    obj = object_points(pattern.size, spacing_m, pattern.asymmetric)
    grids = find_grids(views, pattern, full_scales, progress)
    results, images, found, size, used = grids.results, grids.images, grids.found, grids.size, grids.names
    if len(used) < 3:
        raise InputError(f"the {pattern.text} grid was found in only {len(used)} of {len(results)} photos (need >= 3); "
                         "check --pattern (COLS circles per row, ROWS rows; asymmetric or not)")
    obj_list = [obj] * len(found)
    pts = [b[0] for b in found]
    poses: list = []
    rms, K, dist, per_view = solve_points(obj_list, [p.astype(np.float32).reshape(-1, 1, 2) for p in pts], size,
                                          flags, None, poses)
    info = {"centres": kind, "method": None if kind == "blobs" else method, "rounds": 0, "moved_px": None,
            "blob_rms_px": rms}
    if kind != "blobs":
        radius_m = blob_radius_m(found, poses, obj, K)
        info["radius_m"] = radius_m
        edges = [circle_edges(img, c, predicted_outlines(obj, radius_m, rv, tv, K, dist), method)
                 for img, (c, _), (rv, tv) in zip(images, found, poses)]
        fit = fit_centres(edges, kind, obj, size, flags, K, dist, poses, pts)
        pts, ok, rms, K, dist, per_view = fit.points, fit.ok, fit.rms_px, fit.K, fit.dist, fit.per_view
        obj_list = [obj[m] for m in ok]
        info["rounds"], info["moved_px"] = fit.rounds, fit.moved_px
        for r, m in zip([r for r in results if r.found], ok):
            r.corners = int(m.sum())
    residuals: list = []
    final_poses: list = []
    img_list = [p[np.all(np.isfinite(p), axis=1)].astype(np.float32).reshape(-1, 1, 2) for p in pts]
    solve_points(obj_list, img_list, size, flags, residuals, final_poses)
    for r, v in zip([r for r in results if r.found], per_view):
        r.rms_px = v
    how = {"blobs": "cv2.findCirclesGrid's blob centroids",
           "conic": f"the centres of ellipses fitted to {method}'s points on each circle (undistorted)",
           "corrected": f"the images of the circles' centres from ellipses fitted to {method}'s points (undistorted) "
                        "and the board plane's vanishing line (evaluate.conic.centre_image)"}[kind]
    rounds = f", {info['rounds']} rounds with the calibration's own lens and poses" if kind != "blobs" else ""
    cal = Calibration(K=K, dist=dist, image_size=size, rms_px=rms, n_views=len(used), per_view_rms_px=per_view,
                      used=used, rejected=[r.photo for r in results if not r.found],
                      method=f"Zhang (cv2.calibrateCamera, {words}), {how}{rounds} (edgetruth.evaluate.board.circles)",
                      residual_structure={**residual_structure([o[:, :2] for o in obj_list], residuals, spacing_m),
                                          **image_field_transfer(img_list, residuals, size),
                                          **board_point_transfer([o[:, :2] for o in obj_list], residuals, K, dist,
                                                                 [r for r, _ in final_poses],
                                                                 [t for _, t in final_poses])},
                      board_bend=bend_check([o[:, :2] for o in obj_list], img_list, K, dist,
                                            [r for r, _ in final_poses], [t for _, t in final_poses],
                                            free_dist(flags)))
    info["image_points"] = pts
    return cal, results, info
