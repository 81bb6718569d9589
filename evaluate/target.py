"""Find the ranging target in an (undistorted) image and keep the Canny candidates on its boundary.

Nothing here reads the ground truth: the target is found from the image alone.

1. **Board level.**  The white board's local brightness is estimated by a grey
   closing (max then min filter) of a 4x-downsampled image with a square kernel
   half the image's short side - larger than any target the specs produce
   (<= 0.43 of the short side at 50 cm), so the dark target disappears from the
   estimate while the board's slow illumination fall-off stays.  ``ratio = image /
   board`` is then ~1 on the board, ~0.05 on black targets, ~0.3 on the gray one.
2. **Dark regions.**  ``ratio < 0.55``, opened (3x3) against noise; connected
   components that touch the image border or the invalid (extrapolated) border of
   an undistorted image are dropped (the board's own edge, the unlit world).
   Holes are filled, so specular highlights inside a glossy target (T4) do not
   split it.  The target is the largest remaining component that is compact
   (solidity >= 0.85).
3. **Refined boundary.**  The threshold is re-set to the midpoint between the
   component's own interior level and the board (1.0), so the mask boundary sits
   at the middle of the edge transition for gray targets too; the component is
   re-extracted at that level.
4. **Candidates.**  ``edgetruth.locate.candidates`` on a crop around the target (the
   component's box + ``margin_px``); a candidate is kept when it lies within
   ``boundary_tol_px`` of the mask boundary *and* its gradient normal points
   outwards (from the dark target to the bright board).  Highlight edges inside
   T4 and the board's texture fail one of the two tests.

**Polarity** (``polarity=``): ``dark`` (the default, what every render holds) is the above.
``light`` finds a light target on a darker background (a white sheet on a wall): the
background level is a grey *opening* (min then max) instead of the closing, so the light
target disappears from it, and the steps above run on ``q = 2 - image / background``, which
is ~1 on the background and falls below 1 on the target exactly as the dark ratio does (a
sheet 3x as bright as the wall has q = -1); the ladder then asks for a target at least
45 / 35 / 25 % brighter than its surroundings, the mid-level threshold is the intensity
midpoint between the two, and a kept candidate's normal (dark -> bright) points *into* the
target.  ``auto`` runs both and keeps the region with the larger *local contrast*
(``TargetRegion.score``): the Michelson contrast (o - i) / (o + i) of the median levels inside
it (i, from 3 px inside its boundary) and in a band around it (o, 3-8 px outside), sign
flipped for a light target, so a region that is not darker (lighter) than its own
surroundings scores <= 0.  The wrong polarity can only find the smoothed background's halo
next to the true target (a strip of board beside it, or a ring whose filled interior is the
target itself), which has little or the wrong-signed contrast.  A photo in which the board
carrying a dark target is itself a compact light region fully in view (a small white card on
a dark wall) holds two real candidates: pass the polarity explicitly there.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from edgetruth import locate
from edgetruth.errors import InputError


DARK_RATIO = 0.55
#: tried in turn when no compact region is darker than DARK_RATIO: a glossy target's specular sheen
#: lifts part of it above 0.55 of the board (T4 at ~1 m reaches 0.7), the board stays near 1
DARK_RATIO_LADDER = (DARK_RATIO, 0.65, 0.75)
MIN_AREA_PX = 64
MIN_SOLIDITY = 0.85
#: ``find_target``'s polarity choices: a dark target on a light board, a light one on a darker
#: background, or whichever of the two is found with the larger contrast
POLARITIES = ("dark", "light", "auto")
#: longer / shorter side of the outline's min-area rectangle above which a quadrilateral is a rectangle
RECTANGLE_ASPECT = 1.2


@dataclass
class TargetRegion:
    mask: np.ndarray  # (H, W) bool, filled target region (full image)
    bbox: tuple[int, int, int, int]  # x0, y0, w, h of the component
    centroid: tuple[float, float]
    area_px: float
    solidity: float
    interior_ratio: float  # interior level / board level
    threshold_ratio: float
    shape_guess: str  # "square", "rectangle" or "circle" from the outline (a check against the declared shape)
    polarity: str = "dark"  # "dark" target on a light board or "light" target on a darker background
    score: float = float("nan")  # local contrast against the surroundings, > 0 (auto keeps the larger)
    scores: dict | None = None  # auto polarity: the score of each polarity tried (nan: nothing found)
    finder: dict | None = None  # the declared-target finder's choice, runners-up and closeness (target_finder)

    def crop_box(self, shape, margin_px: int) -> tuple[int, int, int, int]:
        """(x0, y0, x1, y1) exclusive, the bbox grown by ``margin_px`` and clipped to the image."""
        h, w = shape
        x0, y0, bw, bh = self.bbox
        return (max(0, x0 - margin_px), max(0, y0 - margin_px), min(w, x0 + bw + margin_px),
                min(h, y0 + bh + margin_px))


def board_level(image: np.ndarray, factor: int = 4) -> np.ndarray:
    """Local board brightness: grey closing of a downsampled copy, upsampled back (float64)."""
    img = np.asarray(image, np.float32)
    h, w = img.shape
    small = cv2.resize(img, (max(1, w // factor), max(1, h // factor)), interpolation=cv2.INTER_AREA)
    k = max(3, int(min(h, w) / 2 / factor) | 1)
    ker = cv2.getStructuringElement(cv2.MORPH_RECT, (k, k))
    closed = cv2.morphologyEx(small, cv2.MORPH_CLOSE, ker, borderType=cv2.BORDER_REPLICATE)
    closed = cv2.GaussianBlur(closed, (0, 0), 2.0)
    return cv2.resize(closed, (w, h), interpolation=cv2.INTER_LINEAR).astype(np.float64)


def background_level(image: np.ndarray, polarity: str = "dark", factor: int = 4) -> np.ndarray:
    """The level around the target: ``board_level`` (a grey closing) for a dark target, the same
    with a grey opening (min then max) for a light one, so that the target vanishes from it."""
    if polarity == "dark":
        return board_level(image, factor)
    img = np.asarray(image, np.float32)
    h, w = img.shape
    small = cv2.resize(img, (max(1, w // factor), max(1, h // factor)), interpolation=cv2.INTER_AREA)
    k = max(3, int(min(h, w) / 2 / factor) | 1)
    ker = cv2.getStructuringElement(cv2.MORPH_RECT, (k, k))
    opened = cv2.morphologyEx(small, cv2.MORPH_OPEN, ker, borderType=cv2.BORDER_REPLICATE)
    opened = cv2.GaussianBlur(opened, (0, 0), 2.0)
    return cv2.resize(opened, (w, h), interpolation=cv2.INTER_LINEAR).astype(np.float64)


def _fill_holes(mask: np.ndarray) -> np.ndarray:
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    out = np.zeros(mask.shape, np.uint8)
    cv2.drawContours(out, contours, -1, 1, thickness=cv2.FILLED)
    return out.astype(bool)


def _components(dark: np.ndarray, valid: np.ndarray | None):
    n, lab, stats, cents = cv2.connectedComponentsWithStats(dark.astype(np.uint8), connectivity=8)
    h, w = dark.shape
    bad_border = np.zeros(n, bool)
    if valid is not None:
        bad_border[np.unique(lab[~valid])] = True
    for k in range(1, n):
        x0, y0, bw, bh, area = stats[k]
        if x0 == 0 or y0 == 0 or x0 + bw >= w or y0 + bh >= h:
            bad_border[k] = True
    return n, lab, stats, cents, bad_border


def _best_component(dark, valid):
    n, lab, stats, cents, bad = _components(dark, valid)
    best, best_area = None, 0
    for k in range(1, n):
        if bad[k] or stats[k, cv2.CC_STAT_AREA] < MIN_AREA_PX:
            continue
        x0, y0, bw, bh, _ = stats[k]
        m = _fill_holes(lab[y0:y0 + bh, x0:x0 + bw] == k)
        area = float(m.sum())
        cnts, _ = cv2.findContours(m.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        hull = cv2.convexHull(max(cnts, key=cv2.contourArea))
        solidity = area / max(float(cv2.contourArea(hull)), 1.0)
        if solidity >= MIN_SOLIDITY and area > best_area:
            best, best_area = (k, m, (int(x0), int(y0), int(bw), int(bh)), solidity), area
    return best


def local_contrast(image: np.ndarray, mask: np.ndarray, polarity: str, valid: np.ndarray | None = None) -> float:
    """Michelson contrast (o - i) / (|o| + |i|) of the median level i inside ``mask`` (3 px in from its
    boundary) against the median o of the band 3-8 px outside it; negated for a light target."""
    ys, xs = np.nonzero(mask)
    if ys.size == 0:
        return float("nan")
    h, w = mask.shape
    y0, y1, x0, x1 = max(0, ys.min() - 10), min(h, ys.max() + 11), max(0, xs.min() - 10), min(w, xs.max() + 11)
    m = mask[y0:y1, x0:x1].astype(np.uint8)
    k = np.ones((3, 3), np.uint8)
    inner = cv2.erode(m, k, iterations=3).astype(bool)
    if inner.sum() < 10:
        inner = m.astype(bool)
    band = cv2.dilate(m, k, iterations=8).astype(bool) & ~cv2.dilate(m, k, iterations=3).astype(bool)
    if valid is not None:
        band &= valid[y0:y1, x0:x1]
    if not band.any():
        return float("nan")
    img = np.asarray(image, np.float64)[y0:y1, x0:x1]
    i, o = float(np.median(img[inner])), float(np.median(img[band]))
    c = (o - i) / max(abs(o) + abs(i), 1e-12)
    return c if polarity == "dark" else -c


def _shape_guess(mask: np.ndarray) -> str:
    """'square' if the outline is closer to its min-area rectangle than to its min enclosing circle
    ('rectangle' when that rectangle's sides differ by more than ``RECTANGLE_ASPECT``), else 'circle'."""
    cnts, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    c = max(cnts, key=cv2.contourArea)
    area = float(mask.sum())
    (_, _), (rw, rh), _ = cv2.minAreaRect(c)
    (_, _), r = cv2.minEnclosingCircle(c)
    rect_fill = area / max(rw * rh, 1.0)
    circ_fill = area / max(np.pi * r * r, 1.0)
    if rect_fill <= circ_fill:
        return "circle"
    return "rectangle" if max(rw, rh) > RECTANGLE_ASPECT * max(min(rw, rh), 1.0) else "square"


def find_target(image: np.ndarray, valid: np.ndarray | None = None, polarity: str = "dark") -> TargetRegion:
    """The target: dark on a bright board (default), light on a darker background, or ``auto``
    (the polarity found with the larger contrast; see the module docstring)."""
    if polarity not in POLARITIES:
        raise InputError(f"target finding: polarity {polarity!r}; choose one of {', '.join(POLARITIES)}")
    img = np.asarray(image, np.float64)
    if polarity != "auto":
        return _find(img, valid, polarity)
    found, scores = {}, {}
    for pol in ("dark", "light"):
        try:
            found[pol] = _find(img, valid, pol)
            scores[pol] = found[pol].score
        except InputError:
            scores[pol] = float("nan")
    if not found:
        raise InputError("target finding: no compact dark or light region away from the image border; "
                         "is the target in view and in contrast with its background?")
    best = max(found.values(), key=lambda r: r.score if np.isfinite(r.score) else -np.inf)
    best.scores = scores
    return best


def _find(img: np.ndarray, valid: np.ndarray | None, polarity: str) -> TargetRegion:
    """``find_target`` for one polarity.  A light target runs the dark target's steps on
    q = 2 - image / background (~1 on the background, < 1 on the target, linear in intensity)."""
    bg = background_level(img, polarity)
    ratio = img / np.maximum(bg, 1e-9 + 1e-6 * float(bg.max()))
    if polarity == "light":
        ratio = 2.0 - ratio
    open_k = np.ones((3, 3), np.uint8)
    for dark_ratio in DARK_RATIO_LADDER:
        dark = cv2.morphologyEx((ratio < dark_ratio).astype(np.uint8), cv2.MORPH_OPEN, open_k).astype(bool)
        best = _best_component(dark, valid)
        if best is not None:
            break
    if best is None:
        if polarity == "light":
            raise InputError("target finding: no compact light region away from the image border; "
                             "is the target in view and brighter than its background?")
        raise InputError("target finding: no compact dark region away from the image border; "
                         "is the target in view and darker than the board?")
    k, m, (x0, y0, bw, bh), solidity = best
    # interior level: median ratio well inside (eroded) the component
    full = np.zeros(img.shape, bool)
    full[y0:y0 + bh, x0:x0 + bw] = m
    inner = cv2.erode(full.astype(np.uint8), np.ones((5, 5), np.uint8), iterations=2).astype(bool)
    interior = float(np.median(ratio[inner])) if inner.sum() > 10 else float(np.median(ratio[full]))
    thr = 0.5 * (min(interior, dark_ratio) + 1.0)
    # re-extract at the mid level, near the first component only (within its own size: a sheen can
    # leave part of the target above the first threshold)
    pad = max(6, bw, bh)
    ys, xs = slice(max(0, y0 - pad), y0 + bh + pad), slice(max(0, x0 - pad), x0 + bw + pad)
    local = np.zeros(img.shape, bool)
    local[ys, xs] = ratio[ys, xs] < thr
    local = cv2.morphologyEx(local.astype(np.uint8), cv2.MORPH_OPEN, open_k).astype(bool)
    best2 = _best_component(local, valid)
    if best2 is not None:
        _, m2, (x0, y0, bw, bh), solidity = best2
        full = np.zeros(img.shape, bool)
        full[y0:y0 + bh, x0:x0 + bw] = m2
    else:
        thr = dark_ratio
    yy, xx = np.nonzero(full)
    if polarity == "light":  # back from q to the intensity ratio image / background
        interior, thr = 2.0 - interior, 2.0 - thr
    return TargetRegion(full, (x0, y0, bw, bh), (float(xx.mean()), float(yy.mean())), float(full.sum()),
                        float(solidity), interior, float(thr), _shape_guess(full[y0:y0 + bh, x0:x0 + bw]),
                        polarity, local_contrast(img, full, polarity, valid))


def boundary_distance(mask: np.ndarray) -> np.ndarray:
    """Distance (px) of every pixel centre to the mask's boundary (pixels on either side of it)."""
    m = mask.astype(np.uint8)
    edge = (m ^ cv2.erode(m, np.ones((3, 3), np.uint8))) | (m ^ cv2.dilate(m, np.ones((3, 3), np.uint8)))
    return cv2.distanceTransform((edge == 0).astype(np.uint8), cv2.DIST_L2, 5)


@dataclass
class TargetCandidates:
    region: TargetRegion
    crop: np.ndarray  # the image crop the candidates (and refinements) refer to
    offset: tuple[int, int]  # (x0, y0) of the crop in the image
    all_candidates: object  # locate.Candidates of the crop
    candidates: object  # the boundary subset
    keep: np.ndarray  # bool over all_candidates


def target_candidates(image: np.ndarray, valid: np.ndarray | None = None, margin_px: int = 12,
                      boundary_tol_px: float = 2.0, sigma_px: float = 1.0, polarity: str = "dark",
                      region: TargetRegion | None = None) -> TargetCandidates:
    """Find the target (or take ``region``, found elsewhere: ``target_finder.find_region``), crop around it,
    run Canny there and keep the candidates on its boundary (their dark -> bright normal points out of a dark
    target, into a light one)."""
    img = np.asarray(image, np.float64)
    if region is None:
        region = find_target(img, valid, polarity)
    x0, y0, x1, y1 = region.crop_box(img.shape, margin_px)
    crop = np.ascontiguousarray(img[y0:y1, x0:x1])
    cand = locate.candidates(crop, sigma_px=sigma_px)
    dist = boundary_distance(region.mask[y0:y1, x0:x1])
    xi, yi = cand.x.astype(np.intp), cand.y.astype(np.intp)
    near = dist[yi, xi] <= boundary_tol_px
    cx, cy = region.centroid[0] - x0, region.centroid[1] - y0
    out = cand.nx * (cand.x - cx) + cand.ny * (cand.y - cy)
    keep = near & ((out > 0) if region.polarity == "dark" else (out < 0))
    if keep.sum() < 8:
        raise InputError(f"target finding: only {int(keep.sum())} Canny candidates on the target boundary")
    return TargetCandidates(region, crop, (x0, y0), cand, cand.subset(keep), keep)


def is_scene(truth) -> bool:
    """The truth of an image with several outlines (``SceneOutline``: shapes, a ring's two edges, clutter)."""
    return getattr(truth, "shape", "") == "scene"
