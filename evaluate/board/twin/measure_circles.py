"""What a twin of circle-grid photos needs, measured on them: ``measure_circles``.

A circle grid (``edgetruth twin PHOTOS --pattern circles:10x8 --square-m 0.025``) has neither a chessboard's
junctions nor a board of squares' side lines, so here:

- **Camera and poses.**  ``circles.calibrate_circles`` with each circle's corrected centre (ERF4P-fixed11's points
  on the circle, an ellipse, the image of its centre: what ``edgetruth calibrate --pattern circles:... --centres
  corrected`` gives), then ``cv2.solvePnP`` per photo on those centres (t in spacings).
- **The circles' size.**  Each circle's fitted ellipse (undistorted, the edges found on the values decoded with
  the tone) has the area π r_px²; r from it at the circle's pose (``circle_radius``), median over circles and
  photos, in spacings.  What a print's dot gain or a method's
  bias on a curved edge makes of the printed size is in it: the twin prints its circles at the size the photos
  show.
- **Levels and noise.**  ``photo_model.region_noise``: the circles' insides (dark, ``flat_margin_px`` clear of the
  outline) and the white between them (as far clear), one region per row of circles, each pixel's SD about its
  region's quadratic (the shading across the board does not count).  Saturation as ``measure_squares``'.
- **Blur.**  Each circle's outline (its radius, the pose and the lens) cut into four arcs whose normals lie within
  ``ARC_HALF_ANGLE_DEG`` of an image axis: the left and right arcs blur along x, the top and bottom ones along y.
  Each arc's pixels within reach of it (its signed distance, > 0 on the white) are fitted by an ERF
  (``photo_model.blur_of_samples``, as a square's side); medians per axis, the pooled ESF's overshoot for the
  sharpening.  JPEG photos: what their JPEG adds to σ, on a synthetic image of the photo's circles through the
  twin's encoder (``jpeg_blur_px``).
- **Lens shading.**  The white ground between neighbouring circles (``measure_squares.gap_points`` of the circles'
  bounding squares) at the points the pose projects them to (``shading.light_levels``).
- **Tone.**  Not measurable without junctions: 8-bit photos take the power given (``tone_power``, as a board of
  separate squares), 16-bit photos are taken as linear; ``note`` says so.

The record has ``measure_squares``' keys (``derive.twin_texts`` reads both), ``board.kind = "circles"``.
"""
from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
from scipy.special import ndtr
from scipy.spatial import cKDTree

from edgetruth.errors import InputError
from edgetruth.evaluate.board.circles import calibrate_circles, circle_edges, object_points, predicted_outlines
from edgetruth.evaluate.board.tone.photo_model import (ESF_HALF_WIDTH_PX, FLAT_MARGIN_PX, MIN_SIDE_PIXELS,
                                                       SideSamples, blur_of_samples, region_noise)
from edgetruth.evaluate.board.twin.measure import edge_shape, jpeg_quality, read_photo
from edgetruth.evaluate.board.twin.measure_squares import assumed_tone, gap_points, white_saturated
from edgetruth.evaluate.board.twin.shading import light_levels, project
from edgetruth.render.edge_truth import closed_polyline_signed_distance
from edgetruth.render.sensor.pipeline import jpeg_round_trip

#: an arc's normals lie within this angle of an image axis (its blur is that axis', mixed with the other's by
#: sin² of the angle: +0.02 px on σ_y for σ_x, σ_y = 0.8, 0.5 px)
ARC_HALF_ANGLE_DEG = 25.0
#: the method whose ellipses give the centres and the circles' size
CENTRE_METHOD = "erf4p_fixed11"


def outline_geometry(outline: np.ndarray) -> tuple[np.ndarray, float]:
    """(centre (2,), mean radius px) of one projected circle's outline (OUTLINE_SAMPLES, 2)."""
    c = outline.mean(axis=0)
    return c, float(np.mean(np.linalg.norm(outline - c, axis=1)))


def flat_regions(shape: tuple[int, int], outlines: np.ndarray, margin_px: float) -> tuple[np.ndarray, np.ndarray]:
    """(dark, white) int32 label images: the nearest circle + 1 (a region each, so that each region's quadratic
    follows the shading over a spacing only), for pixels ``margin_px`` inside a circle's
    outline (dark) or ``margin_px`` clear of every circle within the grid's hull (white); 0 elsewhere."""
    inside = np.zeros(shape, np.uint8)
    for poly in outlines:
        cv2.fillPoly(inside, [np.round(poly * 16).astype(np.int32)], 255, shift=4)
    d_in = cv2.distanceTransform(inside, cv2.DIST_L2, 5)
    d_out = cv2.distanceTransform(255 - inside, cv2.DIST_L2, 5)
    hull = np.zeros(shape, np.uint8)
    cv2.fillPoly(hull, [np.round(cv2.convexHull(outlines.reshape(-1, 2).astype(np.float32)).reshape(-1, 2) * 16)
                        .astype(np.int32)], 1, shift=4)
    centres = outlines.mean(axis=1)
    tree = cKDTree(centres)
    out = []
    for sel in ((inside > 0) & (d_in >= margin_px), (inside == 0) & (d_out >= margin_px) & (hull > 0)):
        lab = np.zeros(shape, np.int32)
        yy, xx = np.nonzero(sel)
        if len(yy):
            lab[yy, xx] = tree.query(np.c_[xx, yy])[1] + 1
        out.append(lab)
    return out[0], out[1]


