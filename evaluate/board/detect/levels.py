"""A chessboard photo's flat levels: the dark and the light squares' stored values and noise, at their centres.

The board study lists them per photo (``squares.locate_squares``) and the tone's measurement uses them
(``tone_fit``): a white whose noise is gone where the black keeps its own is saturated, and on OpenCV's photos the
saturated ones are those whose dark squares image smallest (docs/board.md, Tone).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from edgetruth.conventions import inside_image


#: half width (px) of the patch whose median is a square's level
LEVEL_HALF_PX = 2
#: ``square_levels(clip=...)`` leaves out the patches within this many noise SDs of the clip
CLIP_MARGIN_SD = 4.0
#: a white is flagged saturated where its noise SD is below this share of the dark squares' (and the dark's is > 0)
SATURATED_SD_RATIO = 0.5


@dataclass
class SquareLevels:
    """One photo's flat levels (stored values): the median and the noise SD of patches at the squares' centres."""

    dark: float
    white: float
    dark_sd: float
    white_sd: float


def light_centres(quads: np.ndarray) -> np.ndarray:
    """(L, 2) the light squares' centres among the dark squares ``quads`` (S, 4, 2; finite): each dark centre
    mirrored through its sides' midpoints (on a chessboard a light square lies across every side of a dark one),
    kept where two dark squares or more reach it (the light squares among the dark ones, not those of the outer
    ring that a board's edge may cut), in the order first reached."""
    q = np.asarray(quads, float)
    centre = q.mean(axis=1)
    light = (q + np.roll(q, -1, axis=1) - centre[:, None]).reshape(-1, 2)  # centre mirrored through each side's mid
    side = float(np.median(np.linalg.norm(q - np.roll(q, -1, axis=1), axis=2))) if len(q) else 1.0
    groups = cKDTree(light).query_ball_point(light, 0.3 * side) if len(light) else []
    return np.array([light[i] for i, g in enumerate(groups) if len(g) >= 2 and min(g) == i]).reshape(-1, 2)


def patches_at(image: np.ndarray, points: np.ndarray, half_px: int) -> tuple[np.ndarray, np.ndarray]:
    """The (2 ``half_px`` + 1)² patches of ``image`` centred on the pixels nearest ``points`` (N, 2; pixel centres
    at integers), as (M, (2 half_px + 1)²) float rows, and which of the points they are (the (N,) mask of those
    whose patch lies inside the image)."""
    r = int(half_px)
    xy = np.round(np.asarray(points, float)).reshape(-1, 2).astype(int)
    inside = inside_image(xy[:, 0], xy[:, 1], image.shape[:2], r)
    rows = [image[y - r:y + r + 1, x - r:x + r + 1].astype(np.float64).ravel() for x, y in xy[inside]]
    return np.array(rows).reshape(-1, (2 * r + 1) ** 2), inside


def square_levels(image: np.ndarray, quads: np.ndarray, half_px: int = LEVEL_HALF_PX,
                  plane: bool = False, clip: float | None = None) -> SquareLevels:
    """The levels of the dark squares (``quads`` (S, 4, 2), NaN rows skipped) and of the light squares between them,
    from (2 ``half_px`` + 1)² patches at their centres: the level is the median of the patches' medians, the SD the
    patches' pooled SD about their own means (so shading across the board does not count), or with ``plane`` about
    their own least-squares planes (so shading across a larger patch does not count either); ``clip``: patches that
    reach it, or whose mean lies within ``CLIP_MARGIN_SD`` noise SDs of it, are left out (a clip cuts their noise).
    The light squares are ``light_centres``'s."""
    q = np.asarray(quads, float)
    q = q[np.all(np.isfinite(q), axis=(1, 2))]
    centre, light = q.mean(axis=1), light_centres(q)
    r = int(half_px)
    yy, xx = np.mgrid[-r:r + 1, -r:r + 1]
    basis = np.c_[np.ones(xx.size), xx.ravel(), yy.ravel()] if plane else np.ones((xx.size, 1))
    keep = np.eye(xx.size) - basis @ np.linalg.pinv(basis)  # a patch's residual about its plane

    def level(points: np.ndarray) -> tuple[float, float]:
        patches, _ = patches_at(image, points, r)

        def pooled(patches):
            resid = patches @ keep if plane else patches - patches.mean(axis=1, keepdims=True)
            return np.sqrt((resid ** 2).sum() / (resid.size - basis.shape[1] * len(patches)))

        if clip is not None:  # those that reach it, and those within 4 SD of it (their noise's tail is cut)
            patches = patches[patches.max(axis=1) < clip]
            if len(patches):
                patches = patches[patches.mean(axis=1) + CLIP_MARGIN_SD * pooled(patches) < clip]
        if not len(patches):
            return float("nan"), float("nan")
        sd = pooled(patches)
        return float(np.median(np.median(patches, axis=1))), float(sd)

    (dark, dark_sd), (white, white_sd) = level(centre), level(light)
    return SquareLevels(dark, white, dark_sd, white_sd)


def saturated(levels: SquareLevels) -> bool:
    """Whether the white looks saturated: flatter than the dark squares by ``SATURATED_SD_RATIO`` (noise-free
    images, whose dark SD is 0, are never flagged)."""
    return bool(levels.dark_sd > 0 and levels.white_sd < SATURATED_SD_RATIO * levels.dark_sd)
