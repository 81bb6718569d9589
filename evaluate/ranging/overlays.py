"""Pictures of what was measured on a photo: the found outline, the fitted sides, the refined points, l.

``photo_overlay`` is a pure function (a gray image and what was found -> an RGB array); the photo
pipeline writes one PNG per photo into the run's ``figures/`` (``write_photo_overlay``), linked from the
report's photos table.  Drawn on the image the methods refined (the undistorted photo), at most
``MAX_SIDE_PX`` on its long side (a 12 Mpx photo is shrunk; coordinates are scaled with it).

Colours (RGB): the found outline ``OUTLINE`` (1 px, not antialiased, so a test can find it), the fitted
side lines or circle ``FIT``, the refined points of one method ``POINTS``, runners-up ``RUNNER`` blended
at 40 %, the text (l in px, the method, Z and the reference distance) on a dark band at the top.
"""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from edgetruth.fileio import atomic_write_bytes


MAX_SIDE_PX = 1600
OUTLINE = (0, 255, 0)
FIT = (255, 0, 255)
POINTS = (255, 40, 40)
RUNNER = (255, 210, 0)
RUNNER_ALPHA = 0.4


def _gray_to_rgb(image: np.ndarray) -> np.ndarray:
    img = np.asarray(image, np.float64)
    lo, hi = np.nanpercentile(img, [0.5, 99.5])
    g = np.clip((img - lo) / max(hi - lo, 1e-12) * 255.0, 0, 255).astype(np.uint8)
    return np.dstack([g, g, g])


def _poly(a: np.ndarray, s: float) -> np.ndarray:
    """Polygon points (N, 2) in image px -> int32 (N, 1, 2) at scale ``s`` (pixel centres stay centres)."""
    return np.round((np.asarray(a, float) + 0.5) * s - 0.5).astype(np.int32).reshape(-1, 1, 2)


def _line_segment(n, d, corners: np.ndarray, extend: float = 0.15):
    """The part of the line n . p = d between the two corners nearest it, extended by ``extend`` of its length."""
    n = np.asarray(n, float)
    dist = np.abs(corners @ n - d)
    a, b = corners[np.argsort(dist)[:2]]
    a, b = a - n * (a @ n - d), b - n * (b @ n - d)  # onto the line
    t = b - a
    return a - extend * t, b + extend * t


def photo_overlay(image: np.ndarray, outline_px, fit: dict | None = None, points=None,
                  runners_up=(), text=()) -> tuple[np.ndarray, float]:
    """(RGB uint8 overlay, scale of the overlay over the image).  ``outline_px``: (N, 2) the found boundary;
    ``fit``: ``images.fit_geometry``'s dict; ``points``: (x, y) of one method; ``runners_up``: contours."""
    rgb = _gray_to_rgb(image)
    h, w = rgb.shape[:2]
    s = min(1.0, MAX_SIDE_PX / max(h, w))
    if s < 1:
        rgb = cv2.resize(rgb, (round(w * s), round(h * s)), interpolation=cv2.INTER_AREA)
    if runners_up:
        faint = rgb.copy()
        for c in runners_up:
            cv2.polylines(faint, [_poly(c, s)], True, RUNNER, 1, cv2.LINE_AA)
        rgb = cv2.addWeighted(faint, RUNNER_ALPHA, rgb, 1 - RUNNER_ALPHA, 0)
    if fit:
        if "lines" in fit:
            corners = np.asarray(fit["corners"], float)
            for n, d in fit["lines"].values():
                a, b = _line_segment(n, d, corners)
                cv2.line(rgb, tuple(int(v) for v in np.round((a + 0.5) * s - 0.5)),
                         tuple(int(v) for v in np.round((b + 0.5) * s - 0.5)), FIT, 1, cv2.LINE_AA)
        elif "circle" in fit:
            cx, cy, r = fit["circle"]
            cv2.circle(rgb, (int(round((cx + 0.5) * s - 0.5)), int(round((cy + 0.5) * s - 0.5))),
                       int(round(r * s)), FIT, 1, cv2.LINE_AA)
    if points is not None:
        x, y = (np.asarray(v, float) for v in points)
        ok = np.isfinite(x) & np.isfinite(y)
        xi = np.clip(np.round((x[ok] + 0.5) * s - 0.5).astype(int), 0, rgb.shape[1] - 1)
        yi = np.clip(np.round((y[ok] + 0.5) * s - 0.5).astype(int), 0, rgb.shape[0] - 1)
        rgb[yi, xi] = POINTS
    cv2.polylines(rgb, [_poly(outline_px, s)], True, OUTLINE, 1, cv2.LINE_8)  # last: on top, exact colour
    if text:
        band = 18 * len(text) + 6
        rgb[:band] = (rgb[:band] * 0.3).astype(np.uint8)
        for k, t in enumerate(text):
            cv2.putText(rgb, t, (6, 18 * k + 16), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1, cv2.LINE_AA)
    return rgb, s


def overlay_name(image_name: str) -> str:
    """``figures/`` file name of a photo's overlay (the photo's path made a flat file name)."""
    stem = "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in image_name)
    return f"overlay_{stem}.png"


def write_photo_overlay(path: Path, image: np.ndarray, region: dict, fit: dict | None, points, method: str,
                        z_m: float, ref_m: float) -> None:
    """One photo's overlay PNG (``region``: ``ImageResult.region``, with the finder's ``outline_px``)."""
    fin = region.get("finder") or {}
    l_px = (fit or {}).get("l_px", float("nan"))
    text = [f"{method}: l = {l_px:.2f} px, Z = {z_m:.3f} m (reference {ref_m:.3f} m)",
            f"{fin.get('chosen', {}).get('polarity', region.get('polarity', '?'))} target, score "
            f"{fin.get('chosen', {}).get('score', float('nan')):.2f}"
            + (f"; CLOSE: runner-up {fin['runners_up'][0]['score']:.2f}" if fin.get("close") else "")]
    rgb, _ = photo_overlay(image, fin.get("outline_px", []), fit, points, fin.get("runner_up_contours_px", ()), text)
    ok, buf = cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    atomic_write_bytes(Path(path), buf.tobytes())