def arc_samples(image: np.ndarray, outlines: np.ndarray, reach_in_px: np.ndarray,
                reach_out_px: float) -> SideSamples:
    """Four arcs per circle (left, right: orientation 1, blur along x; top, bottom: 0, along y): the pixels within
    ``ARC_HALF_ANGLE_DEG`` of the axis seen from the circle's centre, their signed distance to its outline (> 0
    on the white) from -``reach_in_px`` (per circle) to ``reach_out_px``."""
    img = np.asarray(image, np.float64)
    h, w = img.shape
    cos_lim = math.cos(math.radians(ARC_HALF_ANGLE_DEG))
    ds, vs, ori = [], [], []
    for poly, r_in in zip(outlines, reach_in_px):
        c, r = outline_geometry(poly)
        lo = np.maximum(np.floor(poly.min(0) - reach_out_px - 1).astype(int), 0)
        hi = np.minimum(np.ceil(poly.max(0) + reach_out_px + 1).astype(int), [w - 1, h - 1])
        if np.any(hi <= lo):
            continue
        yy, xx = np.mgrid[lo[1]:hi[1] + 1, lo[0]:hi[0] + 1]
        x, y = xx.ravel().astype(float), yy.ravel().astype(float)
        d = closed_polyline_signed_distance(poly, x, y)
        band = (d >= -r_in) & (d <= reach_out_px)
        u = np.c_[x - c[0], y - c[1]]
        u /= np.maximum(np.linalg.norm(u, axis=1), 1e-9)[:, None]
        for axis, o in ((0, 1), (1, 0)):  # x: vertical arcs (orientation 1); y: horizontal arcs (0)
            for sgn in (-1.0, 1.0):
                sel = band & (sgn * u[:, axis] >= cos_lim)
                if sel.sum() < MIN_SIDE_PIXELS:
                    continue
                ds.append(d[sel])
                vs.append(img[y[sel].astype(int), x[sel].astype(int)])
                ori.append(o)
    return SideSamples(ds, vs, np.asarray(ori, int))


def circle_blur(image: np.ndarray, outlines: np.ndarray) -> dict:
    """``photo_model.blur``'s record for a circle grid's arcs (``arc_samples``), the reach inside a circle at most
    ``ESF_HALF_WIDTH_PX`` and 1 px short of its centre, outside half the gap to the nearest circle."""
    geo = [outline_geometry(p) for p in outlines]
    centres = np.array([c for c, _ in geo])
    radii = np.array([r for _, r in geo])
    gap = np.inf
    if len(centres) > 1:
        nearest = cKDTree(centres).query(centres, k=2)[0][:, 1]
        gap = float(np.median(nearest - 2.0 * radii))
    reach_out = min(ESF_HALF_WIDTH_PX, 0.5 * gap)
    reach_in = np.minimum(ESF_HALF_WIDTH_PX, radii - 1.0)
    return blur_of_samples(arc_samples(image, outlines, reach_in, reach_out))


def synthetic_circles(shape: tuple[int, int], outlines: np.ndarray, sigma_x_px: float, sigma_y_px: float,
                      dark: float, white: float) -> np.ndarray:
    """A noise-free image (stored values) of the circles ``outlines``: ``white`` with each circle at ``dark``, its
    coverage at a pixel centre Φ(−d/σ) (d: the signed distance to its outline, σ: ``sigma_x_px`` and ``sigma_y_px``
    combined along the direction from its centre)."""
    h, w = shape
    cover = np.zeros(shape)
    reach = ESF_HALF_WIDTH_PX + 2.0
    for poly in outlines:
        c, _ = outline_geometry(poly)
        x0, y0 = np.maximum(np.floor(poly.min(0) - reach).astype(int), 0)
        x1, y1 = np.minimum(np.ceil(poly.max(0) + reach).astype(int), [w - 1, h - 1])
        if x1 < x0 or y1 < y0:
            continue
        yy, xx = np.mgrid[y0:y1 + 1, x0:x1 + 1].astype(np.float64)
        d = closed_polyline_signed_distance(poly, xx.ravel(), yy.ravel()).reshape(xx.shape)
        ang = np.arctan2(yy - c[1], xx - c[0])
        sigma = np.hypot(np.cos(ang) * sigma_x_px, np.sin(ang) * sigma_y_px)
        cover[y0:y1 + 1, x0:x1 + 1] += ndtr(-d / sigma)
    return white - (white - dark) * np.clip(cover, 0.0, 1.0)


