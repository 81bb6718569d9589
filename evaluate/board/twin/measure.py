"""What a twin of chessboard photos needs, measured on them: ``measure_chessboard`` (``edgetruth twin``'s first step;
a board of separate squares: ``measure_squares``).  Gray or colour photos (read as their luma, or one channel).

Per set: the camera (Zhang's calibration on the line corners), the tone (``measure_tone``), the bit depth, the
largest stored value and the stored step.  Per photo: its pose (``cv2.solvePnP`` in the board study's model order,
``model_order``), the outer ring's cut (``ring_reach``), the squares' levels and noise (and, for 16-bit photos, their
flat patches' for the photon transfer), the ERF blur per axis and the edges' shape (``edge_shape``: overshoot and
pooled ESF, for the sharpening), the light squares' levels (the lens shading), the JPEG
quality its file carries (``jpeg_quality``) and what its JPEG adds to the blur and noise, and the calibration's
bend.  ``derive.twin_texts`` turns the record into the twin's camera and scene; its docstring says how each
measurement sets the twin.
"""
from __future__ import annotations

import math
import struct
from pathlib import Path

import cv2
import numpy as np

from edgetruth.errors import InputError
from edgetruth.evaluate import method_order as mo
from edgetruth.evaluate.board.detect import chessboard as cb
from edgetruth.evaluate.board.detect.levels import saturated, square_levels
from edgetruth.evaluate.board.inputs import BoardInputs
from edgetruth.evaluate.board.measure.grid_corners import DEFAULT_METHOD, grid_points
from edgetruth.evaluate.board.tone.fit import estimate_power
from edgetruth.evaluate.board.tone.photo_model import blur as edge_blur, board_lines
from edgetruth.evaluate.board.twin.jpeg_synthetic import jpeg_blur_px, noise_before_jpeg
from edgetruth.evaluate.board.twin.shading import light_levels, light_square_centres, project
from edgetruth.evaluate.calibration import calibrate_photos
from edgetruth.image_io import read_gray_scaled


#: 16-bit photos whose edges read a tone power outside this band (``raw_tone``) are not a linear sensor's values
RAW_POWER_BAND = (0.8, 1.25)
#: 16-bit photos' photon transfer: the share of a square's side its centre patch spans (``flat_noise``)
FLAT_PATCH_SHARE = 0.5
#: IJG (JPEG Annex K) luminance quantisation table, natural (row-major) order
IJG_LUMA = np.array([
    16, 11, 10, 16, 24, 40, 51, 61, 12, 12, 14, 19, 26, 58, 60, 55, 14, 13, 16, 24, 40, 57, 69, 56,
    14, 17, 22, 29, 51, 87, 80, 62, 18, 22, 37, 56, 68, 109, 103, 77, 24, 35, 55, 64, 81, 104, 113, 92,
    49, 64, 78, 87, 103, 121, 120, 101, 72, 92, 95, 98, 112, 100, 103, 99])
#: zig-zag index -> natural index (a DQT segment stores its table in zig-zag order)
ZIGZAG = np.array([
    0, 1, 8, 16, 9, 2, 3, 10, 17, 24, 32, 25, 18, 11, 4, 5, 12, 19, 26, 33, 40, 48, 41, 34, 27, 20, 13, 6, 7, 14, 21,
    28, 35, 42, 49, 56, 57, 50, 43, 36, 29, 22, 15, 23, 30, 37, 44, 51, 58, 59, 52, 45, 38, 31, 39, 46, 53, 60, 61,
    54, 47, 55, 62, 63])


