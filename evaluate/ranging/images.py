"""The ranging study (seed §4.4): calibrated camera -> undistort -> find target -> every method -> Z.

Per target image:

1. undistort with the *calibrated* model (``edgetruth.evaluate.ranging.undistort``);
2. find the target and its boundary candidates from the image (``edgetruth.evaluate.target``);
3. refine the *same* candidates with every method (``edgetruth.locate.refine``);
4. size: square -> robust side lines, l = left/right distance (the seed's l, with fx);
   circle -> robust circle fit, l = diameter (``edgetruth.evaluate.ranging.size``);
   rectangle (real photos, ``edgetruth.evaluate.ranging.photos``) -> as a square, l = its width;
5. Z = fx * S / l with the calibrated fx and S = the target's physical size (13 cm).

What the experimenter knows and the pipeline uses: the target's shape and physical size
(``target.shape``, ``target.size_m`` in the image's JSON, like the seed's "13 cm square").
What it does *not* use: the true intrinsics, distortion, pose or outline - those only
score the result: e = Z_hat - Z_true with Z_true the target centre's depth
(``true_distance_m``), and ``model_floor_cm``, the error the same ranging model makes
with the *true* outline and the *true* fx (tilt and perspective alone).
"""
from __future__ import annotations

import csv
import io
import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from edgetruth import console, locate
from edgetruth.errors import InputError
from edgetruth.evaluate.design import interval_label
from edgetruth.evaluate.method_order import resolve
from edgetruth.evaluate.ranging.pose import pose_distance
from edgetruth.evaluate.ranging.size import Line, _line_gap, circle_taubin, distance_from_size, fit_circle, fit_square
from edgetruth.evaluate.ranging.undistort import from_calibration, from_truth
from edgetruth.evaluate.target import is_scene, target_candidates
from edgetruth.fileio import atomic_write_text
from edgetruth.locate import plugins
from edgetruth.render.dataset.reader import open_dataset
from edgetruth.render.optics.optical_edge import OpticalOutline, outward_normals
from edgetruth.render.scene.ground_truth import image_outline


@dataclass
class ImageResult:
    """Everything measured on one image (one row per method in ``rows``)."""

    name: str
    rows: list[dict]
    n_candidates: int = 0
    n_boundary: int = 0
    region: dict = field(default_factory=dict)
    points: dict = field(default_factory=dict)  # method -> (x, y) in image coords (for figures)
    crop: tuple = ()
    error: str = ""
    scores: object = None  # the per-point study's scores of the raw image (range_image's score; None: not scored)
    record: dict = field(default_factory=dict)  # the image's design fields (for the per-point tables)
    fits: dict = field(default_factory=dict)  # keep_points: method -> its size fit's geometry (overlays)


#: the target shapes ranging knows: l is the side (square), the width (rectangle), the diameter (circle)
SHAPES = ("square", "rectangle", "circle")


def rectangle_height_m(gt: dict) -> float:
    """A rendered rectangle target's height (m; its ``size_m`` is the width), from the JSON's shape 0."""
    return float(gt["shapes"][0]["height_m"])


def ranging_scope(gt: dict) -> str:
    """Why a rendered target image is not ranged ("" where it is): ranging sizes one target of a shape it models
    (``SHAPES``); an own scene of several outlines, or another shape, is scored per point only."""
    if is_scene(image_outline(gt)):
        return "a scene of several outlines (ranging sizes one target); scored per point"
    shape = gt["target"]["shape"]
    if shape not in SHAPES:
        article = "an" if shape[:1] in "aeiou" else "a"
        return f"{article} {shape} (ranging sizes a {', a '.join(SHAPES[:-1])} or a {SHAPES[-1]}); scored per point"
    return ""


