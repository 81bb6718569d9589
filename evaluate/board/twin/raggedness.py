"""Print raggedness: how far each printed side wanders about a smooth curve, beyond what noise makes it wander.

A side's points (a method's, as the board study assigns them) scatter about the side's straight line for three
reasons: the lens and a bent sheet bow the side (smooth over the side), the pixel noise moves each point, and the
print's own edge is ragged (toner, ink spread, paper fibres, seen through the camera's blur).  The twin renders
the first two and prints a perfect edge, so the third is a term of the real error budget it leaves out.

Measured per side (``side_stats``): the points' signed distance r to the side's line against their position t
along it, a polynomial of degree ``DETREND_DEGREE`` in t taken off (the bow: the lens's and a bend's, smooth over
one side), and the sum of squares left, with its degrees of freedom and the lag-1 correlation of neighbouring
points' residuals (print raggedness correlated over several pixels reads > 0; per-pixel noise about 0).  Pooled
over a photo's sides (``pooled``): the detrended SD, s_meas.

What noise alone leaves (the floor), two ways, neither from the figures the twin is judged on:

- **rendered floor** (``floor_image``): a synthetic image of the photo's own squares (``jpeg_synthetic
  .synthetic_board``: its side lines, its dark and white levels, an ERF of its measured σ per axis across each
  side, straight perfect edges), with Gaussian noise whose variance is linear in the level through the photo's
  measured dark and white SDs (``photo_model.noise``), stored as 8-bit; the same method and the same sides and
  detrend on it give s_floor;
- **Cramér-Rao bound** (``crb_sd``): the bound on one profile row's edge position (``evaluate.crb``, four
  unknowns, 11 px) at the side's σ and noise over contrast; a method is rarely efficient, so this floor is lower.

A JPEG photo's floor goes through a JPEG at the photo's own quality (its 8x8 blocks move an edge block by block).

The print's raggedness as imaged is ``excess`` = sqrt(max(s_meas² − s_floor², 0)).  Tested on a synthetic square
whose sides are displaced by a known smooth random function (``tests/evaluate/board/twin/test_raggedness.py``).
What the rendered floor leaves out: sharpening and demosaicing (its noise is white before any JPEG and its ESF an
ERF), so on a sharpened photo part of the excess may be theirs; its noise before the JPEG is the photo's after it
(a JPEG takes some noise off, so the floor's noise is if anything lower than the photo's, and the excess an upper
bound).
"""
from __future__ import annotations

import math

import numpy as np

from edgetruth import console
from edgetruth.evaluate import method_order as mo
from edgetruth.evaluate.board.detect.chessboard import settle_parity
from edgetruth.evaluate.board.detect.squares import board_candidates, board_squares
from edgetruth.evaluate.board.measure.rows import method_row
from edgetruth.evaluate.board.sides.lines import square_map
from edgetruth.evaluate.board.tone.photo_model import blur, board_lines, noise
from edgetruth.evaluate.board.twin.jpeg_synthetic import synthetic_board
from edgetruth.evaluate.board.twin.measure import jpeg_quality
from edgetruth.render.sensor.pipeline import jpeg_round_trip


#: degree of the polynomial (in the position along a side) taken off each side's residuals: a lens's bow and a
#: bent sheet are smooth over one side
DETREND_DEGREE = 2
#: fewest points a side needs to count (the detrend takes DETREND_DEGREE + 1 of them)
MIN_SIDE_POINTS = 12
#: the rendered floor's noise draw (fixed: the measurement is a pure function of the photo)
FLOOR_SEED = 47