def jpeg_blur_px(shape, outlines, sigma_x_px: float, sigma_y_px: float, dark: float, white: float,
                 quality: int) -> dict:
    """{"x", "y"}: how much a JPEG at ``quality`` (the twin's encoder) raises the ERF σ ``circle_blur`` reads on the
    ``synthetic_circles`` of these outlines, levels and σ, against the same pixels stored as 8-bit without it."""
    u8 = np.clip(np.round(synthetic_circles(shape, outlines, sigma_x_px, sigma_y_px, dark, white)), 0,
                 255).astype(np.uint8)
    plain = circle_blur(u8.astype(np.float64), outlines)
    coded = circle_blur(jpeg_round_trip(u8, int(quality)).astype(np.float64), outlines)
    return {axis: float(coded[name]["sigma_px"] - plain[name]["sigma_px"])
            for axis, name in (("x", "vertical"), ("y", "horizontal"))}


def ellipse_radius_px(q: np.ndarray) -> float:
    """√(area / π) of the ellipse of the conic ``q`` (3, 3): x^T A x + 2 b^T x + c = 0 is (x − x0)^T A (x − x0) = k,
    k = −det(q) / det(A), whose area is π k / √det(A)."""
    A = q[:2, :2]
    det_a = float(np.linalg.det(A))
    k = -float(np.linalg.det(q)) / det_a
    return math.sqrt(abs(k) / math.sqrt(abs(det_a)))


def circle_radius(edges: list, poses: list, obj: np.ndarray, K, dist) -> float:
    """The circles' radius on the board (object units): each fitted ellipse's ``ellipse_radius_px`` (undistorted)
    at its circle's pose.  A small disc of area A at depth z, its normal n at cos β = |n · v| to the ray v to it,
    v at cos α = v_z to the optical axis, images to the area A f² cos β / (z² cos α) (its solid angle over the
    image plane's), so r = r_px (z / f) √(cos α / cos β), f = √(fx fy); the median over circles and photos."""
    f = math.sqrt(K[0, 0] * K[1, 1])
    r = []
    for e, (rv, tv) in zip(edges, poses):
        R = cv2.Rodrigues(np.asarray(rv, float))[0]
        X = obj @ R.T + np.asarray(tv, float).ravel()
        v = X / np.linalg.norm(X, axis=1)[:, None]
        scale = X[:, 2] / f * np.sqrt(v[:, 2] / np.abs(v @ R[:, 2]))
        for k, q in enumerate(e.conics(K, dist)):
            if q is not None:
                r.append(ellipse_radius_px(q) * scale[k])
    return float(np.median(r)) if r else float("nan")