def rectangle_pose_distance(corners_px, K, width_m: float, height_m: float) -> float:
    """Z (m) of the centre of a ``width_m`` x ``height_m`` rectangle from its image corners (4, 2):
    top-left, top-right, bottom-right, bottom-left (undistorted px); ``cv2.solvePnP`` with IPPE."""
    c = np.asarray(corners_px, np.float64).reshape(4, 2)
    if not np.all(np.isfinite(c)):
        raise InputError("rectangle pose: corners are not finite")
    w, h = width_m / 2.0, height_m / 2.0
    obj = np.array([[-w, h, 0.0], [w, h, 0.0], [w, -h, 0.0], [-w, -h, 0.0]])
    ok, _, tvec = cv2.solvePnP(obj, c, np.asarray(K, np.float64), None, flags=cv2.SOLVEPNP_IPPE)
    if not ok:
        raise InputError("rectangle pose: solvePnP found no pose")
    return float(tvec[2, 0])


def size_of(shape: str, x, y, nx, ny, fx: float, fy: float, cy: float, K=None, size_m: float | None = None,
            height_m: float | None = None) -> dict:
    """Image size l (pixels, in fx units) of the target from refined points; with ``K`` and ``size_m``
    also the pose-based distance ``z_pose_m`` (``edgetruth.evaluate.ranging.pose``).

    A rectangle is fitted like a square; l is its width (the left/right side-line distance), so
    ``size_m`` is its horizontal side.  With ``height_m`` its pose is PnP on the four corners, and a
    rectangle whose measured width/height is closer to height_m/size_m than to size_m/height_m
    (turned by 90 degrees) is refused; without it there is no pose distance."""
    if shape in ("square", "rectangle"):
        fit = fit_square(x, y, nx, ny)
        out = {"size_px": fit.width_px, "size_tb_px": fit.height_px * fx / fy, "size_seed_px": fit.width_seed_px,
               "n_used": int(fit.used.sum()),
               "fit_rms_px": float(np.nanmean([ln.rms_px for ln in fit.lines.values()]))}
        pose_args = {"corners_px": fit.corners}
        if shape == "rectangle":
            if height_m is not None and size_m is not None:
                seen, told = np.log(out["size_px"] / out["size_tb_px"]), np.log(size_m / height_m)
                if abs(seen + told) < abs(seen - told):
                    raise InputError(f"rectangle measures width/height {np.exp(seen):.2f} but size_m/height_m is "
                                     f"{np.exp(told):.2f}: it is turned by 90 degrees; swap size_m and height_m")
                if K is not None:
                    try:
                        out["z_pose_m"] = rectangle_pose_distance(fit.corners, K, size_m, height_m)
                    except InputError:
                        out["z_pose_m"] = float("nan")
            else:
                out["z_pose_m"] = float("nan")
            return out
    else:
        fit = fit_circle(x, y, aspect=fx / fy, cy_px=cy)
        out = {"size_px": fit.diameter_px, "size_tb_px": float("nan"), "size_seed_px": float("nan"),
               "n_used": int(fit.used.sum()), "fit_rms_px": fit.rms_px}
        pose_args = {"x": np.asarray(x)[fit.used], "y": np.asarray(y)[fit.used]}
    if K is not None and size_m is not None:
        try:
            out["z_pose_m"] = pose_distance(shape, size_m, K, **pose_args)
        except InputError:
            out["z_pose_m"] = float("nan")
    return out


def fit_geometry(shape: str, x, y, nx, ny, fx: float, fy: float, cy: float) -> dict:
    """What the size step fitted, for pictures: a square's or rectangle's side lines (n, d: n . p = d) and
    corners, or a circle's centre and radius (px of the image the points are in)."""
    if shape in ("square", "rectangle"):
        fit = fit_square(x, y, nx, ny)
        return {"lines": {k: (ln.n.tolist(), float(ln.d)) for k, ln in fit.lines.items()},
                "corners": fit.corners.tolist(), "l_px": fit.width_px}
    fit = fit_circle(x, y, aspect=fx / fy, cy_px=cy)
    return {"circle": (fit.cx, fit.cy, fit.r), "l_px": fit.diameter_px}


def outline_pose_distance(gt: dict, points_px, K) -> float:
    """The pose-based estimate from the truth's outline points (undistorted px: a square's four corners, a
    circle's polyline) with the intrinsic matrix ``K``."""
    pts = np.asarray(points_px, float)
    K = np.asarray(K, float)
    size_m = float(gt["target"]["size_m"])
    if gt["target"]["shape"] == "square":
        return pose_distance("square", size_m, K, corners_px=pts[:4])
    if gt["target"]["shape"] == "rectangle":
        return rectangle_pose_distance(pts[:4], K, size_m, rectangle_height_m(gt))
    return pose_distance("circle", size_m, K, x=pts[:, 0], y=pts[:, 1])


