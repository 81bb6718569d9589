"""From the sensor's raw DN to the image file's pixels: demosaicing, gray, sRGB, JPEG.

- ``cfa = "none"``: the raw DN are the gray image.
- A Bayer CFA: OpenCV's bilinear demosaicing (``cv2.COLOR_Bayer<pattern>2BGR``, 16-bit) and
  OpenCV's gray conversion (Y = 0.299 R + 0.587 G + 0.114 B, rounded); both are linear, so the
  black level passes through unchanged.
- ``output = "raw"``: those DN in a 16-bit PNG.  ``"srgb8"``: v = (DN − black) / (full scale −
  black), clipped to [0, 1], through the sRGB transfer curve (IEC 61966-2-1), × 255, rounded,
  in an 8-bit PNG.  ``"jpeg"``: the srgb8 image through OpenCV's JPEG encoder (libjpeg, gray, at
  ``jpeg_quality``) and decoded again; the decoded pixels go into the 8-bit PNG.
"""
from __future__ import annotations

import numpy as np


def srgb_encode(v):
    """The sRGB transfer curve (linear [0, 1] -> encoded [0, 1])."""
    v = np.clip(np.asarray(v, dtype=np.float64), 0.0, 1.0)
    return np.where(v <= 0.0031308, 12.92 * v, 1.055 * np.power(v, 1.0 / 2.4) - 0.055)


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


def develop(raw_dn: np.ndarray, sensor) -> np.ndarray:
    """The image file's pixels from the raw DN (``sensor``: ``edgetruth.render.sensor.SensorModel``)."""
    gray = raw_dn if sensor.cfa == "none" else demosaic_gray(raw_dn, sensor.cfa)
    if sensor.output == "raw":
        return np.asarray(gray, dtype=np.uint16)
    v = (gray.astype(np.float64) - sensor.dark_offset_dn) / (sensor.max_dn - sensor.dark_offset_dn)
    u8 = np.rint(255.0 * srgb_encode(v)).astype(np.uint8)
    return u8 if sensor.output == "srgb8" else jpeg_round_trip(u8, sensor.jpeg_quality)


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
    }