def side_stats(x, y, labels, normal: np.ndarray, offset: np.ndarray, degree: int = DETREND_DEGREE) -> dict:
    """Per side (arrays of shape (S, 4)): ``n`` points, ``ss`` sum of squared residuals after the detrend,
    ``dof`` their degrees of freedom, ``lag1`` the correlation of neighbouring residuals along the side (NaN with
    too few points), ``length_px`` the span of the points along the side.  ``labels``: each point's side label
    ``4 * square + side`` (−1: none); ``normal``, ``offset``: the side lines n . p = d (``sides.SideFits``)."""
    x, y, labels = np.asarray(x, float), np.asarray(y, float), np.asarray(labels)
    shape = offset.shape
    n = np.zeros(shape, int)
    ss, dof, lag1, span = (np.full(shape, np.nan) for _ in range(4))
    ok = labels >= 0
    order = np.argsort(labels[ok], kind="stable")
    lab, px, py = labels[ok][order], x[ok][order], y[ok][order]
    starts = np.flatnonzero(np.r_[True, lab[1:] != lab[:-1]])
    for a, b in zip(starts, np.r_[starts[1:], len(lab)]):
        s, k = divmod(int(lab[a]), 4)
        nv, d = normal[s, k], offset[s, k]
        if b - a < MIN_SIDE_POINTS or not np.all(np.isfinite(nv)):
            continue
        t = -nv[1] * px[a:b] + nv[0] * py[a:b]
        r = nv[0] * px[a:b] + nv[1] * py[a:b] - d
        i = np.argsort(t)
        t, r = t[i], r[i]
        tc = (t - t.mean()) / max(np.ptp(t) / 2.0, 1e-9)
        e = r - np.polyval(np.polyfit(tc, r, degree), tc)
        n[s, k], ss[s, k], dof[s, k], span[s, k] = b - a, float(e @ e), b - a - degree - 1, float(np.ptp(t))
        den = float(e @ e)
        lag1[s, k] = float(e[1:] @ e[:-1] / den) if den > 0 else np.nan
    return {"n": n, "ss": ss, "dof": dof, "lag1": lag1, "length_px": span}


def pooled(stats: list[dict]) -> dict:
    """Over sides (of one photo or several): the detrended SD sqrt(Σ ss / Σ dof) (px), the sides, the median lag-1
    correlation."""
    ss = np.concatenate([s["ss"].ravel() for s in stats])
    dof = np.concatenate([s["dof"].ravel() for s in stats])
    lag = np.concatenate([s["lag1"].ravel() for s in stats])
    ok = np.isfinite(ss) & (dof > 0)
    if not ok.any():
        return {"sd_px": float("nan"), "sides": 0, "lag1": float("nan")}
    return {"sd_px": math.sqrt(float(ss[ok].sum() / dof[ok].sum())), "sides": int(ok.sum()),
            "lag1": float(np.nanmedian(lag[ok]))}


def excess(sd_meas: float, sd_floor: float) -> float:
    """sqrt(max(s_meas² − s_floor², 0)): what the side's wander holds beyond the floor (px)."""
    if not (math.isfinite(sd_meas) and math.isfinite(sd_floor)):
        return float("nan")
    return math.sqrt(max(sd_meas * sd_meas - sd_floor * sd_floor, 0.0))


def noise_sd_map(clean: np.ndarray, dark: float, white: float, sd_dark: float, sd_white: float) -> np.ndarray:
    """Per pixel noise SD with a variance linear in the level through (dark, sd_dark) and (white, sd_white)."""
    slope = (sd_white ** 2 - sd_dark ** 2) / max(white - dark, 1e-9)
    return np.sqrt(np.maximum(sd_dark ** 2 + slope * (clean - dark), 0.0))


def floor_image(shape: tuple[int, int], lines, sigma_x_px: float, sigma_y_px: float, dark: float, white: float,
                sd_dark: float, sd_white: float, seed: int = FLOOR_SEED, jpeg_quality: int | None = None) -> np.ndarray:
    """The rendered floor (module docstring): the photo's squares with perfect straight edges, its blur per axis,
    levels and noise, stored as 8-bit (float array of integers); through a JPEG at ``jpeg_quality`` when given
    (the photo's own, ``twin.measure.jpeg_quality``: its blocks move an edge block by block)."""
    clean = synthetic_board(shape, lines, sigma_x_px, sigma_y_px, dark, white)
    sd = noise_sd_map(clean, dark, white, sd_dark, sd_white)
    noisy = np.clip(np.round(clean + sd * np.random.default_rng(seed).standard_normal(clean.shape)), 0, 255)
    if jpeg_quality is None:
        return noisy
    return jpeg_round_trip(noisy.astype(np.uint8), int(jpeg_quality)).astype(np.float64)


