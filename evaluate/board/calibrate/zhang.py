"""Zhang calibration of corners, leave-one-image-out reprojection, and side lengths in the board plane.

Model: OpenCV's pinhole camera with radial distortion k1, k2 only (flags
``CALIB_ZERO_TANGENT_DIST | CALIB_FIX_K3``; OpenCV has no skew, i.e. skew 0), as in Zhang's
published result with distortion.  ``cv2.calibrateCamera`` initialises itself from the
planar views (no intrinsic guess).

- **Reprojection RMS**: OpenCV's figure, sqrt(mean squared 2-D residual) over every corner of
  every view; the per-corner residuals (px) are kept for tests and intervals.
- **Leave one image out**: for each image, calibrate on the others, find the held-out image's
  pose with those intrinsics (``solvePnP``, iterative), reproject its corners; the LOO RMS is
  over all held-out corners of all images.
- **Side lengths**: every corner back-projected onto the board plane with the camera and the
  view's pose (undistorted ray, intersected with the plane), side k = |corner k+1 - corner k| in
  board units; its error against the model's side, also converted to px at the side's own image
  scale (image length / model length).

Corners may be missing (NaN): each view uses its finite corners.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from edgetruth.errors import InputError
from edgetruth.evaluate.calibration import undistort_px
from edgetruth.opencv_threads import calibrate_camera


FLAGS = cv2.CALIB_ZERO_TANGENT_DIST | cv2.CALIB_FIX_K3
CRITERIA = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-12)
MIN_VIEWS = 3
MIN_CORNERS_PER_VIEW = 8


@dataclass
class Calibration:
    """K (3x3), dist (k1, k2), rms_px (OpenCV's), poses (rvec, tvec per view), residual_px (per view: (S, 4)
    residual length, NaN where the corner is missing)."""

    K: np.ndarray
    k1: float
    k2: float
    rms_px: float
    rvecs: list
    tvecs: list
    residual_px: list = field(default_factory=list)

    @property
    def dist(self) -> np.ndarray:
        return np.array([self.k1, self.k2, 0.0, 0.0, 0.0])

    def intrinsics(self) -> dict:
        return {"fx": float(self.K[0, 0]), "fy": float(self.K[1, 1]), "cx": float(self.K[0, 2]),
                "cy": float(self.K[1, 2]), "k1": self.k1, "k2": self.k2}

    def to_dict(self) -> dict:
        return {"intrinsics": self.intrinsics(), "K": self.K.tolist(), "rms_px": self.rms_px,
                "rvecs": [np.ravel(r).tolist() for r in self.rvecs],
                "tvecs": [np.ravel(t).tolist() for t in self.tvecs]}


def _views(object_corners: np.ndarray, image_corners: list[np.ndarray]):
    """Per view: (mask of finite corners (S, 4), object points (n, 3), image points (n, 2)), float32 as
    OpenCV's calibrateCamera requires (a rounding of ~3e-5 px at 600 px)."""
    out = []
    for c in image_corners:
        ok = np.all(np.isfinite(c), axis=2)
        obj = np.c_[object_corners[ok], np.zeros(int(ok.sum()))].astype(np.float32)
        out.append((ok, obj, c[ok].astype(np.float32)))
    return out


def calibrate(object_corners: np.ndarray, image_corners: list[np.ndarray], image_size: tuple[int, int]) -> Calibration:
    """Calibrate from per-view corners ``image_corners[i]`` (S, 4, 2) of the model ``object_corners`` (S, 4, 2).
    ``image_size`` = (width, height)."""
    views = _views(object_corners, image_corners)
    if len(views) < 2 or any(len(v[1]) < MIN_CORNERS_PER_VIEW for v in views):
        raise InputError(f"calibration: need at least 2 views with {MIN_CORNERS_PER_VIEW} corners each, got "
                         f"{[len(v[1]) for v in views]}")
    rms, K, dist, rvecs, tvecs = calibrate_camera([v[1] for v in views], [v[2] for v in views], image_size,
                                                  None, None, flags=FLAGS, criteria=CRITERIA)
    cal = Calibration(K, float(dist.ravel()[0]), float(dist.ravel()[1]), float(rms), list(rvecs), list(tvecs))
    for (ok, obj, img), r, t in zip(views, rvecs, tvecs):
        proj, _ = cv2.projectPoints(obj, r, t, K, cal.dist)
        res = np.full(ok.shape, np.nan)
        res[ok] = np.linalg.norm(proj[:, 0] - img, axis=1)
        cal.residual_px.append(res)
    return cal