def true_pose_distance(gt: dict) -> float:
    """The pose-based estimate on the TRUE undistorted outline with the true K (its model floor)."""
    return outline_pose_distance(gt, gt["outline"]["undistorted_px"], gt["camera"]["K"])


def calibrated_pose_distance(gt: dict, undistorter, K) -> float:
    """The pose-based estimate on the TRUE outline seen through the CALIBRATED camera: its distorted
    image undistorted with the calibrated model, then the pose with the calibrated ``K``.  Its error is
    the calibration's share of every method's pose error (true intrinsics give ``true_pose_distance``)."""
    pts = undistorter.undistort_points(np.asarray(gt["outline"]["distorted_px"], float))
    return outline_pose_distance(gt, pts, K)


def polyline_pose_distance(shape: str, size_m: float, points_px, undistorter, K) -> float:
    """The pose-based estimate from a dense closed outline polyline of the raw (distorted) image, through
    the ranging's own size fits: undistorted with ``undistorter``'s model, the pose with ``K``."""
    u = undistorter.undistort_points(np.asarray(points_px, float))
    n = outward_normals(u, np.roll(u, -1, axis=0) - np.roll(u, 1, axis=0))
    K = np.asarray(K, float)
    return size_of(shape, u[:, 0], u[:, 1], n[:, 0], n[:, 1], K[0, 0], K[1, 1], K[1, 2], K=K,
                   size_m=size_m).get("z_pose_m", float("nan"))


def optics_pose_distance(gt: dict) -> float:
    """The pose-based estimate on the OPTICAL edge (the outline moved by the displacement the lens makes,
    ``outline.optical_edge``, its centroid) through the true camera: its error is the optics' share of
    every method's pose error.  NaN without an optical edge in the truth."""
    if not gt.get("outline", {}).get("optical_edge") or "polyline_distorted_px" not in gt["outline"]:
        return float("nan")
    poly = OpticalOutline.from_ground_truth(gt).polyline("centroid")
    return polyline_pose_distance(gt["target"]["shape"], float(gt["target"]["size_m"]), poly, from_truth(gt),
                                  gt["camera"]["K"])


def undistorted_points(x, y, nx, ny, undistorter):
    """Refined points of the raw image -> (x, y, nx, ny) undistorted, the non-finite ones dropped.  The
    normals stay as refined: undistortion is locally a near-identity linear map, so they still tell the
    sides apart for the size fits."""
    x, y, nx, ny = (np.asarray(a, float) for a in (x, y, nx, ny))
    ok = np.isfinite(x) & np.isfinite(y)
    u = undistorter.undistort_points(np.column_stack([x[ok], y[ok]]))
    return u[:, 0], u[:, 1], nx[ok], ny[ok]


def raw_pose_distance(shape: str, size_m: float, x, y, nx, ny, undistorter, K) -> float:
    """The pose-based estimate from points refined on the RAW image: the points undistorted (not the
    image resampled), then the ranging's size fits and pose.  Beside the ranging's own estimate (points
    refined on the undistorted image) it isolates what the image's resampling does to a method."""
    K = np.asarray(K, float)
    return size_of(shape, *undistorted_points(x, y, nx, ny, undistorter), K[0, 0], K[1, 1], K[1, 2], K=K,
                   size_m=size_m).get("z_pose_m", float("nan"))


def true_size_px(gt: dict) -> float:
    """The ranging model's l evaluated on the TRUE undistorted outline (truth, for the model floor)."""
    pts = np.asarray(gt["outline"]["undistorted_px"])
    if gt["target"]["shape"] in ("square", "rectangle"):  # l: the left and right sides' gap (a rectangle's width)
        tl, tr, br, bl = pts

        def through(a, b):
            t = (b - a) / np.linalg.norm(b - a)
            n = np.array([-t[1], t[0]])
            return Line(n, float(n @ a), np.ones(2, bool), 0.0)

        return _line_gap(through(tl, bl), np.array([tl, bl]), through(tr, br), np.array([tr, br]))
    return 2.0 * circle_taubin(pts[:, 0], pts[:, 1])[2]


