"""From the sensor's raw DN to the image file's pixels: demosaicing, gray, sRGB, JPEG.

- ``cfa = "none"``: the raw DN are the gray image.
- A Bayer CFA: OpenCV's bilinear demosaicing (``cv2.COLOR_Bayer<pattern>2BGR``, 16-bit) and
  OpenCV's gray conversion (Y = 0.299 R + 0.587 G + 0.114 B, rounded); both are linear, so the
  black level passes through unchanged.
- ``output = "raw"``: those DN in a 16-bit PNG.  ``"srgb8"``: v = (DN − black) / (full scale −
  black), clipped to [0, 1], through the sRGB transfer curve (IEC 61966-2-1), × 255, rounded,
  in an 8-bit PNG.  ``output_gamma`` = G > 0 replaces the sRGB curve by e = v^(1/G) (G = 1: the
  stored values are linear in light; ``edgetruth.evaluate.board.tone.values``'s power:G decodes it).
  ``"jpeg"``: the srgb8 image through OpenCV's JPEG encoder (libjpeg, gray, at ``jpeg_quality``)
  and decoded again; the decoded pixels go into the 8-bit PNG.
- **A video camera's processing** (8-bit outputs; each step off by default, in this order, on the
  encoded values e in [0, 1] before their 8-bit rounding): ``output_gain`` g and ``output_offset_dn``
  o: e ← g e + o/255 (the video level and black level; g > 1 lets the white clip at 255); ``sharpen_amount`` a: the aperture correction, an unsharp
  mask e ← e + a (e − G_σ * e), G_σ a sampled Gaussian of ``sharpen_sigma_px`` along x, y or both
  (``sharpen_axis``; borders by edge replication), so an edge's ESF over- and undershoots;
  ``output_noise_dn`` s: e ← e + N(0, (s/255)²) per pixel, the analog chain's noise after the
  camera's gamma and sharpening (white: independent from pixel to pixel; drawn from the image's
  sensor generator after the exposure's numbers, so the exposure's noise is the same with it on or
  off); then e is clipped to [0, 1] -- or to [0, ``output_clip_dn``/255], a white that saturates
  below 255, flat where it clips -- × 255, rounded.
- **Fewer levels** (last, on the 8-bit image; off by default): ``output_levels`` = N maps each
  pixel to the nearest of N gray levels round(255 k / (N − 1)); ``output_levels_rgb`` = [Nr, Ng, Nb]
  writes the gray image through an RGB palette of that many levels per channel (each channel
  starts at the gray value times its ``output_rgb_gains``, a colour cast, clipped to 0..255), then
  takes the BT.601 luma 0.299 R + 0.587 G + 0.114 B, rounded (a
  gray photo saved as a 256-colour 3-3-2 palette image and read back as luma, e.g. Zhang's
  CalibIm2/4/5).  ``output_dither = "floyd_steinberg"``: instead of the nearest level, error
  diffusion (Floyd & Steinberg 1976; raster order, the error of each pixel to its right 7/16,
  down-left 3/16, down 5/16, down-right 1/16; each channel on its own, which for a palette that is
  a product of per-channel levels is exactly error diffusion in RGB with the nearest palette
  colour); the error that would leave the image is dropped.  It keeps the local mean; it draws no
  random numbers.
"""
from __future__ import annotations

import numpy as np


def srgb_encode(v):
    """The sRGB transfer curve (linear [0, 1] -> encoded [0, 1])."""
    v = np.clip(np.asarray(v, dtype=np.float64), 0.0, 1.0)
    return np.where(v <= 0.0031308, 12.92 * v, 1.055 * np.power(v, 1.0 / 2.4) - 0.055)


def encode(v, sensor):
    """Linear [0, 1] -> encoded [0, 1]: the sRGB curve, or v^(1/G) with the sensor's ``output_gamma`` G > 0."""
    gamma = getattr(sensor, "output_gamma", 0.0)
    if not gamma:
        return srgb_encode(v)
    return np.power(np.clip(np.asarray(v, dtype=np.float64), 0.0, 1.0), 1.0 / gamma)


def srgb_decode(e):
    """Inverse of ``srgb_encode``."""
    e = np.clip(np.asarray(e, dtype=np.float64), 0.0, 1.0)
    return np.where(e <= 0.04045, e / 12.92, np.power((e + 0.055) / 1.055, 2.4))


def demosaic_gray(raw_dn: np.ndarray, pattern: str) -> np.ndarray:
    """Bayer mosaic (uint16) -> gray uint16 via OpenCV's bilinear demosaicing."""
    import cv2

    bgr = cv2.cvtColor(np.ascontiguousarray(raw_dn, dtype=np.uint16), getattr(cv2, f"COLOR_Bayer{pattern}2BGR"))
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY)


