"""Find the declared target's outer boundary in a real scene: many candidate regions, scored, the best kept.

A pure function over arrays (``find_declared_target``); ``evaluate/target.py``'s region and candidate steps
run on what it returns.  Nothing here reads ground truth.  The priors are what a photo's CSV row
says: the shape (square, rectangle, circle), the aspect ratio (``size_m / height_m``, 1 for a
square), the polarity (dark, light or auto) and optionally a region of interest or a point inside
the target.

**Candidates.**  The image is smoothed (and reduced to at most ``WORK_PX`` on its long side, so a
12 Mpx phone photo costs what a small one does) and cut at many levels: global thresholds at the
5th-95th percentiles, and a local threshold against a box mean a third of the image wide (uneven
light), for each polarity the prior allows.  Every component's *outer* contour is a candidate
(``cv2.RETR_CCOMP``: a component inside another one's hole -- a black square on a white sheet on a
dark door -- is still a top-level contour), so whatever is printed inside a target (a drawing, text,
a fiducial) is a hole that the outer contour ignores.  Components touching the image border, the
undistorted image's invalid border, or leaving the region of interest are dropped.

**Scores** (each in [0, 1], multiplied):

- ``fit``: the outline against its model: a quadrilateral (the convex hull reduced to 4 corners)
  for squares and rectangles, an ellipse (``cv2.fitEllipse``) for circles: exp(-d / 0.02) with d
  the mean distance of the contour to the model over sqrt(area);
- ``convexity``: solidity (area / convex-hull area) to the 4th power;
- ``aspect``: the quadrilateral's aspect ratio *rectified* with the camera matrix (the homography of
  the unit square onto the corners, K^-1 H, ratio of its first two column norms; exact for a planar
  rectangle at any tilt; width over height, the corners in image order), against the declared
  ``size_m / height_m``: exp(-(log ratio / 0.15)^2);
  a circle's ellipse may be as flat as ``MIN_ELLIPSE_AXES`` (tilt up to ~60 degrees);
- ``contrast``: the boundary sampled at ``N_BOUNDARY`` points, the smoothed image 3 px in and out
  along the normal; per point the Michelson contrast with the polarity's sign; the fraction of points
  above ``MIN_POINT_CONTRAST`` ("all round": a region bounded in part by nothing, such as a shadow or a
  stroke of a drawing, fails there) times min(1, median / 0.1);
- ``nesting``: a candidate that lies inside another candidate scoring at least half as well is the
  print on a target, not the target: x ``NESTED_PENALTY``.

Candidates that are the same region at other levels (mask IoU >= 0.85) are merged, keeping the best
score; the result lists the runners-up and ``close`` is set when the second scores within
``CLOSE_RATIO`` of the best.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from edgetruth.errors import InputError
from edgetruth.evaluate.target import TargetRegion, _shape_guess, local_contrast


#: long side (px) of the working copy candidates are found on
WORK_PX = 960
PERCENTILES = tuple(range(5, 96, 5))
LOCAL_OFFSETS = (0.04, 0.08, 0.16)  # of the image's 5-95 % range
MIN_AREA_FRAC = 2e-4  # of the image area (at 640 x 480: 61 px, a 13 cm square at ~8 m)
MAX_AREA_FRAC = 0.8
N_BOUNDARY = 96
PROBE_PX = 3.0
MIN_POINT_CONTRAST = 0.04
MIN_ELLIPSE_AXES = 0.5
NESTED_PENALTY = 0.2
CLOSE_RATIO = 0.8
SAME_REGION_IOU = 0.85
MAX_CANDIDATES = 400  # per level set, largest first: a textured background yields thousands of specks


@dataclass
class Candidate:
    """One candidate region (full-image pixel coordinates)."""

    contour: np.ndarray  # (N, 2) float, the outer boundary
    polarity: str
    area_px: float
    bbox: tuple[int, int, int, int]  # x0, y0, w, h
    score: float
    terms: dict
    model: dict  # {"quad": (4, 2)} or {"ellipse": ((cx, cy), (a, b), angle_deg)}
    level: str = ""  # where it came from, e.g. "p35" or "local+0.08"

    def summary(self) -> dict:
        return {"polarity": self.polarity, "bbox": list(self.bbox), "area_px": round(self.area_px, 1),
                "score": round(self.score, 4), **{k: round(v, 4) for k, v in self.terms.items()},
                "level": self.level}


@dataclass
class FinderResult:
    best: Candidate
    runners_up: list[Candidate] = field(default_factory=list)
    close: bool = False
    n_candidates: int = 0
    by_polarity: dict = field(default_factory=dict)  # polarity -> its best candidate (auto: both tried)

    def mask(self, shape) -> np.ndarray:
        return contour_mask(self.best.contour, shape)


def contour_mask(contour: np.ndarray, shape) -> np.ndarray:
    """Filled polygon of a (N, 2) contour as a bool mask of ``shape`` (H, W)."""
    m = np.zeros(shape, np.uint8)
    pts = np.round(np.asarray(contour, float) * 16).astype(np.int32).reshape(-1, 1, 2)
    cv2.fillPoly(m, [pts], 1, lineType=cv2.LINE_8, shift=4)
    return m.astype(bool)


def _quad_candidates(hull: np.ndarray) -> list[np.ndarray]:
    """Four-corner approximations of a convex hull ((M, 1, 2)): Douglas-Peucker with a growing tolerance,
    and the hull points extreme along the diagonals of its min-area rectangle (robust to a notch)."""
    out = []
    h = hull.astype(np.float32)
    peri = cv2.arcLength(h, True)
    for eps in (0.01, 0.02, 0.03, 0.05, 0.08, 0.12):
        ap = cv2.approxPolyDP(h, eps * peri, True)
        if len(ap) == 4:
            out.append(ap.reshape(4, 2).astype(float))
            break
        if len(ap) < 4:
            break
    p = h.reshape(-1, 2).astype(float)
    (_, _), (_, _), ang = cv2.minAreaRect(h)
    t = np.radians(ang)
    u, v = p @ np.array([np.cos(t), np.sin(t)]), p @ np.array([-np.sin(t), np.cos(t)])
    idx = [int(np.argmax(f)) for f in (u + v, u - v, -u - v, -u + v)]
    if len(set(idx)) == 4:
        out.append(p[idx])
    out.append(cv2.boxPoints(cv2.minAreaRect(h)).astype(float))
    return out


def _segment_distance(p: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Distance of points (N, 2) to the closed polygon's boundary (K, 2), vectorised over both."""
    a = poly[None, :, :]
    b = np.roll(poly, -1, axis=0)[None, :, :]
    ab = b - a
    t = np.clip(np.sum((p[:, None, :] - a) * ab, axis=2) / np.maximum(np.sum(ab * ab, axis=2), 1e-12), 0, 1)
    d = np.linalg.norm(p[:, None, :] - (a + t[..., None] * ab), axis=2)
    return d.min(axis=1)