def measure_circles(photos: list[Path], pattern, tone_power: float = 2.2, channel: str = "luma",
                    progress=None) -> dict:
    """Every measurement a twin of these photos of the circle grid ``pattern`` (a circles ``BoardPattern``) needs
    (module docstring), as JSON-ready data, lengths in grid spacings: ``rms_px``, ``K``, ``dist``, ``tone``, one
    record per photo on which the grid is found; ``left_out`` names the others (fewer than 3 found: an
    ``InputError``).  ``progress``: wraps an iterable of photos in a progress bar."""
    photos = [Path(p) for p in photos]
    views, scale, size, union = [], None, None, 0
    for p in photos if progress is None else progress(photos):
        img, scale, bits = read_photo(p, channel, scale)
        if size is not None and img.shape != size:
            raise InputError(f"{p}: {img.shape[1]}x{img.shape[0]} px among photos of {size[1]}x{size[0]}; give "
                             "photos of one camera at one size")
        size, union = img.shape, union | bits
        views.append((p.name, img))
    cal, results, info = calibrate_circles(views, pattern, 1.0, centres=f"corrected:{CENTRE_METHOD}",
                                           full_scales=[scale] * len(views))
    K, dist = np.asarray(cal.K, float), np.asarray(cal.dist, float).ravel()
    obj = object_points(pattern.size, 1.0, pattern.asymmetric).astype(np.float64)
    by_name = dict(zip([p.name for p in photos], photos))
    images = dict(views)
    used = [r.photo for r in results if r.found]
    left_out = [{"photo": r.photo, "why": f"the {pattern.text} grid was not found on it (cv2.findCirclesGrid)"}
                for r in results if not r.found]
    poses = []
    for name, pts in zip(used, info["image_points"]):
        ok = np.all(np.isfinite(pts), axis=1)
        _, rvec, tvec = cv2.solvePnP(obj[ok], pts[ok], K, dist, flags=cv2.SOLVEPNP_ITERATIVE)
        poses.append((rvec, tvec, ok))
    # the size from edges found again on the values decoded with the tone (8-bit: the power given), so that it is
    # the linear half-way crossing's: on the stored values a tone curve moves every edge towards the dark side by
    # about σ Φ⁻¹(0.5^G), ~0.3 px at G = 2.2 (the centres move alike on every side and stay)
    power = float(tone_power) if scale == 255.0 else 1.0
    blob_r = info["radius_m"]
    edges = [circle_edges(scale * (np.asarray(images[name], np.float64) / scale) ** power, pts,
                          predicted_outlines(obj, blob_r, rv, tv, K, dist), CENTRE_METHOD)
             for name, pts, (rv, tv, _) in zip(used, info["image_points"], poses)]
    radius = circle_radius(edges, [(rv, tv) for rv, tv, _ in poses], obj, K, dist)
    if not (0 < radius < 0.5 * (math.sqrt(2.0) if pattern.asymmetric else 1.0)):
        raise InputError(f"the circles' radius measured {radius:.3g} spacings: not a circle grid of separate circles; "
                         "check --pattern")
    # the white between circles: midway between neighbours, clear of every circle's bounding square
    quads = obj[:, None, :2] + radius * np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float)[None]
    gaps = gap_points(quads)
    rows = []
    for name, (rvec, tvec, ok), pts in zip(used, poses, info["image_points"]):
        p, img = by_name[name], images[name]
        outlines = predicted_outlines(obj, radius, rvec, tvec, K, dist)
        proj, _ = cv2.projectPoints(obj[ok], rvec, tvec, K, dist)
        res = np.linalg.norm(proj.reshape(-1, 2) - pts[ok], axis=1)
        r_px = float(np.median([outline_geometry(o)[1] for o in outlines]))
        margin = min(FLAT_MARGIN_PX, 0.45 * r_px)
        dark_l, white_l = flat_regions(img.shape, outlines, margin)
        dark, white = region_noise(img, dark_l), region_noise(img, white_l)
        if not (dark["mean"] > 0):
            raise InputError(f"{p}: its circles read {dark['mean']:.3g}, so the print's contrast cannot be measured; "
                             "leave it out or give photos whose blacks are not clipped")
        top = float(img.max())
        clip = 255.0 if scale == 255.0 else (top if np.count_nonzero(img == top) >= 10 else None)
        sat = white_saturated(dark, white)
        b = circle_blur(img, outlines)
        sx, sy = (b[k]["sigma_px"] for k in ("vertical", "horizontal"))
        q = jpeg_quality(p)
        synthetic = q is not None and np.isfinite(sx + sy)
        R = cv2.Rodrigues(rvec)[0]
        rows.append({
            "photo": p.name, "R": R.tolist(), "t_model": tvec.ravel().tolist(),
            "pose_rms_px": float(np.sqrt(np.mean(res ** 2))), "corners": int(ok.sum()), "radius_px": r_px,
            "dark": dark["mean"], "white": white["mean"], "dark_sd": dark["sd"], "white_sd": white["sd"],
            "white_at_max": white["at_max_fraction"],
            "white_top": float(np.percentile(img[white_l > 0], 99)), "white_saturated": sat,
            "sigma_x_px": sx if np.isfinite(sx) else None, "sigma_y_px": sy if np.isfinite(sy) else None,
            **edge_shape(b),
            "jpeg_sigma_px": jpeg_blur_px(img.shape, outlines, sx, sy, dark["mean"], white["mean"], q[0])
            if synthetic else None,
            "noise_before_jpeg": None,  # the chessboard's measure reads it at junction-bounded squares' centres
            "jpeg_quality": None if q is None else {"quality": q[0], "exact": q[1]},
            "light_levels": light_levels(img, project(gaps, R, tvec.ravel(), K, dist), clip),
        })
    tone = assumed_tone(scale, tone_power, "circles")
    lo, hi = obj[:, :2].min(0), obj[:, :2].max(0)
    h, w = size
    all_images = [images[n] for n in used]
    return {"board": {"kind": "circles", "pattern_text": pattern.text, "cols": pattern.cols, "rows": pattern.rows,
                      "asymmetric": bool(pattern.asymmetric), "radius_spacings": radius,
                      "centre_model": (0.5 * (lo + hi)).tolist(), "side_model": 2.0 * radius,
                      "centres": f"corrected:{CENTRE_METHOD}", "rounds": info["rounds"]},
            "light_points": gaps.tolist(), "image_size": [w, h], "rms_px": cal.rms_px,
            "K": K.tolist(), "dist": dist.tolist(), "tone": tone, "photos": rows,
            "full_scale": scale, "max_value": int(max(float(im.max()) for im in all_images)),
            "value_step": (union & -union) if union else 1, "left_out": left_out}
