"""What a twin of photos of a board of separate squares needs, measured on them: ``measure_squares``.

The chessboard's twin (``measure.measure_chessboard``) reads its camera from OpenCV's grid and its tone at the
junctions where four squares meet.  A board of separate squares (Zhang's: a model file of quads, ``--model``) has
neither, so here:

- **Camera and poses.**  Each photo's squares are the board study's (``photo_model.board_lines``: the model's quads
  found and matched, their side lines fitted to Canny-Devernay points), their corners the side lines' crossings;
  Zhang's calibration on them (``board.calibrate``: k1, k2, as his), then ``cv2.solvePnP`` per photo with that
  camera (t in model units).
- **Levels and noise.**  ``photo_model.noise``: the squares' insides (dark) and a ring around each (white), each
  region's SD about its own quadratic (shading across the board does not count).  A white is saturated where its
  SD is below half the dark's (``levels.saturated``'s rule) or more than ``CLIPPED_SHARE`` of it sits at its top
  (``white_top``, the ring's 99th percentile: the twin clips there, its level before the clip from that share).
- **Blur.**  ``photo_model.blur``: the ERF σ per axis, and the pooled ESF and its overshoot (``measure.edge_shape``:
  sharpening, which the twin fits, ``sharpening``).  JPEG photos: what their JPEG adds to σ
  (``jpeg_synthetic.jpeg_blur_px``).
- **Lens shading.**  The white gaps' levels (``gap_points``: midway between neighbouring squares) at the points
  the pose projects them to (``shading.light_levels``).
- **Tone.**  Not measurable without junctions: 8-bit photos take the power given (``tone_power``; the twin's
  default is sRGB's 2.2), 16-bit photos are taken as linear (raw) values, unchecked; ``note`` says so.

The record has the chessboard's keys where they mean the same (``derive.twin_texts`` reads both), with ``board``
saying which board it is, ``t_model`` for the pose's translation and no ring or bend.
"""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from scipy.spatial import cKDTree

from edgetruth.errors import InputError
from edgetruth.evaluate.board.calibrate.zhang import calibrate
from edgetruth.evaluate.board.tone.photo_model import blur as edge_blur, board_lines, flat_labels, noise
from edgetruth.evaluate.board.twin.jpeg_synthetic import jpeg_blur_px
from edgetruth.evaluate.board.twin.measure import edge_shape, jpeg_quality, read_photo
from edgetruth.evaluate.board.twin.shading import light_levels, project


#: a white region with more than this share of its pixels at its largest value is clipped (``photo_model``'s)
CLIPPED_SHARE = 0.3
#: ``gap_points`` keeps points at least this share of a square's side clear of every square
GAP_CLEARANCE = 0.15
#: neighbours: square centres within this factor of each square's nearest neighbour distance
NEIGHBOUR_FACTOR = 1.5


def gap_points(corners: np.ndarray) -> np.ndarray:
    """(G, 2) points of the white ground between separate squares ``corners`` (S, 4, 2, model units): the midpoints
    of each square's centre and its neighbours' (within ``NEIGHBOUR_FACTOR`` of its nearest one), kept where they
    lie ``GAP_CLEARANCE`` of a side clear of every square, each once, in a fixed order."""
    from matplotlib.path import Path as Polygon  # lazy: matplotlib is heavy

    q = np.asarray(corners, float)
    centre = q.mean(axis=1)
    side = float(np.median(np.linalg.norm(q - np.roll(q, -1, axis=1), axis=2)))
    tree = cKDTree(centre)
    nearest = tree.query(centre, k=2)[0][:, 1]
    mids = []
    for i, c in enumerate(centre):
        for j in tree.query_ball_point(c, NEIGHBOUR_FACTOR * nearest[i]):
            if j > i:
                mids.append(0.5 * (c + centre[j]))
    mids = np.asarray(mids, float).reshape(-1, 2)
    clear = np.ones(len(mids), bool)
    for quad in q:  # inside a square grown by the clearance (its corners pushed out from its centre)
        c = quad.mean(axis=0)
        grown = c + (quad - c) * (1.0 + 2.0 * GAP_CLEARANCE * side / np.linalg.norm(quad - c, axis=1).mean())
        clear &= ~Polygon(grown).contains_points(mids)
    mids = mids[clear]
    if not len(mids):
        return mids
    groups = cKDTree(mids).query_ball_point(mids, 0.05 * side)
    return np.array([mids[i] for i, g in enumerate(groups) if min(g) == i]).reshape(-1, 2)


def white_saturated(dark: dict, white: dict) -> bool:
    """A white region is saturated where its noise SD is below half the dark's (``levels.saturated``'s rule) or
    more than ``CLIPPED_SHARE`` of it sits at its top (``photo_model.region_noise``'s records)."""
    return bool((dark["sd"] > 0 and white["sd"] < 0.5 * dark["sd"]) or white["at_max_fraction"] > CLIPPED_SHARE)


def assumed_tone(scale: float, tone_power: float, board: str) -> dict:
    """The tone of photos of a ``board`` without junctions to measure it at (separate squares, circles): 8-bit photos
    (``scale`` 255) the power given, 16-bit ones linear (raw), unchecked; ``note`` says so."""
    if scale == 255.0:
        return {"power": None, "ci": None, "output_gamma": float(tone_power),
                "note": f"not measurable on {board} (no junctions); a power of {tone_power:g} assumed (--tone-power)"}
    return {"power": None, "ci": None, "output_gamma": 1.0,
            "note": "16-bit photos, taken as a linear sensor's values (raw) with a black level; not checked (no "
                    f"junctions on {board} to read a tone at)"}