def design_fields(gt: dict) -> dict:
    """Row fields of a paired design cell: its pose slot, its levels (``f1=L1;f2=L2``) and the factors
    it moves off the base cell (``off_base``; empty for the base cell)."""
    d = gt.get("design")
    if not d:
        return {"slot": "", "levels": "", "off_base": ""}
    lv, base = d.get("levels") or {}, d.get("base_levels") or {}
    return {"slot": d["slot"], "levels": ";".join(f"{k}={v}" for k, v in lv.items()),
            "off_base": ",".join(k for k, v in lv.items() if base.get(k) != v)}


def process_image(image: np.ndarray, gt: dict, cal, undistorter, methods: list[str], keep_points: bool = False,
                  name: str = "image", options: dict | None = None, undistort: str = "image") -> ImageResult:
    """Run steps 1-5 on one image; ``gt`` supplies only the target's shape/size (and the scoring truth).
    ``undistort``: "image" (remap it, then refine) or "points" (refine the raw image, undistort the points)."""
    shape = gt["target"]["shape"]
    size_m = float(gt["target"]["size_m"])
    z_true = float(gt["true_distance_m"])
    base = {"image": name, "spec": gt.get("spec", ""), "group": gt.get("group", ""),
            "target": gt["target"]["id"], "shape": shape, "true_distance_m": z_true,
            "interval": interval_label(100 * z_true), **design_fields(gt)}
    outside = ranging_scope(gt)
    if outside:  # rows that say so; the per-point scoring still runs (no ``error``)
        return ImageResult(name, [dict(base, method=m, status=f"not ranged: {outside}", z_hat_m=float("nan"),
                                       error_cm=float("nan"), rel_error_pct=float("nan")) for m in methods])
    floor_l = true_size_px(gt)
    height_m = rectangle_height_m(gt) if shape == "rectangle" else None  # the rectangle's pose
    f_true = float(gt["camera"]["fx_px"])
    base["model_floor_cm"] = 100.0 * (distance_from_size(f_true, size_m, floor_l) - z_true)
    base["pose_floor_cm"] = 100.0 * (true_pose_distance(gt) - z_true)
    try:
        base["pose_cal_floor_cm"] = 100.0 * (calibrated_pose_distance(gt, undistorter, cal.K) - z_true)
    except InputError:
        base["pose_cal_floor_cm"] = float("nan")
    try:
        base["pose_optics_floor_cm"] = 100.0 * (optics_pose_distance(gt) - z_true)
    except InputError:
        base["pose_optics_floor_cm"] = float("nan")
    if check_undistort(undistort) == "points":
        return range_undistorted(image, None, shape, size_m, z_true, cal, methods, base, keep_points=keep_points,
                                 name=name, options=options, l_true_px=floor_l, points_undistorter=undistorter,
                                 height_m=height_m)
    return range_undistorted(undistorter(image), undistorter.valid_mask(), shape, size_m, z_true, cal, methods, base,
                             keep_points=keep_points, name=name, options=options, l_true_px=floor_l, height_m=height_m)