def jpeg_round_trip(image_u8: np.ndarray, quality: int) -> np.ndarray:
    import cv2

    ok, buf = cv2.imencode(".jpg", np.ascontiguousarray(image_u8, dtype=np.uint8),
                           [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:  # pragma: no cover
        raise OSError("cv2 could not encode a JPEG")
    return cv2.imdecode(buf, cv2.IMREAD_UNCHANGED)


def sharpen(encoded: np.ndarray, amount: float, sigma_px: float, axis: str = "x") -> np.ndarray:
    """Unsharp mask e + amount (e − G_σ * e) along ``axis`` ('x', 'y' or 'xy')."""
    from scipy.ndimage import gaussian_filter1d

    e = np.asarray(encoded, dtype=np.float64)
    blurred = e
    for ax in {"x": (1,), "y": (0,), "xy": (0, 1)}[axis]:
        blurred = gaussian_filter1d(blurred, sigma_px, axis=ax, mode="nearest", truncate=5.0)
    return e + amount * (e - blurred)


def even_levels(n: int) -> np.ndarray:
    """N gray levels evenly spaced over 0..255, rounded: round(255 k / (N − 1))."""
    return np.rint(255.0 * np.arange(int(n)) / (int(n) - 1))


def nearest_level(values: np.ndarray, levels: np.ndarray) -> np.ndarray:
    """Each value to the nearest of the sorted ``levels`` (ties to the lower one)."""
    v = np.asarray(values, dtype=np.float64)
    i = np.clip(np.searchsorted(levels, v), 1, len(levels) - 1)
    lo, hi = levels[i - 1], levels[i]
    return np.where(v - lo <= hi - v, lo, hi)


def floyd_steinberg(values: np.ndarray, levels: list) -> np.ndarray:
    """Floyd–Steinberg error diffusion of each channel of ``values`` (C, H, W) onto its sorted ``levels[c]``.

    Raster order (rows top to bottom, each left to right); pixel (y, x) depends only on pixels
    before it in that order, and on none of the row below, so every pixel with x + 2y = t can be
    done at once once t − 1 is done: the loop runs over W + 2(H − 1) such wavefronts, vectorised
    along them (the same result as the pixel-by-pixel loop, tested)."""
    v = np.asarray(values, dtype=np.float64)
    c_n, h, w = v.shape
    err = np.zeros((c_n, h + 1, w + 2))  # padded: column x lives at x + 1; row h and the outer columns are dropped
    out = np.empty_like(v)
    for t in range(w + 2 * (h - 1)):
        y0, y1 = max(0, -((w - 1 - t) // 2)), min(h - 1, t // 2)  # 0 <= t - 2y <= w - 1
        if y0 > y1:
            continue
        y = np.arange(y0, y1 + 1)
        x = t - 2 * y
        for c in range(c_n):
            val = v[c, y, x] + err[c, y, x + 1]
            q = nearest_level(val, levels[c])
            e = val - q
            out[c, y, x] = q
            err[c, y, x + 2] += e * (7.0 / 16.0)
            err[c, y + 1, x] += e * (3.0 / 16.0)
            err[c, y + 1, x + 1] += e * (5.0 / 16.0)
            err[c, y + 1, x + 2] += e * (1.0 / 16.0)
    return out


def quantise(image_u8: np.ndarray, sensor) -> np.ndarray:
    """The 8-bit image reduced to the sensor's ``output_levels`` or ``output_levels_rgb`` (module docstring)."""
    img = np.asarray(image_u8, dtype=np.float64)
    if sensor.output_levels:
        levels = [even_levels(sensor.output_levels)]
        stack = img[None]
    else:
        levels = [even_levels(n) for n in sensor.output_levels_rgb]
        stack = np.stack([np.clip(g * img, 0.0, 255.0) for g in sensor.output_rgb_gains])
    if sensor.output_dither == "floyd_steinberg":
        q = floyd_steinberg(stack, levels)
    else:
        q = np.stack([nearest_level(stack[c], levels[c]) for c in range(len(levels))])
    if len(levels) == 1:
        return q[0].astype(np.uint8)
    gray = LUMA_R * q[0] + LUMA_G * q[1] + LUMA_B * q[2]
    return np.clip(np.rint(gray), 0, 255).astype(np.uint8)


#: BT.601 luma weights (``edgetruth.image_io.read_gray``'s rule for colour photos)
LUMA_R, LUMA_G, LUMA_B = 0.299, 0.587, 0.114


def video_processing(encoded: np.ndarray, sensor, rng: np.random.Generator | None) -> np.ndarray:
    """The encoded values through ``output_gain`` and ``output_offset_dn``, sharpening and ``output_noise_dn`` (module docstring),
    clipped to [0, 1]; unchanged when all three are off."""
    e = encoded
    if sensor.output_gain != 1.0 or sensor.output_offset_dn:
        e = e * sensor.output_gain + sensor.output_offset_dn / 255.0
    if sensor.sharpen_amount:
        e = sharpen(e, sensor.sharpen_amount, sensor.sharpen_sigma_px, sensor.sharpen_axis)
    if sensor.output_noise_dn:
        if rng is None:
            raise ValueError("output_noise_dn needs the image's random generator")
        e = e + rng.normal(0.0, sensor.output_noise_dn / 255.0, size=e.shape)
    return np.clip(e, 0.0, 1.0)


def clip_level(sensor) -> float:
    """The encoded values' upper clip (1, or ``output_clip_dn`` / 255)."""
    return getattr(sensor, "output_clip_dn", 255.0) / 255.0


def develop(raw_dn: np.ndarray, sensor, rng: np.random.Generator | None = None) -> np.ndarray:
    """The image file's pixels from the raw DN (``sensor``: ``edgetruth.render.sensor.linear_model.SensorModel``; ``rng``:
    the image's generator, used only by ``output_noise_dn``)."""
    gray = raw_dn if sensor.cfa == "none" else demosaic_gray(raw_dn, sensor.cfa)
    if sensor.output == "raw":
        return np.asarray(gray, dtype=np.uint16)
    v = (gray.astype(np.float64) - sensor.dark_offset_dn) / (sensor.max_dn - sensor.dark_offset_dn)
    e = encode(v, sensor)
    if getattr(sensor, "video_processed", False):
        e = video_processing(e, sensor, rng)
    if clip_level(sensor) < 1.0:
        e = np.minimum(e, clip_level(sensor))
    u8 = np.rint(255.0 * e).astype(np.uint8)
    out = u8 if sensor.output == "srgb8" else jpeg_round_trip(u8, sensor.jpeg_quality)
    return quantise(out, sensor) if getattr(sensor, "quantised", False) else out


def describe(sensor) -> dict:
    """What the JSON says about the image file's pixels."""
    raw = sensor.output == "raw"
    return {
        "png_bit_depth": 16 if raw else 8,
        "encoding": {"raw": "raw DN (linear, black level included)",
                     "srgb8": "8-bit sRGB: round(255 * srgb((DN - black) / (full scale - black)))",
                     "jpeg": f"8-bit sRGB through JPEG (libjpeg via OpenCV, quality {sensor.jpeg_quality}), decoded"}[
            sensor.output],
        "black_level_dn": sensor.dark_offset_dn if raw else 0.0,
        "white_level_dn": sensor.max_dn if raw else 255,
        "cfa": sensor.cfa,
        "demosaic": None if sensor.cfa == "none" else
        f"OpenCV bilinear (COLOR_Bayer{sensor.cfa}2BGR), gray = 0.299 R + 0.587 G + 0.114 B (COLOR_BGR2GRAY)",
        "channel_qe": None if sensor.cfa == "none" else {"R": sensor.qe_r, "G": sensor.qe_g, "B": sensor.qe_b},
    } | curve_truth(sensor) | ({"quantisation": quantisation_truth(sensor)} if getattr(sensor, "quantised", False)
                               else {}) | (
        {"video": video_truth(sensor)} if getattr(sensor, "video_processed", False) else {})


def curve_truth(sensor) -> dict:
    """What the JSON adds when the 8-bit curve is not sRGB's or the white clips below 255 (nothing otherwise)."""
    out = {}
    gamma = getattr(sensor, "output_gamma", 0.0)
    if gamma and sensor.output != "raw":
        out["transfer_curve"] = {"gamma": gamma, "meaning": "e = v^(1/gamma) replaces the sRGB curve; the "
                                                            "encoding line's srgb() reads as this curve"}
    if clip_level(sensor) < 1.0 and sensor.output != "raw":
        out["clip_dn"] = {"value": sensor.output_clip_dn, "meaning": "encoded values clipped to clip_dn / 255 after "
                                                                     "the video processing and its noise"}
    return out


def video_truth(sensor) -> dict:
    """What the JSON says about the video processing of the encoded values."""
    return {"output_gain": sensor.output_gain, "output_offset_dn": sensor.output_offset_dn,
            "sharpening": {"amount": sensor.sharpen_amount, "sigma_px": sensor.sharpen_sigma_px,
                           "axis": sensor.sharpen_axis} if sensor.sharpen_amount else None,
            "output_noise_dn": sensor.output_noise_dn,
            "meaning": "encoded values e (sRGB, 0..1) -> g e + offset / 255 -> e + amount (e - G * e) (G a Gaussian of sigma_px along "
                       "axis, edge replication) -> + N(0, (output_noise_dn / 255)^2) -> clipped to [0, 1], x 255, "
                       "rounded"}


def quantisation_truth(sensor) -> dict:
    """What the JSON says about the output's reduction to fewer levels."""
    if sensor.output_levels:
        what = {"gray_levels": even_levels(sensor.output_levels).astype(int).tolist()}
    else:
        what = {"rgb_levels": [even_levels(n).astype(int).tolist() for n in sensor.output_levels_rgb],
                "rgb_gains": [float(g) for g in sensor.output_rgb_gains],
                "gray": "round(0.299 R + 0.587 G + 0.114 B) of the palette colour (each channel from the gray value "
                        "times its gain, clipped to 0..255)"}
    return {**what, "dither": sensor.output_dither,
            "meaning": "applied last, to the 8-bit image: each pixel to the nearest level, or Floyd-Steinberg error "
                       "diffusion (raster order, 7/16 right, 3/16 down-left, 5/16 down, 1/16 down-right; each channel "
                       "on its own)"}