def crb_sd(normal: np.ndarray, covered: np.ndarray, sigma_x_px: float, sigma_y_px: float, noise_sd: float,
           contrast: float) -> float:
    """The Cramér-Rao floor (module docstring), RMS over the covered sides: each side's σ along its normal from the
    per-axis σ, the noise over the contrast."""
    from edgetruth.evaluate.crb import position_std_bound_many  # lazy: crb loads numba

    nv = normal[covered]
    if not len(nv) or not contrast > 0:
        return float("nan")
    sig = np.hypot(nv[:, 0] * sigma_x_px, nv[:, 1] * sigma_y_px)
    b = position_std_bound_many(sig, noise_sd / contrast, 0.0)
    return float(np.sqrt(np.mean(b * b)))


def measure_set(images: list[np.ndarray], model, methods: list[str], options: dict, names: list[str] | None = None,
                progress: bool = False, paths=None) -> dict:
    """Raggedness of every side of every photo for each method (module docstring): per photo and pooled over the
    set, the detrended SD on the photo, on its rendered floor, their excess, the lag-1 correlations and the
    Cramér-Rao floor.  The squares are found once on the photos (``squares.board_squares``) and the floor uses the
    same squares and candidates rule, so both see the same sides.  ``paths``: the photos' files; a JPEG's floor goes
    through a JPEG at its quality."""
    chess = model.pattern is not None
    if chess:  # which squares are dark, as the board study settles it

        model = settle_parity([np.asarray(i, np.float64) for i in images], model)
    names = names or [f"photo{i + 1}" for i in range(len(images))]
    qualities = [None] * len(images) if paths is None else [(jpeg_quality(p) or (None,))[0] for p in paths]
    per_photo, stats_real, stats_floor = [], {m: [] for m in methods}, {m: [] for m in methods}
    for name, img, q in console.track(list(zip(names, images, qualities)), desc="raggedness", unit="photo",
                                      enabled=progress):
        img = np.asarray(img, np.float64)
        found = board_squares(img, model)[0]
        lines = board_lines(img, model)
        if found is None or lines is None:
            per_photo.append({"photo": name, "found": False})
            continue
        quads = found.corners
        bl, nz = blur(img, lines), noise(img, lines, chess)
        sx, sy = bl["vertical"]["sigma_px"], bl["horizontal"]["sigma_px"]
        dark, white = nz["black"]["mean"], nz["white"]["mean"]
        sdd, sdw = nz["black"]["sd"], nz["white"]["sd"]
        flo = floor_image(img.shape, lines, sx, sy, dark, white, sdd, sdw, jpeg_quality=q)
        smap = square_map(quads, img.shape)
        rec = {"photo": name, "found": True, "jpeg_quality": q, "sigma_x_px": sx, "sigma_y_px": sy, "dark": dark,
               "white": white, "sd_dark": sdd, "sd_white": sdw,
               "crb_px": crb_sd(lines.normal, lines.covered, sx, sy, math.sqrt((sdd ** 2 + sdw ** 2) / 2.0),
                                white - dark), "methods": {}}
        for label in methods:
            method, kw = mo.resolve(label, options)
            both = []
            for im in (img, flo):
                cand = board_candidates(im, quads, chess)
                row = method_row(label, method, kw, [im], [cand], [quads], [smap], keep_points=True)
                f, p = row.sides[0], row.points[0]
                both.append(side_stats(p["x"], p["y"], p["label"], f.normal, f.offset))
            stats_real[label].append(both[0])
            stats_floor[label].append(both[1])
            r, fl = pooled([both[0]]), pooled([both[1]])
            rec["methods"][label] = {"sd_px": r["sd_px"], "floor_sd_px": fl["sd_px"], "lag1": r["lag1"],
                                     "floor_lag1": fl["lag1"], "sides": r["sides"],
                                     "excess_px": excess(r["sd_px"], fl["sd_px"])}
        per_photo.append(rec)
    overall = {}
    for label in methods:
        if not stats_real[label]:
            continue
        r, fl = pooled(stats_real[label]), pooled(stats_floor[label])
        overall[label] = {"sd_px": r["sd_px"], "floor_sd_px": fl["sd_px"], "excess_px": excess(r["sd_px"], fl["sd_px"]),
                          "lag1": r["lag1"], "floor_lag1": fl["lag1"], "sides": r["sides"],
                          "photos": len(stats_real[label])}
    crbs = [p["crb_px"] for p in per_photo if p.get("found")]
    return {"degree": DETREND_DEGREE, "methods": overall, "per_photo": per_photo,
            "crb_px": float(np.sqrt(np.nanmean(np.square(crbs)))) if crbs else float("nan")}