def measure_squares(photos: list[Path], model, tone_power: float = 2.2, channel: str = "luma",
                    progress=None) -> dict:
    """Every measurement a twin of these photos of the board ``model`` (``board.model.BoardModel``, separate
    squares) needs (module docstring), as JSON-ready data: ``rms_px``, ``K``, ``dist``, ``tone`` and one record per
    photo on which the board is found; ``left_out`` names the others and why (fewer than 3 left: an
    ``InputError``).  ``tone_power``: the 8-bit photos' tone (stored = linear^(1/power)), assumed.
    ``progress``: wraps an iterable of photos in a progress bar."""
    photos = [Path(p) for p in photos]
    gaps = gap_points(model.corners)
    found, left_out = [], []
    scale, size, union = None, None, 0
    for p in photos if progress is None else progress(photos):
        img, scale, bits = read_photo(p, channel, scale)
        if size is not None and img.shape != size:
            raise InputError(f"{p}: {img.shape[1]}x{img.shape[0]} px among photos of {size[1]}x{size[0]}; give "
                             "photos of one camera at one size")
        size, union = img.shape, union | bits
        lines = board_lines(img, model)
        if lines is None:
            left_out.append({"photo": p.name, "why": f"the model's {len(model)} squares were not found on it"})
            continue
        found.append((p, img, lines))
    if len(found) < 3:
        raise InputError(f"the model's squares were found on {len(found)} of {len(photos)} photos (left out: "
                         f"{', '.join(o['photo'] for o in left_out) or 'none'}); a twin needs 3 or more for Zhang's "
                         "calibration")
    h, w = size
    cal = calibrate(model.corners, [ln.corners for _, _, ln in found], (w, h))
    K, dist = cal.K, cal.dist
    rows = []
    for p, img, lines in found:
        ok = np.all(np.isfinite(lines.corners), axis=2)
        obj = np.c_[model.corners[ok], np.zeros(int(ok.sum()))]
        _, rvec, tvec = cv2.solvePnP(obj, lines.corners[ok], K, dist, flags=cv2.SOLVEPNP_ITERATIVE)
        proj, _ = cv2.projectPoints(obj, rvec, tvec, K, dist)
        res = np.linalg.norm(proj.reshape(-1, 2) - lines.corners[ok], axis=1)
        top = float(img.max())  # 16-bit: a value ten pixels or more share is a clip; 8-bit: 255
        clip = 255.0 if scale == 255.0 else (top if np.count_nonzero(img == top) >= 10 else None)
        nz = noise(img, lines)
        ring = img[flat_labels(img.shape, lines)[1] > 0]
        dark, white = nz["black"], nz["white"]
        if not (dark["mean"] > 0):
            raise InputError(f"{p}: its dark squares read {dark['mean']:.3g}, so the print's contrast cannot be "
                             "measured; leave it out or give photos whose blacks are not clipped")
        sat = white_saturated(dark, white)
        b = edge_blur(img, lines)
        sx, sy = (b[k]["sigma_px"] for k in ("vertical", "horizontal"))
        q = jpeg_quality(p)
        synthetic = q is not None and np.isfinite(sx + sy)
        R = cv2.Rodrigues(rvec)[0]
        rows.append({
            "photo": p.name, "R": R.tolist(), "t_model": tvec.ravel().tolist(),
            "pose_rms_px": float(np.sqrt(np.mean(res ** 2))), "corners": int(ok.sum()),
            "dark": dark["mean"], "white": white["mean"], "dark_sd": dark["sd"], "white_sd": white["sd"],
            "white_at_max": white["at_max_fraction"], "white_top": float(np.percentile(ring, 99)),
            "white_saturated": sat,
            "sigma_x_px": sx if np.isfinite(sx) else None, "sigma_y_px": sy if np.isfinite(sy) else None,
            **edge_shape(b),
            "jpeg_sigma_px": jpeg_blur_px(img.shape, lines, sx, sy, dark["mean"], white["mean"], q[0])
            if synthetic else None,
            "noise_before_jpeg": None,  # the chessboard's measure reads it at junction-bounded squares' centres
            "jpeg_quality": None if q is None else {"quality": q[0], "exact": q[1]},
            "light_levels": light_levels(img, project(gaps, R, tvec.ravel(), K, dist), clip),
        })
    tone = assumed_tone(scale, tone_power, "separate squares")
    q = model.corners.reshape(-1, 2)
    return {"board": {"kind": "model", "source": model.source, "squares": len(model),
                      "centre_model": (0.5 * (q.min(0) + q.max(0))).tolist(),
                      "side_model": float(np.median(np.linalg.norm(model.corners - np.roll(model.corners, -1, 1),
                                                                   axis=2)))},
            "light_points": gaps.tolist(), "image_size": [w, h], "rms_px": cal.rms_px,
            "K": np.asarray(K).tolist(), "dist": np.asarray(dist).ravel().tolist(), "tone": tone, "photos": rows,
            "full_scale": scale, "max_value": int(max(float(im.max()) for _, im, _ in found)),
            "value_step": (union & -union) if union else 1, "left_out": left_out}
