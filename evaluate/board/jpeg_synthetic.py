"""What a photo's JPEG did to it, measured on a synthetic image of the photo's own squares through the same encoder.

A JPEG photo's blur and noise are read after its JPEG, and a twin's renders go through a JPEG again.
``synthetic_board`` draws the photo's squares (its side lines, its levels, an ERF of its σ across each side) and
stores them as 8-bit with and without the JPEG at the photo's quality (``render.sensor.pipeline.jpeg_round_trip``,
the twin's encoder):

- ``jpeg_blur_px``: how much the JPEG raises the ERF σ ``photo_model.blur`` reads (by 0.00-0.05 px on OpenCV's
  photos at quality 50, depending on the side's angle to the 8x8 blocks);
- ``white_sd_before_jpeg``: the white's noise SD before the JPEG that leaves the photo's after it.  A JPEG's
  quantisation takes small noise off almost whole and larger noise in part (at quality 50, 3, 4.5 and 6 DN before
  it leave about 1.1, 2.3 and 3.6 DN at a white of ~230), so no one factor maps after to before; the synthetic
  board finds the level per photo.  On OpenCV's photos: 3.9-4.5 DN at 220 (median 4.27).  The twin takes its
  read noise off that (``twin_derive``: 4.11 DN of shot noise), and its rendered white SD at the squares' centres
  then reads 0.97x the photos' (docs/board.md).
"""
from __future__ import annotations

import math

import numpy as np

from edgetruth.evaluate.board.photo_model import ESF_HALF_WIDTH_PX


def synthetic_board(shape: tuple[int, int], lines, sigma_x_px: float, sigma_y_px: float, dark: float,
                    white: float) -> np.ndarray:
    """A noise-free image (float, stored values) of the squares whose side lines ``lines`` are
    (``photo_model.BoardLines``): ``white`` with each dark square at ``dark``, its coverage at a pixel centre the
    product over its sides of Φ(−d/σ) (d: the distance outside the side, px; σ: ``sigma_x_px`` and ``sigma_y_px``
    combined along the side's normal), exact along the middle of each side where ``photo_model.blur`` reads it."""
    from scipy.special import ndtr

    from edgetruth.evaluate.board.photo_model import _outward

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
    from edgetruth.evaluate.board.photo_model import blur
    from edgetruth.render.sensor.pipeline import jpeg_round_trip

    img = synthetic_board(shape, lines, sigma_x_px, sigma_y_px, dark, white)
    u8 = np.clip(np.round(img), 0, 255).astype(np.uint8)
    plain = blur(u8.astype(np.float64), lines)
    coded = blur(jpeg_round_trip(u8, int(quality)).astype(np.float64), lines)
    return {axis: float(coded[name]["sigma_px"] - plain[name]["sigma_px"])
            for axis, name in (("x", "vertical"), ("y", "horizontal"))}


#: the noise SDs before the JPEG, as multiples of the photo's after it, at which ``white_sd_before_jpeg`` measures
#: what the JPEG leaves (it interpolates between them; the ratio at quality 50 is 2.0-2.3 on OpenCV's photos)
BEFORE_OVER_AFTER = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 6.0)
#: noise draws averaged per level (fixed seeds: the measurement is a pure function of the photo)
NOISE_SEEDS = (0, 1)


def white_sd_before_jpeg(shape: tuple[int, int], lines, squares, sigma_x_px: float, sigma_y_px: float, dark: float,
                         white: float, white_sd_after: float, quality: int) -> float | None:
    """The white's noise SD (8-bit DN, at the level ``white``) before a JPEG at ``quality`` that leaves
    ``white_sd_after`` at the light squares' centres (``levels.square_levels`` of ``squares``, as the photo's was
    measured): the ``synthetic_board`` of these lines, levels and σ with Gaussian noise of SD s √(v / ``white``) at
    each stored level v (shot noise), stored as 8-bit through the JPEG, at each s of ``BEFORE_OVER_AFTER`` times
    ``white_sd_after``; the s whose mean white SD after it (``NOISE_SEEDS``) is ``white_sd_after``, interpolated.
    None when no noise is measured after it, or when even the largest s leaves less."""
    from edgetruth.evaluate.board.levels import square_levels
    from edgetruth.render.sensor.pipeline import jpeg_round_trip

    if not (white_sd_after > 0 and math.isfinite(white_sd_after)):
        return None
    clean = synthetic_board(shape, lines, sigma_x_px, sigma_y_px, dark, white)
    shot = np.sqrt(np.maximum(clean, 1.0) / white)
    draws = [np.random.default_rng(seed).standard_normal(clean.shape) for seed in NOISE_SEEDS]
    before = np.asarray(BEFORE_OVER_AFTER) * white_sd_after
    after = []
    for s in before:
        sds = [square_levels(jpeg_round_trip(np.clip(np.round(clean + s * shot * z), 0, 255).astype(np.uint8),
                                             int(quality)).astype(np.float64), squares).white_sd for z in draws]
        after.append(float(np.mean(sds)))
    after = np.maximum.accumulate(np.asarray(after))  # the JPEG leaves more of more noise: monotone
    if after[-1] < white_sd_after:
        return None
    if after[0] >= white_sd_after:
        return float(before[0] * white_sd_after / max(after[0], 1e-9))
    return float(np.interp(white_sd_after, after, before))
