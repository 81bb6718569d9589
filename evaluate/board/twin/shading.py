"""A chessboard photo set's lens shading: how the light squares' level falls off across the image.

A twin's board is lit by its light (``render.scene.mitsuba_scene``: a small square area light at
``light_position_m`` in the camera frame, aimed at the board's centre, whose irradiance there is the group's
``irradiance_w_m2``), so its light squares already vary as that light's cos_b cos_l / r² across the board.  What the
photos show beyond that, the same at the same place in every photo, is the lens's: its relative illumination, the
renderer's ``1 + a2 h² + a4 h⁴`` (``shading_a2``, ``shading_a4``; h the field height, 1 at the image corner,
``render.optics.prediction.field_height``).

``light_levels`` measures each photo's light squares (the board study's chessboard model: the light squares among
the dark ones) as the median of a patch at the point its pose projects them to; ``fit_shading`` fits
level = W_i · light(X) · (1 + a2 h² + a4 h⁴) over the unsaturated photos (one W_i per photo, relative residuals;
``scipy.optimize.least_squares``).  A set whose levels cannot separate the lens from the light (fewer than
``MIN_PHOTOS`` photos or ``MIN_LEVELS`` levels) keeps no shading.
"""
from __future__ import annotations

import math

import cv2
import numpy as np
from scipy.optimize import least_squares

from edgetruth.evaluate.board.detect import chessboard as cb
from edgetruth.evaluate.board.detect.levels import light_centres, patches_at


#: half width (px) of the patch whose median is a light square's level (a 7 x 7 patch)
PATCH_HALF_PX = 3
#: what the fit needs: unsaturated photos and light-square levels over them
MIN_PHOTOS, MIN_LEVELS = 2, 20


def light_square_centres(pattern: tuple[int, int]) -> np.ndarray:
    """(L, 2) the light squares' centres among the dark ones, in the board study's chessboard model (squares; inner
    corner (0, 0) at the origin), in a fixed order: ``levels.light_centres`` of the model's dark squares."""
    return light_centres(cb.chessboard_model(tuple(pattern), 1.0).corners)


def project(points_model: np.ndarray, R, t, K, dist) -> np.ndarray:
    """(N, 2) image positions (px) of model points (squares, z = 0) under the pose (R, t in squares)."""
    X = np.c_[np.asarray(points_model, float), np.zeros(len(points_model))]
    uv, _ = cv2.projectPoints(X, cv2.Rodrigues(np.asarray(R, float))[0], np.asarray(t, float), np.asarray(K, float),
                              np.asarray(dist, float))
    return uv.reshape(-1, 2)


def light_levels(image: np.ndarray, uv: np.ndarray, clip: float | None = None) -> list[float | None]:
    """The median of a (2 ``PATCH_HALF_PX`` + 1)² patch at each of ``uv`` (the nearest pixel centre); None where the
    patch leaves the image or reaches ``clip`` (a clip flattens the shading it measures)."""
    patches, inside = patches_at(image, uv, PATCH_HALF_PX)
    level = np.median(patches, axis=1)
    ok = np.ones(len(patches), bool) if clip is None else patches.max(axis=1) < clip
    out: list[float | None] = [None] * len(inside)
    for i, v, good in zip(np.flatnonzero(inside), level, ok):
        out[i] = float(v) if good else None
    return out


def light_falloff(points_cam_m: np.ndarray, centre_cam_m: np.ndarray, normal_cam: np.ndarray,
                  light_m: np.ndarray) -> np.ndarray:
    """The twin's light at board points relative to the board's centre: cos_b cos_l / r² of a small source at
    ``light_m`` facing ``centre_cam_m`` (camera frame, m), 1 at the centre."""
    light_m = np.asarray(light_m, float)
    aim = (centre_cam_m - light_m) / np.linalg.norm(centre_cam_m - light_m)

    def e(points):
        v = light_m - np.atleast_2d(points)
        r = np.linalg.norm(v, axis=1)
        return np.clip(v @ normal_cam / r, 0, None) * np.clip(-(v @ aim) / r, 0, None) / r ** 2

    return e(points_cam_m) / e(centre_cam_m)[0]


def lens_shading(h: np.ndarray, a2: float, a4: float) -> np.ndarray:
    """The renderer's shading polynomial 1 + a2 h² + a4 h⁴."""
    h = np.asarray(h, float)
    return 1.0 + a2 * h ** 2 + a4 * h ** 4


def fit_shading(photos: list[dict]) -> dict:
    """(a2, a4) of ``level = W_i · light · (1 + a2 h² + a4 h⁴)`` over photos, each {``level``: linear levels,
    ``light``: ``light_falloff`` at them, ``h``: their field heights}; -> {a2, a4, levels, photos, rms_before,
    rms_after} (RMS of the relative residuals with no shading and with the fitted one), or {a2: 0, a4: 0, note}
    when there is too little to fit."""
    use = []
    for p in photos:
        ok = np.isfinite(p["level"]) & np.isfinite(p["light"]) & (p["light"] > 0)
        if ok.sum() >= 3:
            use.append({k: np.asarray(p[k], float)[ok] for k in ("level", "light", "h")})
    n = sum(len(p["level"]) for p in use)
    if len(use) < MIN_PHOTOS or n < MIN_LEVELS:
        return {"a2": 0.0, "a4": 0.0, "levels": n, "photos": len(use),
                "note": f"{len(use)} unsaturated photo(s), {n} light-square levels: too few to fit the lens "
                        "shading; none"}

    def resid(x, shading=True):
        a2, a4 = (x[0], x[1]) if shading else (0.0, 0.0)
        return np.concatenate([(x[2 + i] * p["light"] * lens_shading(p["h"], a2, a4) - p["level"]) / p["level"]
                               for i, p in enumerate(use)])

    w0 = [float(np.median(p["level"] / p["light"])) for p in use]
    flat = least_squares(lambda w: resid(np.r_[0.0, 0.0, w], False), w0)
    fit = least_squares(resid, np.r_[0.0, 0.0, w0], bounds=(np.r_[-1.0, -1.0, [0.0] * len(use)],
                                                                  np.r_[10.0, 10.0, [np.inf] * len(use)]))
    a2, a4 = float(fit.x[0]), float(fit.x[1])
    return {"a2": a2, "a4": a4, "levels": n, "photos": len(use),
            "rms_before": float(math.sqrt(np.mean(flat.fun ** 2))),
            "rms_after": float(math.sqrt(np.mean(fit.fun ** 2)))}