def order_corners(q: np.ndarray) -> np.ndarray:
    """Corners (4, 2) in image order: top-left, top-right, bottom-right, bottom-left (by angle about the centre)."""
    c = q.mean(axis=0)
    ang = np.arctan2(q[:, 1] - c[1], q[:, 0] - c[0])
    q = q[np.argsort(ang)]  # clockwise on screen (y down), starting near -pi (left)
    k = int(np.argmin(q[:, 0] + q[:, 1]))
    return np.roll(q, -k, axis=0)


def rectified_aspect(corners: np.ndarray, K: np.ndarray) -> float:
    """Width / height of the planar rectangle whose image corners (TL, TR, BR, BL) are ``corners``,
    with camera matrix K: H maps the unit square onto them, K^-1 H = s [r1 r2 t] diag(w, h, 1)."""
    src = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
    H = cv2.getPerspectiveTransform(src, order_corners(corners).astype(np.float32))
    M = np.linalg.solve(K, H)
    return float(np.linalg.norm(M[:, 0]) / max(np.linalg.norm(M[:, 1]), 1e-12))


def _bilinear(img: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    return cv2.remap(img, x.astype(np.float32).reshape(1, -1), y.astype(np.float32).reshape(1, -1),
                     cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE).ravel()


def boundary_contrast(smooth: np.ndarray, contour: np.ndarray, polarity: str, n: int = N_BOUNDARY,
                      probe_px: float = PROBE_PX) -> np.ndarray:
    """Per-point Michelson contrast (o - i)/(o + i) across a closed contour (N, 2), ``probe_px`` in and out
    along its normal at ``n`` points equally spaced by arc length; sign flipped for a light target."""
    c = np.asarray(contour, float)
    seg = np.linalg.norm(np.roll(c, -1, axis=0) - c, axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    at = np.linspace(0, s[-1], n, endpoint=False)
    closed = np.vstack([c, c[:1]])
    x, y = np.interp(at, s, closed[:, 0]), np.interp(at, s, closed[:, 1])
    step = max(s[-1] / n, 1.0)
    tx = np.interp(at + step, s, closed[:, 0], period=s[-1]) - np.interp(at - step, s, closed[:, 0], period=s[-1])
    ty = np.interp(at + step, s, closed[:, 1], period=s[-1]) - np.interp(at - step, s, closed[:, 1], period=s[-1])
    norm = np.maximum(np.hypot(tx, ty), 1e-12)
    nx, ny = ty / norm, -tx / norm  # one of the two normals; made outward below
    area2 = np.sum(c[:, 0] * np.roll(c[:, 1], -1) - np.roll(c[:, 0], -1) * c[:, 1])
    if area2 < 0:  # counter-clockwise on screen: flip to outward
        nx, ny = -nx, -ny
    inner = _bilinear(smooth, x - probe_px * nx, y - probe_px * ny)
    outer = _bilinear(smooth, x + probe_px * nx, y + probe_px * ny)
    con = (outer - inner) / np.maximum(np.abs(outer) + np.abs(inner), 1e-12)
    return con if polarity == "dark" else -con


def _level_masks(g: np.ndarray, polarities) -> list[tuple[str, str, np.ndarray]]:
    lo, hi = np.percentile(g, [5, 95])
    span = max(hi - lo, 1e-12)
    levels = np.percentile(g, PERCENTILES)
    k = max(15, int(min(g.shape) / 3) | 1)
    local = cv2.blur(g, (k, k), borderType=cv2.BORDER_REFLECT)
    out = []
    for pol in polarities:
        sgn = 1.0 if pol == "light" else -1.0
        for p, t in zip(PERCENTILES, levels):
            out.append((pol, f"p{p}", (sgn * (g - t) > 0)))
        for o in LOCAL_OFFSETS:
            out.append((pol, f"local+{o:g}", (sgn * (g - local) > o * span)))
    return out


def _score(c: np.ndarray, area: float, pol: str, smooth: np.ndarray, shape: str, aspect: float,
           K: np.ndarray) -> tuple[float, dict, dict]:
    hull = cv2.convexHull(c.astype(np.float32).reshape(-1, 1, 2))
    hull_area = max(float(cv2.contourArea(hull)), 1.0)
    solidity = min(area / hull_area, 1.0)
    root = np.sqrt(area)
    if shape == "circle":
        if len(c) < 6:
            return 0.0, {}, {}
        (ex, ey), (a, b), ang = cv2.fitEllipse(c.astype(np.float32))
        if min(a, b) <= 0:
            return 0.0, {}, {}
        th = np.radians(ang)
        dx, dy = c[:, 0] - ex, c[:, 1] - ey
        u, v = dx * np.cos(th) + dy * np.sin(th), -dx * np.sin(th) + dy * np.cos(th)
        r = np.hypot(u / (a / 2), v / (b / 2))
        d = float(np.mean(np.abs(r - 1.0))) * (a + b) / 4
        ratio = min(a, b) / max(a, b)
        aspect_s = 1.0 if ratio >= MIN_ELLIPSE_AXES else float(np.exp(-((np.log(ratio / MIN_ELLIPSE_AXES) / 0.15) ** 2)))
        model = {"ellipse": ((float(ex), float(ey)), (float(a), float(b)), float(ang))}
        ar = ratio
    else:
        quads = [order_corners(q) for q in _quad_candidates(hull)]
        dists = [float(np.mean(_segment_distance(c, q))) for q in quads]
        q, d = quads[int(np.argmin(dists))], min(dists)
        try:
            ar = rectified_aspect(q, K)
        except (np.linalg.LinAlgError, cv2.error):
            ar = np.nan
        # width / height as declared (size_m is the horizontal side: a rectangle turned by 90 degrees is refused
        # by the size step too, so a portrait sheet is not a landscape target)
        good = np.isfinite(ar) and ar > 0
        aspect_s = float(np.exp(-((np.log(ar / aspect) / 0.15) ** 2))) if good else 0.0
        model = {"quad": q}
    fit = float(np.exp(-(d / root) / 0.02))
    con = boundary_contrast(smooth, c, pol)
    allround = float(np.mean(con > MIN_POINT_CONTRAST))
    strength = float(min(1.0, max(np.median(con), 0.0) / 0.1))
    terms = {"fit": fit, "convexity": solidity ** 4, "aspect": aspect_s, "contrast": allround * strength,
             "all_round": allround, "median_contrast": float(np.median(con)), "aspect_seen": float(ar)}
    score = fit * solidity ** 4 * aspect_s * allround * strength
    return score, terms, model


def _rect_mask(shape, roi):
    m = np.zeros(shape, bool)
    x, y, w, h = roi
    m[max(0, y):y + h, max(0, x):x + w] = True
    return m


def find_declared_target(image: np.ndarray, shape: str = "square", aspect: float = 1.0, polarity: str = "auto",
                         valid: np.ndarray | None = None, roi: tuple[int, int, int, int] | None = None,
                         point: tuple[float, float] | None = None, K: np.ndarray | None = None,
                         n_runners_up: int = 4) -> FinderResult:
    """The declared target of a photo (see the module docstring).  ``aspect``: width / height (m / m);
    ``roi``: (x, y, w, h) px the target lies inside; ``point``: (x, y) px inside the target; ``K``: the
    camera matrix (default: fx = fy = the long side, centred) for the rectified aspect."""
    img = np.asarray(image, np.float64)
    if img.ndim != 2:
        raise InputError(f"target finding: a 2-D gray image is needed, got shape {img.shape}")
    H, W = img.shape
    if K is None:
        f = float(max(H, W))
        K = np.array([[f, 0, (W - 1) / 2], [0, f, (H - 1) / 2], [0, 0, 1.0]])
    scale = min(1.0, WORK_PX / max(H, W))
    small = cv2.resize(img.astype(np.float32), (max(1, round(W * scale)), max(1, round(H * scale))),
                       interpolation=cv2.INTER_AREA) if scale < 1 else img.astype(np.float32)
    h, w = small.shape
    Ks = np.diag([scale, scale, 1.0]) @ K
    g = cv2.GaussianBlur(small, (0, 0), 1.0)
    allowed = np.ones((h, w), bool)
    if valid is not None:
        v = cv2.resize(np.asarray(valid, np.uint8), (w, h), interpolation=cv2.INTER_NEAREST).astype(bool)
        allowed &= cv2.erode(v.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    allowed[0, :] = allowed[-1, :] = allowed[:, 0] = allowed[:, -1] = False
    if roi is not None:
        allowed &= _rect_mask((h, w), tuple(int(round(t * scale)) for t in roi))
    pt = None if point is None else (point[0] * scale, point[1] * scale)
    pols = ("dark", "light") if polarity == "auto" else (polarity,)
    min_area, max_area = MIN_AREA_FRAC * h * w, MAX_AREA_FRAC * h * w
    open_k = np.ones((3, 3), np.uint8)
    found: list[Candidate] = []
    for pol, level, m in _level_masks(g, pols):
        m = cv2.morphologyEx(m.astype(np.uint8), cv2.MORPH_OPEN, open_k)
        cnts, hier = cv2.findContours(m, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
        if hier is None:
            continue
        tops = [c for c, hh in zip(cnts, hier[0]) if hh[3] < 0]
        areas = np.array([cv2.contourArea(c) for c in tops]) if tops else np.zeros(0)
        order = np.argsort(-areas)[:MAX_CANDIDATES]
        for k in order:
            area = float(areas[k])
            if area < min_area or area > max_area:
                continue
            c = tops[k].reshape(-1, 2)
            if not allowed[c[:, 1], c[:, 0]].all():
                continue
            cf = c.astype(float)
            if pt is not None and cv2.pointPolygonTest(cf.astype(np.float32).reshape(-1, 1, 2), pt, False) < 0:
                continue
            score, terms, model = _score(cf, area, pol, g, shape, aspect, Ks)
            if not terms:
                continue
            x0, y0, bw, bh = cv2.boundingRect(c)
            found.append(Candidate(cf, pol, area, (x0, y0, bw, bh), score, terms, model, level))
    if not found:
        where = " inside the roi_px" if roi is not None else (" around the point_px" if point is not None else "")
        raise InputError(f"target finding: no closed {'/'.join(pols)} region{where} away from the image border; "
                         "is the whole target in view and in contrast with its surroundings?")
    groups = _merge(found, (h, w))
    _nesting(groups, (h, w))
    groups.sort(key=lambda c: -c.score)
    inv = 1.0 / scale
    for c in groups:  # back to full-image pixels
        c.contour = (c.contour + 0.5) * inv - 0.5 if scale < 1 else c.contour
        c.area_px *= inv * inv
        c.bbox = tuple(int(round(t * inv)) for t in c.bbox)
        if "quad" in c.model:
            c.model["quad"] = (c.model["quad"] + 0.5) * inv - 0.5 if scale < 1 else c.model["quad"]
        elif scale < 1:
            (ex, ey), (a, b), ang = c.model["ellipse"]
            c.model["ellipse"] = (((ex + 0.5) * inv - 0.5, (ey + 0.5) * inv - 0.5), (a * inv, b * inv), ang)
    best, rest = groups[0], groups[1:1 + n_runners_up]
    close = bool(rest) and rest[0].score >= CLOSE_RATIO * best.score
    by_pol = {pol: next((c for c in groups if c.polarity == pol), None) for pol in pols}
    return FinderResult(best, rest, close, len(found), by_pol)


def _merge(found: list[Candidate], shape) -> list[Candidate]:
    """One candidate per region: those with mask IoU >= SAME_REGION_IOU (same polarity) are one, the best kept."""
    found = sorted(found, key=lambda c: -c.score)
    kept: list[tuple[Candidate, np.ndarray]] = []
    for c in found:
        x0, y0, bw, bh = c.bbox
        dup = False
        for k, km in kept:
            if k.polarity != c.polarity:
                continue
            kx, ky, kw, kh = k.bbox
            ix = max(0, min(x0 + bw, kx + kw) - max(x0, kx))
            iy = max(0, min(y0 + bh, ky + kh) - max(y0, ky))
            if ix * iy < SAME_REGION_IOU * max(bw * bh, kw * kh):
                continue
            cm = contour_mask(c.contour, shape)
            inter = float(np.count_nonzero(cm & km))
            if inter / max(float(np.count_nonzero(cm | km)), 1.0) >= SAME_REGION_IOU:
                dup = True
                break
        if not dup:
            kept.append((c, contour_mask(c.contour, shape)))
        if len(kept) >= 60:
            break
    return [c for c, _ in kept]


def _nesting(cands: list[Candidate], shape) -> None:
    """Penalise a candidate lying inside another that scores at least half as well (the print on a target)."""
    masks = [contour_mask(c.contour, shape) for c in cands]
    base = [c.score for c in cands]
    for i, c in enumerate(cands):
        x0, y0, bw, bh = c.bbox
        for j, o in enumerate(cands):
            if i == j or o.area_px <= c.area_px or base[j] < 0.5 * base[i]:
                continue
            ox, oy, ow, oh = o.bbox
            if not (ox <= x0 and oy <= y0 and ox + ow >= x0 + bw and oy + oh >= y0 + bh):
                continue
            inside = np.count_nonzero(masks[i] & masks[j]) / max(np.count_nonzero(masks[i]), 1)
            if inside > 0.95:
                c.score *= NESTED_PENALTY
                c.terms["nested"] = NESTED_PENALTY
                break


def refine_mask(image: np.ndarray, cand: Candidate, band_px: int = 4) -> tuple[np.ndarray, float, float]:
    """The target mask with its boundary at the middle of the edge transition: inside / outside levels
    (medians 3 px in and out of the candidate's boundary), re-thresholded at their midpoint within
    ``band_px`` of the boundary; returns (mask, inside level, outside level)."""
    img = np.asarray(image, np.float64)
    m = contour_mask(cand.contour, img.shape).astype(np.uint8)
    k = np.ones((3, 3), np.uint8)
    core = cv2.erode(m, k, iterations=band_px).astype(bool)
    grown = cv2.dilate(m, k, iterations=band_px).astype(bool)
    ring_in = cv2.erode(m, k, iterations=2).astype(bool) & ~cv2.erode(m, k, iterations=5).astype(bool)
    ring_out = cv2.dilate(m, k, iterations=5).astype(bool) & ~cv2.dilate(m, k, iterations=2).astype(bool)
    if ring_in.sum() < 8 or ring_out.sum() < 8:
        return m.astype(bool), float("nan"), float("nan")
    i, o = float(np.median(img[ring_in])), float(np.median(img[ring_out]))
    thr = 0.5 * (i + o)
    side = (img < thr) if cand.polarity == "dark" else (img > thr)
    out = core | (grown & side)
    n, lab = cv2.connectedComponents(out.astype(np.uint8), connectivity=8)
    if n > 2:  # keep the component holding most of the candidate
        counts = np.bincount(lab[m.astype(bool)], minlength=n)
        counts[0] = 0
        out = lab == int(np.argmax(counts))
    cnts, _ = cv2.findContours(out.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    filled = np.zeros(img.shape, np.uint8)
    cv2.drawContours(filled, cnts, -1, 1, thickness=cv2.FILLED)
    return filled.astype(bool), i, o


def find_region(image: np.ndarray, valid: np.ndarray | None = None, shape: str = "square", aspect: float = 1.0,
                polarity: str = "auto", roi=None, point=None, K=None):
    """``find_declared_target`` then ``refine_mask``, as the ``target.TargetRegion`` the candidate step takes;
    its ``finder`` holds the choice, the runners-up and whether the choice was close."""
    img = np.asarray(image, np.float64)
    res = find_declared_target(img, shape, aspect, polarity, valid, roi, point, K)
    mask, inside, outside = refine_mask(img, res.best)
    if mask.sum() < 16:
        raise InputError("target finding: the chosen region vanished when its boundary was refined")
    ys, xs = np.nonzero(mask)
    x0, y0 = int(xs.min()), int(ys.min())
    bbox = (x0, y0, int(xs.max()) - x0 + 1, int(ys.max()) - y0 + 1)
    cnts, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    hull = cv2.convexHull(max(cnts, key=cv2.contourArea))
    solidity = float(mask.sum()) / max(float(cv2.contourArea(hull)), 1.0)
    b = res.best
    outline = max(cnts, key=cv2.contourArea).reshape(-1, 2)
    finder = {"chosen": b.summary(), "outline_px": outline.tolist(), "runners_up": [c.summary() for c in res.runners_up], "close": res.close,
              "n_candidates": res.n_candidates, "contour_px": np.round(b.contour, 2).tolist(),
              "runner_up_contours_px": [np.round(c.contour, 1).tolist() for c in res.runners_up],
              **({"quad_px": np.round(b.model["quad"], 3).tolist()} if "quad" in b.model else
                 {"ellipse": b.model["ellipse"]})}
    if polarity == "auto":  # the old finder's Michelson contrast of each polarity's best region (nan: none)
        finder["contrast_by_polarity"] = {
            pol: (local_contrast(img, contour_mask(c.contour, img.shape), pol, valid) if c is not None
                  else float("nan")) for pol, c in res.by_polarity.items()}
    ratio = inside / outside if np.isfinite(inside) and outside else float("nan")
    return TargetRegion(mask, bbox, (float(xs.mean()), float(ys.mean())), float(mask.sum()), solidity, ratio,
                        0.5 * (1.0 + ratio), _shape_guess(mask[y0:y0 + bbox[3], x0:x0 + bbox[2]]), b.polarity,
                        local_contrast(img, mask, b.polarity, valid), finder.get("contrast_by_polarity"),
                        finder=finder)