def range_undistorted(und: np.ndarray, valid, shape: str, size_m: float, z_ref_m: float, cal, methods: list[str],
                      base: dict, keep_points: bool = False, name: str = "image", options: dict | None = None,
                      l_true_px: float = float("nan"), polarity: str = "dark",
                      height_m: float | None = None, points_undistorter=None,
                      finder: dict | None = None) -> ImageResult:
    """Steps 2-5 on an undistorted image: find the target (``polarity``: see target_finding), refine
    its boundary with every method, size it and range it; errors against ``z_ref_m`` (the truth of a
    render, or a photo's reference distance), size errors against ``l_true_px`` when it is known.
    ``base``: the fields every row of this image starts from.  With ``points_undistorter`` the image is
    the RAW one (``valid`` None): every method refines it, and its points are undistorted before the size
    and pose fits (``Undistorter.undistort_points``), so no resampling touches the pixels.  With ``finder``
    (the priors of a photo's CSV row: shape, aspect, polarity, roi, point) the declared-target finder
    (``target_finder.find_region``) finds the target instead of the render's dark-region finder."""
    fx, fy, cy = cal.fx, cal.fy, cal.cy
    try:
        region = None
        if finder is not None:
            from edgetruth.evaluate.ranging.target_finder import find_region  # lazy: optional

            region = find_region(und, valid, K=cal.K, **finder)
        tc = target_candidates(und, valid, polarity=polarity, region=region)
    except InputError as exc:
        return ImageResult(name, [dict(base, method=m, status=f"no target: {exc}", z_hat_m=float("nan"),
                                       error_cm=float("nan"), rel_error_pct=float("nan")) for m in methods],
                           error=str(exc))
    x0, y0 = tc.offset
    res = ImageResult(name, [], len(tc.all_candidates), len(tc.candidates),
                      {"bbox": list(tc.region.bbox), "solidity": tc.region.solidity,
                       "shape_guess": tc.region.shape_guess, "interior_ratio": tc.region.interior_ratio,
                       "polarity": tc.region.polarity, "contrast": tc.region.score,
                       **({"contrast_by_polarity": tc.region.scores} if tc.region.scores else {}),
                       **({"finder": tc.region.finder} if tc.region.finder else {})},
                      crop=(x0, y0, tc.crop.shape[1], tc.crop.shape[0]))
    if keep_points:
        res.points["_canny_all"] = (tc.all_candidates.x + x0, tc.all_candidates.y + y0)
        res.points["_canny_kept"] = (tc.candidates.x + x0, tc.candidates.y + y0)
        res.points["_image"] = tc.crop
    for m in methods:
        row = dict(base, method=m, n_points=len(tc.candidates))
        try:
            mid, kw = resolve(m, options)
            pts = locate.refine(tc.crop, tc.candidates, mid, **kw)
            x, y, nx, ny = pts.x + x0, pts.y + y0, pts.nx, pts.ny
            if points_undistorter is not None:
                x, y, nx, ny = undistorted_points(x, y, nx, ny, points_undistorter)
            s = size_of(shape, x, y, nx, ny, fx, fy, cy, K=cal.K, size_m=size_m, height_m=height_m)
            z = distance_from_size(fx, size_m, s["size_px"])
            row.update(s, status="ok", converged_frac=float(np.mean(pts.converged)), time_s=pts.elapsed_s,
                       z_hat_m=z, error_cm=100.0 * (z - z_ref_m), rel_error_pct=100.0 * abs(z - z_ref_m) / z_ref_m,
                       size_error_px=s["size_px"] - l_true_px, error_pose_cm=100.0 * (s["z_pose_m"] - z_ref_m))
            if keep_points:
                res.points[m] = (x, y)
                res.fits[m] = fit_geometry(shape, x, y, nx, ny, fx, fy, cy)
        except InputError as exc:
            row.update(status=f"size failed: {exc}", z_hat_m=float("nan"), error_cm=float("nan"),
                       rel_error_pct=float("nan"))
        res.rows.append(row)
    return res


#: where the ranging undistorts: the image (bilinear remap, then every method refines it: the seed's pipeline)
#: or the points (every method refines the raw image; its points are undistorted, cv2.undistortPoints)
UNDISTORT_MODES = ("image", "points")
#: the report's line for each ``--undistort`` mode
UNDISTORT_LINES = {
    "image": "the image, bilinear remap (edgetruth/evaluate/ranging/undistort.py), then every method refines it: the "
             "seed's pipeline (Table 13c: what the resampling does)",
    "points": "the points: every method refines the raw image, and its points are undistorted (cv2.undistortPoints) "
              "before the size and pose fits",
}


def check_undistort(mode: str) -> str:
    if mode not in UNDISTORT_MODES:
        raise InputError(f"--undistort {mode!r}: choose one of {', '.join(UNDISTORT_MODES)}")
    return mode