# --- the photos' files ------------------------------------------------------------------------------
def ijg_table(quality: int) -> np.ndarray:
    """The IJG luminance table at ``quality`` (1-100; libjpeg's ``jpeg_quality_scaling``), natural order."""
    q = int(quality)
    scale = 5000 // q if q < 50 else 200 - 2 * q
    return np.clip((IJG_LUMA * scale + 50) // 100, 1, 255)


def jpeg_quality(path) -> tuple[int, bool] | None:
    """(quality, exact) of a JPEG file's first luminance table against the IJG tables, or None for a file that is
    not a baseline JPEG with one: ``exact`` when it is the IJG table at that quality, else the nearest (least
    summed |log ratio|)."""
    data = Path(path).read_bytes()
    if data[:2] != b"\xff\xd8":
        return None
    i = 2
    while i + 4 <= len(data) and data[i] == 0xFF:
        marker, length = data[i + 1], struct.unpack(">H", data[i + 2:i + 4])[0]
        if marker == 0xDB:  # DQT: one or more tables, each (precision | id) then 64 or 128 bytes
            j, end = i + 4, i + 2 + length
            while j < end:
                precision, ident = data[j] >> 4, data[j] & 15
                size = 128 if precision else 64
                raw = data[j + 1:j + 1 + size]
                values = np.frombuffer(raw, ">u2" if precision else np.uint8).astype(int)
                if ident == 0 and values.size == 64:
                    table = np.empty(64, int)
                    table[ZIGZAG] = values
                    err = [float(np.abs(np.log(table / ijg_table(q))).sum()) for q in range(1, 101)]
                    best = int(np.argmin(err)) + 1
                    return best, bool(err[best - 1] == 0.0)
                j += 1 + size
        if marker == 0xDA:  # start of scan: no table before it
            return None
        i += 2 + length
    return None


def read_photo(path, channel: str, scale: float | None) -> tuple[np.ndarray, float, int]:
    """(gray image, full scale, its stored values OR-ed) of one photo of a set whose photos so far have full scale
    ``scale`` (None: the first).  A colour photo is read as its luma (float, ``channel``), its full scale the file's
    (255 for an 8-bit colour JPEG); the OR (its trailing zeros: the stored step) is 0 for float values.  An
    ``InputError`` for a photo that is not 8- or 16-bit, or not of the set's depth (one camera's output)."""
    img, s = read_gray_scaled(path, channel=channel)
    if s not in (255.0, 65535.0):
        raise InputError(f"{path}: {img.dtype} values; give 8-bit or 16-bit photos (a twin renders 8-bit or raw "
                         "16-bit images)")
    if scale is not None and s != scale:
        raise InputError(f"{path}: {'8' if s == 255 else '16'}-bit among {'8' if scale == 255 else '16'}-bit "
                         "photos; give photos of one bit depth (one camera's output)")
    bits = int(np.bitwise_or.reduce(img, axis=None)) if np.issubdtype(img.dtype, np.integer) else 0
    return img, s, bits


# --- measurements -----------------------------------------------------------------------------------
def edge_shape(blur: dict) -> dict:
    """A photo's edges' shape per axis from ``photo_model.blur``: ``overshoot_pct`` (the larger of the pooled ESF's
    over- and undershoot, % of the step: sharpening) and ``esf`` (the pooled normalised ESF, [t px, value] lists, 5
    decimals), for ``sharpening.fit_sharpening``; empty where no side was measured."""
    out = {"overshoot_pct": {}, "esf": {}}
    for axis, name in (("x", "vertical"), ("y", "horizontal")):
        b = blur.get(name)
        if not b or not len(b["esf"][0]):
            return {}
        out["overshoot_pct"][axis] = float(max(b["overshoot_pct"], b["undershoot_pct"]))
        out["esf"][axis] = [np.round(np.asarray(v, float), 5).tolist() for v in b["esf"]]
    return out


def model_order(view, corners: np.ndarray) -> np.ndarray:
    """The model's (S, 4, 2) square corners taken from ``corners`` (OpenCV's order), via the view's grid."""
    q = view.squares.corners.reshape(-1, 2)
    d = np.linalg.norm(q[:, None, :] - view.inner[None, :, :], axis=2)
    k = np.argmin(d, axis=1)
    if not np.all(d[np.arange(len(q)), k] < 1e-6):  # pragma: no cover - the grid's squares are its inner corners
        raise RuntimeError("a model corner is not one of OpenCV's inner corners")
    return corners[k].reshape(view.squares.corners.shape)


def ring_reach(img, K, dist, rvec, tvec, cols: int, rows: int) -> dict:
    """Median reach (in squares) of the dark outer-ring squares beyond the outermost inner corners, along x and y."""
    reach = {"x": [], "y": []}
    s = np.linspace(0.0, 1.2, 241)
    for r in range(-1, rows):
        for c in range(-1, cols):
            if (r + c) % 2 or not (r in (-1, rows - 1) or c in (-1, cols - 1)):
                continue
            for axis, edge in (("x", c == -1), ("x", c == cols - 1), ("y", r == -1), ("y", r == rows - 1)):
                if not edge or (axis == "x" and r in (-1, rows - 1)) or (axis == "y" and c in (-1, cols - 1)):
                    continue  # the ring's corner squares: both cuts meet there
                if axis == "x":
                    x = -s if c == -1 else (cols - 1) + s
                    y = np.full_like(s, r + 0.5)
                else:
                    y = -s if r == -1 else (rows - 1) + s
                    x = np.full_like(s, c + 0.5)
                p, _ = cv2.projectPoints(np.stack([x, y, 0 * x], 1), rvec, tvec, K, dist)
                p = p.reshape(-1, 2)
                ok = (p[:, 0] >= 0) & (p[:, 0] <= img.shape[1] - 1) & (p[:, 1] >= 0) & (p[:, 1] <= img.shape[0] - 1)
                if not ok.all():
                    continue
                v = cv2.remap(img.astype(np.float32), p[:, 0:1].astype(np.float32), p[:, 1:2].astype(np.float32),
                              cv2.INTER_LINEAR).ravel()
                dark, white = np.median(v[20:60]), np.max(v)
                above = np.flatnonzero(v[20:] > 0.5 * (dark + white))
                if above.size:
                    reach[axis].append(float(s[20 + above[0]]))
    return {k: float(np.median(v)) if v else float("nan") for k, v in reach.items()}


def measure_chessboard(photos: list[Path], pattern: tuple[int, int], channel: str = "luma",
                       progress=None) -> dict:
    """Every measurement a twin of these chessboard photos needs (module docstring), as JSON-ready data:
    ``rms_px``, ``K``, ``dist``, ``tone`` and one record per photo (pose with t in squares, ring, levels, blur,
    JPEG quality, bend) on which the board is found; ``left_out`` names the others and why (fewer than 3 left: an
    ``InputError``).
    ``progress``: wraps an iterable of photos in a progress bar (the calibration's pass, then the measurements')."""
    photos = [Path(p) for p in photos]
    model = cb.chessboard_model(pattern, 1.0)
    light_centres = light_square_centres(pattern)
    grids = []  # each photo's edge points, measured once: the calibration's refits and the poses use them

    def finder(image, pattern_size):
        grids.append(grid_points(image, pattern_size))
        return grids[-1]

    cal, results = calibrate_photos([(p.name, p) for p in photos], pattern, 1.0, channel=channel,
                                    corner_finder=finder, undistort_lines=True, progress=progress)
    # a photo without the board is left out, as calibrate leaves it out (the calibration needs 3 boards found)
    left_out = [{"photo": p.name, "why": f"the {pattern[0]}x{pattern[1]} board was not found on it"}
                for p, r in zip(photos, results) if not r.found]
    K, dist = cal.K, cal.dist
    rows, images, used = [], [], []
    scale, union = None, 0  # the photos' full scale, and every stored value OR-ed (its trailing zeros: the step)
    for i, (p, grid) in enumerate(zip(photos if progress is None else progress(photos), grids)):
        if not results[i].found:
            continue
        img, scale, bits = read_photo(p, channel, scale)
        union |= bits
        view = cb.find_squares(img, model)
        if view is None:  # OpenCV's corners without the board study's squares: the study could not pair it
            left_out.append({"photo": p.name, "why": "the board study's squares were not found on it"})
            continue
        mc = model_order(view, grid.corners((K, dist)))
        board = np.c_[model.corners.reshape(-1, 2), np.zeros(mc.size // 2)]
        ok = np.all(np.isfinite(mc.reshape(-1, 2)), axis=1)
        _, rvec, tvec = cv2.solvePnP(board[ok], mc.reshape(-1, 2)[ok], K, dist, flags=cv2.SOLVEPNP_ITERATIVE)
        proj, _ = cv2.projectPoints(board[ok], rvec, tvec, K, dist)
        res = np.linalg.norm(proj.reshape(-1, 2) - mc.reshape(-1, 2)[ok], axis=1)
        top = int(img.max())  # 16-bit: a value ten pixels or more share is a clip; 8-bit: 255
        clip = 255 if scale == 255.0 else (top if np.count_nonzero(img == top) >= 10 else None)
        lev = square_levels(img, view.squares.corners)
        flat = None
        if scale != 255.0:  # the photon transfer's levels: patches of half a square, about their planes
            quads = view.squares.corners
            side = float(np.nanmedian(np.linalg.norm(quads - np.roll(quads, -1, axis=1), axis=2)))
            half = max(2, int(FLAT_PATCH_SHARE * side / 2))
            fl = square_levels(img, quads, half_px=half, plane=True, clip=clip)
            flat = {"half_px": half, "dark": fl.dark, "white": fl.white, "dark_sd": fl.dark_sd, "white_sd": fl.white_sd}
        lines = board_lines(img, model)
        blur = {} if lines is None else edge_blur(img, lines)
        if lev.dark <= 0:
            raise InputError(f"{p}: its dark squares read 0, so the print's contrast cannot be measured; leave it out "
                             "or give photos whose blacks are not clipped")
        shade = light_levels(img, project(light_centres, cv2.Rodrigues(rvec)[0], tvec.ravel(), K, dist), clip)
        q = jpeg_quality(p)
        sx, sy = (blur.get(k, {}).get("sigma_px") for k in ("vertical", "horizontal"))
        synthetic = q is not None and sx is not None and sy is not None and math.isfinite(sx + sy)
        jpeg_px = jpeg_blur_px(img.shape, lines, sx, sy, lev.dark, lev.white, q[0]) if synthetic else None
        before = (noise_before_jpeg(img.shape, lines, view.squares.corners, sx, sy, lev.dark, lev.white,
                                    lev.white_sd, lev.dark_sd, q[0]) if synthetic and not saturated(lev) else None)
        rows.append({
            "photo": p.name, "R": cv2.Rodrigues(rvec)[0].tolist(), "t_squares": tvec.ravel().tolist(),
            "pose_rms_px": float(np.sqrt(np.mean(res ** 2))),
            "ring": ring_reach(img, K, dist, rvec, tvec, *pattern),
            "dark": lev.dark, "white": lev.white, "dark_sd": lev.dark_sd, "white_sd": lev.white_sd,
            "white_saturated": bool(saturated(lev)),
            "sigma_x_px": sx, "sigma_y_px": sy, "jpeg_sigma_px": jpeg_px, "noise_before_jpeg": before,
            "jpeg_quality": None if q is None else {"quality": q[0], "exact": q[1]},
            "light_levels": shade,
            **edge_shape(blur),
            **({} if flat is None else {"flat_noise": flat}),
        })
        images.append(img)
        used.append(i)
    if len(rows) < 3:
        raise InputError(f"the board study's squares were found on {len(rows)} of {len(photos)} photos (left out: "
                         f"{', '.join(o['photo'] for o in left_out)}); a twin study compares 3 or more")
    # each photo's quadratic bend (the calibration's bend check, one per photo it calibrated on), in squares: the
    # calibration's unit is one square
    quad = (cal.board_bend or {}).get("quadratic") or {}
    views = [i for i, r in enumerate(results) if r.found]
    if quad.get("views") == len(views):
        bends = dict(zip(views, zip(quad["coefficients_mm"], quad["scale_mm"])))
        for r, i in zip(rows, used):
            c, sc = bends[i]
            r["bend_squares"] = {"coefficients": [v / 1e3 for v in c], "scale": sc / 1e3}
    photos = [photos[i] for i in used]
    tone = measure_tone(photos, images, rows, model) if scale == 255.0 else raw_tone(photos, images, rows, model)
    return {"pattern": list(pattern), "image_size": list(cal.image_size), "rms_px": cal.rms_px,
            "K": np.asarray(K).tolist(),
            "dist": np.asarray(dist).ravel().tolist(), "tone": tone, "photos": rows,
            "full_scale": scale, "max_value": int(max(int(im.max()) for im in images)),
            "value_step": (union & -union) if union else 1, "left_out": left_out}


def raw_tone(photos, images, rows, model) -> dict:
    """16-bit photos are taken as a linear sensor's values (raw); ``measure_tone`` checks it on their stored values.
    A linear sensor's edges are symmetric steps whatever its black level (an ERF fit does not see an offset), so
    they read a power of 1; a 16-bit export through a tone curve reads its curve's (1.8 at ProPhoto's, ~2.2 at
    sRGB's: ``test_measure``).  An ``InputError`` when the power lies outside ``RAW_POWER_BAND`` and its 95 %
    interval leaves out 1; else the tone as measured, with ``output_gamma`` 1 and the reading in ``note``."""
    tone = measure_tone(photos, images, rows, model, full_scale=65535.0)
    words = "16-bit photos, taken as a linear sensor's values (raw) with a black level"
    if tone["power"] is None:
        return {**tone, "output_gamma": 1.0, "note": f"{words}; not checked: {tone['note']}"}
    power, (lo, hi) = tone["power"], tone["ci"]
    if not RAW_POWER_BAND[0] <= power <= RAW_POWER_BAND[1] and not lo <= 1.0 <= hi:
        raise InputError(f"{Path(photos[0]).name} ... ({len(photos)} 16-bit photos): their edges read a tone power of "
                         f"{power:.2f} (95 % {lo:.2f}-{hi:.2f}, at the chessboard's junctions) where a linear sensor's "
                         "read 1, so the values carry a tone curve (a 16-bit export?); give the camera's linear raw "
                         "values (e.g. dcraw -4 -T), or 8-bit photos, whose tone the twin renders")
    return {**tone, "output_gamma": 1.0,
            "note": f"{words}; their edges read a power of {power:.3f} (95 % {lo:.3f}-{hi:.3f}; a linear sensor's "
                    f"read 1)"}


def measure_tone(photos, images, rows, model, full_scale: float = 255.0) -> dict:
    """``tone_fit.estimate_power`` (ERF4P-fixed11) on the unsaturated photos -> {power, ci, photos, output_gamma}:
    ``output_gamma`` 1 (linear) when the 95 % interval holds 1, else the power.  Too few unsaturated photos (or no
    power found): linear, and ``note`` says why.  ``full_scale``: the stored values' (65535 for 16-bit photos)."""
    keep = [i for i, r in enumerate(rows) if not r["white_saturated"]]
    if len(keep) < 3:
        return {"power": None, "ci": None, "photos": [rows[i]["photo"] for i in keep], "output_gamma": 1.0,
                "note": f"{len(keep)} unsaturated photo(s): too few to measure the tone; linear assumed"}
    method, options = mo.resolve(DEFAULT_METHOD, mo.study_options())
    inp = BoardInputs([photos[i] for i in keep], model)
    try:
        fit = estimate_power(inp, [images[i] for i in keep], [full_scale] * len(keep), "ERF4P-fixed11", method,
                             options)
    except InputError as exc:
        return {"power": None, "ci": None, "photos": [rows[i]["photo"] for i in keep], "output_gamma": 1.0,
                "note": f"no tone measured ({exc}); linear assumed"}
    lo, hi = fit.ci
    gamma = 1.0 if lo <= 1.0 <= hi else round(float(fit.power), 2)
    return {"power": float(fit.power), "ci": [float(lo), float(hi)], "photos": fit.photos,
            "per_photo": fit.per_photo, "output_gamma": gamma}
