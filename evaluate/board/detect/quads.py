"""Dark quadrilaterals of a photo: the candidate squares of a board, to pixel accuracy.

Adaptive mean threshold (a pixel darker than its neighbourhood's mean by ``offset`` of the
image's gray range is dark), outer contours of the dark regions, a polygon approximation
of each (Douglas-Peucker, tolerance a fraction of the perimeter), kept when it has four
vertices, is convex, fills its contour (area ratio), is neither tiny nor a large part of
the image, and does not reach the image's border (a square cut by it is not a square).
Several neighbourhood sizes are tried and their quads pooled (duplicates, the same square
found twice, merged by their centres), so squares of any size from ``MIN_SIDE_PX`` to
about a quarter of the image are found without a size hint.

Corners are returned clockwise on screen (image y down), in OpenCV's pixel-centre
convention; they are the polygon's vertices (about 1 px accurate), only a first pass for
the side-line fits.
"""
from __future__ import annotations

import cv2
import numpy as np

from edgetruth.evaluate.board.model import convex, signed_areas

MIN_SIDE_PX = 6.0
#: Neighbourhood sizes of the adaptive threshold, as fractions of the image's smaller side.
BLOCK_FRACTIONS = (1 / 4, 1 / 8, 1 / 16)
#: A pixel is dark when it is this fraction of the gray range below its neighbourhood's mean.
OFFSET_FRACTION = 0.05
#: Douglas-Peucker tolerances, fractions of the contour's perimeter.
EPSILONS = (0.03, 0.05)
#: A quad must cover at least this share of its contour's area, and the contour of the quad.
FILL_MIN = 0.85
#: Dark regions reaching this close to the image's border are cut by it and left out.
BORDER_PX = 2


def to_uint8(image: np.ndarray) -> np.ndarray:
    """The image stretched to 0..255 between its 0.5 and 99.5 percentiles (8-bit images pass unchanged)."""
    img = np.asarray(image)
    if img.dtype == np.uint8:
        return img
    f = img.astype(np.float64)
    lo, hi = np.percentile(f, [0.5, 99.5])
    if hi <= lo:
        hi = lo + 1.0
    return np.clip(np.round((f - lo) * (255.0 / (hi - lo))), 0, 255).astype(np.uint8)


def _quads_of(binary: np.ndarray) -> list[np.ndarray]:
    h, w = binary.shape
    contours, _ = cv2.findContours(binary, cv2.RETR_LIST, cv2.CHAIN_APPROX_SIMPLE)
    out = []
    for c in contours:
        area_c = cv2.contourArea(c)
        if area_c < MIN_SIDE_PX ** 2 or area_c > h * w / 16:
            continue
        x, y = c[:, 0, 0], c[:, 0, 1]
        if x.min() < BORDER_PX or y.min() < BORDER_PX or x.max() > w - 1 - BORDER_PX or y.max() > h - 1 - BORDER_PX:
            continue  # cut by the image's border: its visible part is not the square
        per = cv2.arcLength(c, True)
        for eps in EPSILONS:
            poly = cv2.approxPolyDP(c, eps * per, True)
            if len(poly) == 4:
                q = poly[:, 0, :].astype(np.float64)
                a = abs(signed_areas(q))
                if convex(q) and min(a, area_c) / max(a, area_c) >= FILL_MIN:
                    out.append(q)
                break
    return out


def clockwise(quads: np.ndarray) -> np.ndarray:
    """Quads reordered clockwise on screen (positive shoelace area in y-down coordinates)."""
    q = np.asarray(quads, np.float64).copy()
    flip = signed_areas(q) < 0
    q[flip] = q[flip][:, ::-1]
    return q


def find_quads(image: np.ndarray) -> np.ndarray:
    """(Q, 4, 2) dark quadrilaterals of ``image``, clockwise on screen, duplicates merged."""
    g = to_uint8(image)
    h, w = g.shape
    rng = float(np.percentile(g, 99) - np.percentile(g, 1)) or 1.0
    found = []
    for frac in BLOCK_FRACTIONS:
        block = max(3, int(min(h, w) * frac) | 1)
        binary = cv2.adaptiveThreshold(g, 255, cv2.ADAPTIVE_THRESH_MEAN_C, cv2.THRESH_BINARY_INV, block,
                                       OFFSET_FRACTION * rng)
        found += _quads_of(binary)
    if not found:
        return np.zeros((0, 4, 2))
    q = clockwise(np.array(found))
    # merge duplicates: keep the first quad of each group of centres closer than a third of its side
    centres = q.mean(axis=1)
    side = np.sqrt(np.abs(signed_areas(q)))
    d = np.linalg.norm(centres[:, None] - centres[None], axis=2)
    dup = np.triu(d < side[:, None] / 3, k=1).any(axis=0)
    return q[~dup]