ROW_FIELDS = ("dataset", "image", "spec", "group", "slot", "levels", "off_base", "target", "shape", "true_distance_m",
              "interval", "method", "status",
              "z_hat_m", "error_cm", "rel_error_pct", "size_px", "size_tb_px", "size_seed_px", "size_error_px",
              "model_floor_cm", "z_pose_m", "error_pose_cm", "pose_floor_cm", "pose_cal_floor_cm",
              "pose_optics_floor_cm", "error_pose_raw_cm", "n_points", "n_used", "fit_rms_px", "converged_frac",
              "time_s")


def write_rows(path: Path, rows: list[dict]) -> None:
    """``ranging_rows.csv``: one row per (image, method), columns ``ROW_FIELDS`` (docs/formats.md)."""
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=ROW_FIELDS, extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: r.get(k, "") for k in ROW_FIELDS})
    atomic_write_text(path, buf.getvalue())


def read_rows(path: Path) -> list[dict]:
    out = []
    with open(path, newline="") as fh:
        for r in csv.DictReader(fh):
            for k in ("true_distance_m", "z_hat_m", "error_cm", "rel_error_pct", "size_px", "size_tb_px",
                      "size_seed_px", "size_error_px", "model_floor_cm", "z_pose_m", "error_pose_cm", "pose_floor_cm",
                      "pose_cal_floor_cm", "pose_optics_floor_cm", "error_pose_raw_cm", "fit_rms_px", "converged_frac",
                      "time_s"):
                if k in r:
                    r[k] = float(r[k]) if r[k] not in ("", None) else float("nan")
            out.append(r)
    return out


_undistorters: dict = {}


def _undistorter(cal):
    key = (cal.K.tobytes(), cal.dist.tobytes(), tuple(cal.image_size))
    if key not in _undistorters:
        _undistorters[key] = from_calibration(cal)
    return _undistorters[key]


def ranging_methods(labels: list[str], options: dict | None = None) -> list[str]:
    """The labels of ``labels`` that size and range the undistorted image: all but those whose method
    needs the camera's model (``Method.needs_camera``; they are scored per point on the raw image)."""
    return [m for m in labels if not getattr(locate.METHODS.get(resolve(m, options)[0]), "needs_camera", False)]


def range_image(dataset: str, name: str, cal, methods: list[str], keep_points: bool, options: dict,
                score=None, undistort: str = "image"):
    """One task (a pure function of its arguments): range target image ``name`` of ``dataset`` with
    every method and, with ``score`` (the per-point study's ``score_image(image, gt, methods, options,
    radiance=)``, passed by the main job: ranging does not import that study), score every method's points on
    the raw image against the exact outline; None for a checkerboard.  Runs in worker processes."""
    s = open_dataset(dataset)[name]
    gt = s.truth
    if gt.get("kind") != "target":
        return None
    size = (int(gt["camera"]["width_px"]), int(gt["camera"]["height_px"]))
    if size != tuple(cal.image_size):
        raise InputError(f"{dataset}/{name}: image size {size} differs from the calibrated {tuple(cal.image_size)}; "
                         "calibrate with boards from the same camera")
    image = s.image.astype(np.float64)
    # the size and pose rows read the undistorted (resampled) image, where a camera model's edge-spread
    # tables no longer describe the blur: methods that need them (patch_esf_fit) are scored per point only
    r = process_image(image, gt, cal, _undistorter(cal), ranging_methods(methods, options), keep_points,
                      name=name, options=options, undistort=undistort)
    if r.rows:
        r.record = {k: r.rows[0].get(k, "") for k in POINT_RECORD_FIELDS}
    if score is not None and not r.error:
        try:
            r.scores = score(image, gt, methods, options, radiance=s.radiance)
        except InputError as exc:  # the raw image's target finding failed: the image has no points
            r.record["points_error"] = str(exc)
        else:
            add_raw_pose(r, gt, cal, _undistorter(cal))
    return r


