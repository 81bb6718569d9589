"""Pictures of a board study's photo: the squares found and one method's fitted sides, to check by looking.

``board_overlay`` is a pure function (a gray photo, the detected quads, a method's side-line corners ->
an RGB array, shrunk to at most ``MAX_SIDE_PX`` on its long side); the study writes one PNG per photo
used into ``figures/`` (``board_overlay_<photo>.png``), linked from the report's "Squares found" table.
Colours (RGB): the detected squares (the quads the squares were found by) ``FOUND`` in green, the
quadrilaterals of the method's fitted side lines (their intersections) ``SIDES`` in magenta, the
method's refined points ``POINTS`` in red.
"""
from __future__ import annotations

import cv2
import numpy as np


MAX_SIDE_PX = 1600
FOUND = (0, 255, 0)
SIDES = (255, 0, 255)
POINTS = (255, 40, 40)


def _polys(quads, s: float) -> list[np.ndarray]:
    q = np.asarray(quads, float).reshape(-1, 4, 2)
    ok = np.all(np.isfinite(q), axis=(1, 2))
    return [np.round((p + 0.5) * s - 0.5).astype(np.int32).reshape(-1, 1, 2) for p in q[ok]]


def board_overlay(image: np.ndarray, found_quads, side_corners=None, points=None, text: str = "") -> np.ndarray:
    """RGB uint8 picture of one photo (see the module docstring); NaN quads (squares not found) are skipped."""
    img = np.asarray(image, np.float64)
    lo, hi = np.nanpercentile(img, [0.5, 99.5])
    g = np.clip((img - lo) / max(hi - lo, 1e-12) * 255.0, 0, 255).astype(np.uint8)
    rgb = np.dstack([g, g, g])
    h, w = g.shape
    s = min(1.0, MAX_SIDE_PX / max(h, w))
    if s < 1:
        rgb = cv2.resize(rgb, (round(w * s), round(h * s)), interpolation=cv2.INTER_AREA)
    if points is not None:
        x, y = (np.asarray(v, float) for v in points[:2])
        ok = np.isfinite(x) & np.isfinite(y)
        xi = np.clip(np.round((x[ok] + 0.5) * s - 0.5).astype(int), 0, rgb.shape[1] - 1)
        yi = np.clip(np.round((y[ok] + 0.5) * s - 0.5).astype(int), 0, rgb.shape[0] - 1)
        rgb[yi, xi] = POINTS
    if side_corners is not None:
        cv2.polylines(rgb, _polys(side_corners, s), True, SIDES, 1, cv2.LINE_AA)
    cv2.polylines(rgb, _polys(found_quads, s), True, FOUND, 1, cv2.LINE_8)
    if text:
        rgb[:24] = (rgb[:24] * 0.3).astype(np.uint8)
        cv2.putText(rgb, text, (6, 17), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1, cv2.LINE_AA)
    return rgb


def overlay_name(photo: str) -> str:
    stem = "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in photo)
    return f"board_overlay_{stem}.png"


def png_bytes(rgb: np.ndarray) -> bytes:
    ok, buf = cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    return buf.tobytes()