def leave_one_out(object_corners: np.ndarray, image_corners: list[np.ndarray], image_size) -> dict:
    """Held-out reprojection: {'rms_px': over all held-out corners, 'per_view_rms_px': [...],
    'residual_px': [(S, 4) per view], 'intrinsics': [per fold]}."""
    n = len(image_corners)
    if n < MIN_VIEWS:
        raise InputError(f"leave-one-out: need at least {MIN_VIEWS} views, got {n}")
    residuals, per_view, folds = [], [], []
    for i in range(n):
        cal = calibrate(object_corners, [c for j, c in enumerate(image_corners) if j != i], image_size)
        ok, obj, img = _views(object_corners, [image_corners[i]])[0]
        good, rvec, tvec = cv2.solvePnP(obj, img, cal.K, cal.dist, flags=cv2.SOLVEPNP_ITERATIVE)
        res = np.full(ok.shape, np.nan)
        if good:
            proj, _ = cv2.projectPoints(obj, rvec, tvec, cal.K, cal.dist)
            res[ok] = np.linalg.norm(proj[:, 0] - img, axis=1)
        residuals.append(res)
        per_view.append(_rms(res))
        folds.append(cal.intrinsics())
    return {"rms_px": _rms(np.concatenate([r.ravel() for r in residuals])), "per_view_rms_px": per_view,
            "residual_px": residuals, "intrinsics": folds}


def _rms(v) -> float:
    v = np.asarray(v, float)
    v = v[np.isfinite(v)]
    return float(np.sqrt(np.mean(v * v))) if v.size else float("nan")


def board_points(cal: Calibration, view: int, image_pts: np.ndarray) -> np.ndarray:
    """Image points (..., 2) of ``view`` back-projected onto its board plane: (..., 2) board coordinates."""
    shape = image_pts.shape
    p = image_pts.reshape(-1, 2).astype(np.float64)
    out = np.full(p.shape, np.nan)
    ok = np.all(np.isfinite(p), axis=1)
    if not ok.any():
        return out.reshape(shape)

    und = undistort_px(p[ok], cal.K, cal.dist, normalised=True)
    rays = np.c_[und, np.ones(len(und))]
    R, _ = cv2.Rodrigues(np.asarray(cal.rvecs[view], np.float64))
    t = np.asarray(cal.tvecs[view], np.float64).ravel()
    normal = R[:, 2]
    lam = (normal @ t) / (rays @ normal)
    X = (lam[:, None] * rays - t) @ R  # R^T (lam ray - t)
    out[ok] = X[:, :2]
    return out.reshape(shape)


def side_lengths(cal: Calibration, object_corners: np.ndarray, image_corners: list[np.ndarray]) -> dict:
    """Per view (S, 4) arrays: 'length' measured in the board plane (board units), 'error' (measured - model,
    board units), 'error_px' (the error at the side's image scale)."""
    model_len = np.linalg.norm(np.roll(object_corners, -1, axis=1) - object_corners, axis=2)
    out = {"length": [], "error": [], "error_px": []}
    for i, c in enumerate(image_corners):
        b = board_points(cal, i, c)
        length = np.linalg.norm(np.roll(b, -1, axis=1) - b, axis=2)
        img_len = np.linalg.norm(np.roll(c, -1, axis=1) - c, axis=2)
        err = length - model_len
        out["length"].append(length)
        out["error"].append(err)
        out["error_px"].append(err * img_len / model_len)
    return out