def add_raw_pose(r: ImageResult, gt: dict, cal, undistorter) -> None:
    """Each row's ``error_pose_raw_cm``: the pose from the method's points refined on the raw image (the
    scored candidates: on the target's boundary, clear of its corners), undistorted as points.  The
    refined points then leave the result (they are not stored)."""
    pts = r.scores.points
    r.scores.points = {}
    shape, size_m, z = gt["target"]["shape"], float(gt["target"]["size_m"]), float(gt["true_distance_m"])
    if shape not in ("square", "circle"):
        return
    for row in r.rows:
        p = pts.get(row["method"])
        if p is None or row.get("status") != "ok":
            continue
        try:
            row["error_pose_raw_cm"] = 100.0 * (raw_pose_distance(shape, size_m, *p, undistorter, cal.K) - z)
        except InputError:
            row["error_pose_raw_cm"] = float("nan")


#: the per-image fields of ``render_points.npz``'s records
POINT_RECORD_FIELDS = ("image", "spec", "group", "slot", "levels", "off_base", "target", "shape", "true_distance_m",
                       "interval")


def _range_task(i, *args):
    return i, range_image(*args)


def run_ranging(datasets: list[Path], cal, out_dir: Path, methods: list[str] | None = None,
                progress: bool = True, names: dict | None = None, figure_examples: int = 2,
                options: dict | None = None, backend: str = "local", workers: int | None = 1,
                address: str | None = None, score=None, undistort: str = "image") -> dict:
    """Range every target image of ``datasets`` with every method; write ``ranging_rows.csv``
    (``undistort``: ``process_image``).  ``score``: the per-point scorer of each image (``range_image``); its
    scores come back in "point_images" and "point_scores" (the image records and their scores, in order).

    Images are independent tasks on ``backend`` (in-process, local pool or Ray, with the caller's
    plug-in methods shipped to the workers); rows come back in dataset/index order whatever the
    backend.  Returns {"rows": [...], "examples": [ImageResult with points, ...], "per_image": [...], ...}.
    """
    from edgetruth.backends import make_backend  # lazy: the tests patch it on its module

    methods = list(methods or locate.METHODS)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    jobs = []
    for ds in datasets:
        d = open_dataset(ds)
        want = (names or {}).get(str(ds))
        for s in d.targets():
            if want is None or s.name in set(want):
                jobs.append((str(ds), s.name, s.truth["target"]["shape"]))
    # figure examples: the first image of each shape (at most figure_examples)
    keep, shown = set(), set()
    for k, (_, _, shape) in enumerate(jobs):
        if len(keep) < figure_examples and shape not in shown:
            keep.add(k)
            shown.add(shape)
    check_undistort(undistort)
    tasks = [(k, ds, n, cal, methods, k in keep, options or {}, score, undistort)
             for k, (ds, n, _) in enumerate(jobs)]
    results: dict = {}
    t0 = time.perf_counter()
    n_workers = 1 if workers is None else int(workers)
    n_workers = min(n_workers, max(1, len(tasks)))
    init, initargs = plugins.backend_initializer(backend, n_workers, methods)
    with make_backend(backend, n_workers, address, gpu=False, initializer=init, initargs=initargs) as be, \
            console.bar(total=len(tasks), desc="ranging", unit="img", enabled=progress) as bar:
        for k, r in be.map_unordered(_range_task, tasks):
            results[k] = r
            bar.update(1)
    rows, per_image, examples, point_images, point_scores = [], [], [], [], []
    for k in range(len(tasks)):
        r = results[k]
        if r is None:
            continue
        if k in keep and not r.error and "_image" in r.points:  # ranged: its crop and points to show
            examples.append(r)
        rel = os.path.relpath(jobs[k][0], out_dir)
        rows += [dict(row, dataset=rel) for row in r.rows]
        if r.scores is not None:
            point_images.append(dict(r.record, dataset=rel))
            point_scores.append(r.scores)
        per_image.append({"image": r.name, "dataset": jobs[k][0], "n_candidates": r.n_candidates,
                          "n_boundary": r.n_boundary, **r.region, "error": r.error})
    write_rows(out_dir / "ranging_rows.csv", rows)
    (out_dir / "ranging_images.json").write_text(json.dumps(per_image, indent=1))
    return {"rows": rows, "examples": examples, "per_image": per_image, "wall_s": time.perf_counter() - t0,
            "methods": methods, "point_images": point_images, "point_scores": point_scores}
