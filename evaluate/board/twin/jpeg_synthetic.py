"""What a photo's JPEG did to it, measured on a synthetic image of the photo's own squares through the same encoder.

A JPEG photo's blur and noise are read after its JPEG, and a twin's renders go through a JPEG again.
``synthetic_board`` draws the photo's squares (its side lines, its levels, an ERF of its σ across each side) and
stores them as 8-bit with and without the JPEG at the photo's quality (``render.sensor.pipeline.jpeg_round_trip``,
the twin's encoder):

- ``jpeg_blur_px``: how much the JPEG raises the ERF σ ``photo_model.blur`` reads (by 0.00-0.05 px on OpenCV's
  photos at quality 50, depending on the side's angle to the 8x8 blocks);
- ``noise_before_jpeg``: the shot noise (at the white) and the constant read noise before the JPEG that leave the
  photo's white and dark SDs after it.  A JPEG's quantisation takes small noise off almost whole and larger noise
  in part (at quality 50, 3, 4.5 and 6 DN before it leave about 1.1, 2.3 and 3.6 DN at a white of ~230, and dark
  noise below ~1.5 DN leaves nothing), so no one factor maps after to before; the synthetic board finds both per
  photo (OpenCV's photos: docs/board.md, *Your own twin*).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.special import ndtr

from edgetruth.evaluate.board.detect.levels import square_levels
from edgetruth.evaluate.board.tone.photo_model import ESF_HALF_WIDTH_PX, _outward, blur
from edgetruth.render.sensor.pipeline import jpeg_round_trip


def synthetic_board(shape: tuple[int, int], lines, sigma_x_px: float, sigma_y_px: float, dark: float,
                    white: float) -> np.ndarray:
    """A noise-free image (float, stored values) of the squares whose side lines ``lines`` are
    (``photo_model.BoardLines``): ``white`` with each dark square at ``dark``, its coverage at a pixel centre the
    product over its sides of Φ(−d/σ) (d: the distance outside the side, px; σ: ``sigma_x_px`` and ``sigma_y_px``
    combined along the side's normal), exact along the middle of each side where ``photo_model.blur`` reads it."""
    n, d = _outward(lines)
    h, w = shape
    cover = np.zeros(shape)
    reach = ESF_HALF_WIDTH_PX + 2.0
    for s in np.flatnonzero(np.all(np.isfinite(lines.corners), axis=(1, 2))):
        c = lines.corners[s]
        x0, y0 = np.maximum(np.floor(c.min(0) - reach).astype(int), 0)
        x1, y1 = np.minimum(np.ceil(c.max(0) + reach).astype(int), [w - 1, h - 1])
        if x1 < x0 or y1 < y0:
            continue
        yy, xx = np.mgrid[y0:y1 + 1, x0:x1 + 1].astype(np.float64)
        inside = np.ones_like(xx)
        for k in range(4):
            sigma = math.hypot(n[s, k, 0] * sigma_x_px, n[s, k, 1] * sigma_y_px)
            inside *= ndtr(-(n[s, k, 0] * xx + n[s, k, 1] * yy - d[s, k]) / sigma)
        cover[y0:y1 + 1, x0:x1 + 1] += inside
    return white - (white - dark) * np.clip(cover, 0.0, 1.0)


def jpeg_blur_px(shape: tuple[int, int], lines, sigma_x_px: float, sigma_y_px: float, dark: float, white: float,
                 quality: int) -> dict:
    """{"x", "y"}: how much a JPEG at ``quality`` (``render.sensor.pipeline.jpeg_round_trip``, the twin's encoder)
    raises the ERF σ (px) ``photo_model.blur`` reads on the ``synthetic_board`` of these lines, levels and σ; the
    same pixels stored as 8-bit without it are the reference, so the synthesis' own small bias cancels."""
    img = synthetic_board(shape, lines, sigma_x_px, sigma_y_px, dark, white)
    u8 = np.clip(np.round(img), 0, 255).astype(np.uint8)
    plain = blur(u8.astype(np.float64), lines)
    coded = blur(jpeg_round_trip(u8, int(quality)).astype(np.float64), lines)
    return {axis: float(coded[name]["sigma_px"] - plain[name]["sigma_px"])
            for axis, name in (("x", "vertical"), ("y", "horizontal"))}


#: the white's shot-noise SDs before the JPEG, as multiples of the photo's SD after it, at which
#: ``noise_before_jpeg`` measures what the JPEG leaves (it interpolates between them)
BEFORE_OVER_AFTER = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 6.0)
#: noise draws averaged per level (fixed seeds: the measurement is a pure function of the photo)
NOISE_SEEDS = (0, 1)


#: the constant (read) noise SDs before the JPEG, 8-bit DN, at which ``noise_before_jpeg`` measures the darks
READ_NOISE_DN = (0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0)
#: alternations of the white's and the dark's one-dimensional solutions
NOISE_PASSES = 3


def noise_before_jpeg(shape: tuple[int, int], lines, squares, sigma_x_px: float, sigma_y_px: float, dark: float,
                      white: float, white_sd_after: float, dark_sd_after: float, quality: int) -> dict | None:
    """The noise before a JPEG at ``quality`` that leaves the photo's white and dark SDs after it (at the light and
    dark squares' centres, ``levels.square_levels``): SD² = s² v / ``white`` + r² at each stored level v, shot noise
    of SD s at the white and a constant (read) noise r, on the ``synthetic_board`` of these lines, levels and σ.
    The white's SD is solved for s with r held (``BEFORE_OVER_AFTER``), the dark's for r with s held
    (``READ_NOISE_DN``), ``NOISE_PASSES`` times.  -> {"shot_dn": s, "read_dn": r}; None when no noise is measured
    after it, or when none of the levels leaves as much."""
    if not (white_sd_after > 0 and math.isfinite(white_sd_after) and math.isfinite(dark_sd_after)):
        return None
    clean = synthetic_board(shape, lines, sigma_x_px, sigma_y_px, dark, white)
    rel = np.maximum(clean, 1.0) / white
    draws = [np.random.default_rng(seed).standard_normal(clean.shape) for seed in NOISE_SEEDS]

    def after(s: float, r: float) -> tuple[float, float]:
        sd = np.sqrt(s * s * rel + r * r)
        lv = [square_levels(jpeg_round_trip(np.clip(np.round(clean + sd * z), 0, 255).astype(np.uint8),
                                            int(quality)).astype(np.float64), squares) for z in draws]
        return float(np.mean([v.white_sd for v in lv])), float(np.mean([v.dark_sd for v in lv]))

    def solve(grid, measured, target) -> float | None:
        measured = np.maximum.accumulate(np.asarray(measured))  # more noise before leaves more after: monotone
        if measured[-1] < target:
            return None
        if measured[0] >= target:
            return float(grid[0])
        first = int(np.argmax(measured > measured[0]))  # the flat start (a JPEG takes small noise off whole)
        return float(np.interp(target, measured[max(first - 1, 0):], np.asarray(grid)[max(first - 1, 0):]))

    s, r = white_sd_after, 0.0
    for _ in range(NOISE_PASSES):
        grid = np.asarray(BEFORE_OVER_AFTER) * white_sd_after
        s_new = solve(grid, [after(v, r)[0] for v in grid], white_sd_after)
        if s_new is None:
            return None
        s = s_new
        r_new = solve(READ_NOISE_DN, [after(s, v)[1] for v in READ_NOISE_DN], dark_sd_after)
        if r_new is None:
            return None
        r = r_new
    return {"shot_dn": s, "read_dn": r}
