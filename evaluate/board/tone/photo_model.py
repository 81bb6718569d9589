"""What a camera and its processing did to photos of a board of squares, measured on the photos.

The digital twin of a photo set (``edgetruth study twin``) must render what the photos show, and
nothing the photos do not show.  This module measures it, on any photos of a board of separate
dark squares (the board study's model and square finder), and on the twin's renders alike, so
that the two can be compared like with like:

- **Blur, per orientation.**  The squares' side lines come from Canny–Devernay's points (the
  board study's ``sides``); each side's pixels in the middle of the side (``SIDE_MIDDLE``, away
  from the corners), within ``ESF_HALF_WIDTH_PX`` of its line, against their signed distance d to
  it, are fitted with an edge-spread function I(d) = A + B Φ((d − μ)/σ) (all four free, one fit per
  side, batched Levenberg–Marquardt).  σ is reported per orientation: *horizontal* sides (their
  normal within 45° of the image's y axis: σ is the blur along y) and *vertical* ones (blur along
  x); the median over the sides.  The fit is done on the stored values and again on the values
  decoded through the sRGB curve (``linear``: what a gamma-encoding camera's sensor saw); the
  relative residual RMS of both fits says which describes the edge better.
- **e-SFR and sharpening.**  Per orientation every side's pixels, aligned by its fitted μ and
  normalised by its A and B, are pooled into one edge-spread function binned at ``BIN_PX`` (the
  sides' many sub-pixel phases play the slant's part in ISO 12233); the line-spread function is its
  central difference, the MTF its Fourier transform (divided by the transfer of the difference and
  of the binning, as ``edgetruth.evaluate.sfr`` does).  Overshoot: how far the pooled ESF rises
  above its bright plateau (and dips below its dark one) near the edge, in % of the step -- the
  mark of sharpening.
- **Noise in flat regions.**  Black: each square's inside, ``FLAT_MARGIN_PX`` in from its side
  lines; white: a ring around each square from ``FLAT_MARGIN_PX`` to ``RING_OUTER_PX`` out (on a
  chessboard, only the ring's parts beside the sides: its corners touch the next dark square).  Each
  region's pixels minus a quadratic surface fitted to them (shading, a reflection's gradient);
  the residual SD (degrees of freedom taken off), the lag-1 correlation of the residuals along x
  and along y (< 0: error-diffusion dithering pushes neighbours apart; > 0: an analog low-pass),
  the mean |difference| of horizontal neighbours, the number of distinct values, the share of
  the region's pixels at or above its 99th percentile (``at_max_fraction``: ~1 % for a noisy flat,
  most of it when the flat is clipped).  The noise's dependence on the signal:
  each level's SD carried to linear values through the sRGB curve's slope.
- **Gray levels and palette.**  Distinct values in the photo; for a colour file (Zhang's PNGs are
  colour-palette files of a gray camera), the distinct values of each channel over the colours
  used: a product palette (e.g. 8 × 8 × 4 values: the 256-colour 3-3-2 palette) shows there.

``derive_twin`` turns the measurements into a twin's settings (documented there).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from scipy.optimize import least_squares
from scipy.special import ndtr, ndtri

from edgetruth import locate
from edgetruth.evaluate.board.detect.squares import board_candidates, board_squares
from edgetruth.evaluate.board.model import BoardModel
from edgetruth.evaluate.board.sides.lines import intersect as meet, intersect_sides, side_fits, square_map
from edgetruth.image_io import quiet_stderr, read_gray
from edgetruth.render.optics import mtf
from edgetruth.render.sensor.pipeline import srgb_decode, srgb_encode


SIDE_MIDDLE = (0.2, 0.8)
ESF_HALF_WIDTH_PX = 6.0
BIN_PX = 0.125
FLAT_MARGIN_PX = 4.0
RING_OUTER_PX = 10.0
MIN_SIDE_PIXELS = 40
PLATEAU_FROM_PX = 3.5  # the pooled ESF's plateaus: |t| from here to ESF_HALF_WIDTH_PX
LM_ITERATIONS = 40
ORIENTATIONS = ("horizontal", "vertical")


# --- geometry: the squares' side lines -------------------------------------------------------------
@dataclass
class BoardLines:
    """Per photo: side lines n . p = d (S, 4, 2) / (S, 4) from Devernay's points and the corners they give."""

    normal: np.ndarray
    offset: np.ndarray
    corners: np.ndarray
    covered: np.ndarray


def board_lines(image: np.ndarray, model: BoardModel) -> BoardLines | None:
    """The side lines of the model's squares found on ``image`` (None when the board is not found)."""
    c = board_squares(image, model)[0]
    if c is None:
        return None
    cand = board_candidates(image, c.corners, chessboard=False)  # the side lines alone
    pts = locate.refine(image, cand, "canny_devernay")
    f = side_fits(c.corners, square_map(c.corners, image.shape), pts.x, pts.y, pts.nx, pts.ny, pts.converged)
    ok = f.covered & np.all(np.isfinite(f.corners), axis=2) & np.roll(np.all(np.isfinite(f.corners), axis=2), -1, 1)
    return BoardLines(f.normal, f.offset, f.corners, ok)


# --- edge spread: one ERF per side ----------------------------------------------------------------
@dataclass
class SideSamples:
    d: list  # per side: signed distances (px) to its line
    v: list  # per side: pixel values
    orientation: np.ndarray  # (n,) 0 horizontal side (blur along y), 1 vertical side


def side_samples(image: np.ndarray, lines: BoardLines) -> SideSamples:
    img = np.asarray(image, np.float64)
    h, w = img.shape
    ds, vs, ori = [], [], []
    r = ESF_HALF_WIDTH_PX + 1
    for s, k in zip(*np.nonzero(lines.covered)):
        a, b = lines.corners[s, k], lines.corners[s, (k + 1) % 4]
        n, d0 = lines.normal[s, k], lines.offset[s, k]
        length = float(np.linalg.norm(b - a))
        u = (b - a) / length
        x0, x1 = int(max(0, math.floor(min(a[0], b[0]) - r))), int(min(w - 1, math.ceil(max(a[0], b[0]) + r)))
        y0, y1 = int(max(0, math.floor(min(a[1], b[1]) - r))), int(min(h - 1, math.ceil(max(a[1], b[1]) + r)))
        yy, xx = np.mgrid[y0:y1 + 1, x0:x1 + 1]
        t = (xx - a[0]) * u[0] + (yy - a[1]) * u[1]
        dist = xx * n[0] + yy * n[1] - d0
        sel = (t >= SIDE_MIDDLE[0] * length) & (t <= SIDE_MIDDLE[1] * length) & (np.abs(dist) <= ESF_HALF_WIDTH_PX)
        if sel.sum() < MIN_SIDE_PIXELS:
            continue
        ds.append(dist[sel].astype(np.float64))
        vs.append(img[yy[sel], xx[sel]])
        ori.append(0 if abs(n[1]) > abs(n[0]) else 1)
    return SideSamples(ds, vs, np.asarray(ori, int))


def fit_erf_batch(d_list: list, v_list: list) -> dict:
    """Least-squares I(d) = A + B Φ((d − μ)/σ) per side (batched Levenberg–Marquardt); arrays A, B, mu, sigma
    (> 0), rms (residual RMS), converged."""
    n = len(d_list)
    m = max((len(d) for d in d_list), default=0)
    d = np.zeros((n, m))
    v = np.zeros((n, m))
    w = np.zeros((n, m))
    for i, (di, vi) in enumerate(zip(d_list, v_list)):
        d[i, :len(di)], v[i, :len(vi)], w[i, :len(di)] = di, vi, 1.0
    if n == 0:
        return {k: np.zeros(0) for k in ("A", "B", "mu", "sigma", "rms", "converged")}
    # start: plateaus from the outer pixels on each side of the line
    far = np.abs(d) >= 2.5
    lo_side = (d < 0) & far & (w > 0)
    hi_side = (d > 0) & far & (w > 0)
    a0 = np.sum(v * lo_side, 1) / np.maximum(lo_side.sum(1), 1)
    b0 = np.sum(v * hi_side, 1) / np.maximum(hi_side.sum(1), 1) - a0
    p = np.stack([a0, b0, np.zeros(n), np.full(n, 0.7)], axis=1)
    lam = np.full(n, 1e-2)

    def resid(p):
        z = (d - p[:, 2:3]) / p[:, 3:4]
        return (p[:, 0:1] + p[:, 1:2] * ndtr(z) - v) * w, z

    r, z = resid(p)
    cost = (r ** 2).sum(1)
    for _ in range(LM_ITERATIONS):
        phi = np.exp(-0.5 * z * z) / math.sqrt(2.0 * math.pi)
        jac = np.stack([w, ndtr(z) * w, -p[:, 1:2] * phi / p[:, 3:4] * w, -p[:, 1:2] * phi * z / p[:, 3:4] * w], -1)
        jtj = np.einsum("nmi,nmj->nij", jac, jac)
        jtr = np.einsum("nmi,nm->ni", jac, r)
        damp = jtj + lam[:, None, None] * np.einsum("nii->ni", jtj)[:, :, None] * np.eye(4)
        step = np.linalg.solve(damp + 1e-12 * np.eye(4), -jtr[..., None])[..., 0]
        trial = p + step
        trial[:, 3] = np.clip(np.abs(trial[:, 3]), 0.05, 5.0)
        trial[:, 2] = np.clip(trial[:, 2], -3.0, 3.0)
        r_t, z_t = resid(trial)
        c_t = (r_t ** 2).sum(1)
        better = c_t < cost
        p = np.where(better[:, None], trial, p)
        r = np.where(better[:, None], r_t, r)
        z = np.where(better[:, None], z_t, z)
        cost = np.where(better, c_t, cost)
        lam = np.where(better, lam * 0.3, lam * 10.0)
    npts = w.sum(1)
    rms = np.sqrt(cost / np.maximum(npts - 4, 1))
    ok = np.isfinite(p).all(1) & (p[:, 3] > 0.05) & (p[:, 3] < 5.0) & (np.abs(p[:, 1]) > 0)
    return {"A": p[:, 0], "B": p[:, 1], "mu": p[:, 2], "sigma": p[:, 3], "rms": rms, "converged": ok}


def pooled_esf(samples: SideSamples, fit: dict, which: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(bin centres t, normalised ESF) of the sides ``which`` (bool mask), aligned by μ, scaled by A, B."""
    t_all, e_all = [], []
    for i in np.flatnonzero(which & fit["converged"]):
        t_all.append(samples.d[i] - fit["mu"][i])
        e_all.append((samples.v[i] - fit["A"][i]) / fit["B"][i])
    if not t_all:
        return np.zeros(0), np.zeros(0)
    t, e = np.concatenate(t_all), np.concatenate(e_all)
    edges = np.arange(-ESF_HALF_WIDTH_PX + 1.0, ESF_HALF_WIDTH_PX - 1.0 + 1e-9, BIN_PX)
    idx = np.digitize(t, edges) - 1
    ok = (idx >= 0) & (idx < len(edges) - 1)
    cnt = np.bincount(idx[ok], minlength=len(edges) - 1)
    s = np.bincount(idx[ok], e[ok], minlength=len(edges) - 1)
    centres = 0.5 * (edges[:-1] + edges[1:])
    good = cnt > 0
    return centres[good], s[good] / cnt[good]


def esf_mtf(t: np.ndarray, esf: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """MTF (cycles/px) of a binned ESF: central-difference LSF, Hann-tapered tails, |FFT| / DC, divided by the
    transfer of the central difference and of the bin averaging."""
    if len(esf) < 16:
        return np.zeros(0), np.zeros(0)
    lsf = np.zeros_like(esf)
    lsf[1:-1] = 0.5 * (esf[2:] - esf[:-2])
    tt = np.linspace(-1.0, 1.0, len(lsf))
    lsf = lsf * np.where(np.abs(tt) <= 0.5, 1.0, 0.5 * (1.0 + np.cos(np.pi * (np.abs(tt) - 0.5) / 0.5)))
    n_fft = 4096
    spec = np.abs(np.fft.rfft(lsf, n=n_fft))
    freq = np.fft.rfftfreq(n_fft, d=BIN_PX)
    mtf = spec / spec[0] / (np.sinc(2.0 * freq * BIN_PX) * np.sinc(freq * BIN_PX))
    sel = freq <= 1.0
    return freq[sel], mtf[sel]


def mtf50(freq: np.ndarray, mtf: np.ndarray) -> float:
    below = np.nonzero(mtf <= 0.5)[0]
    if not len(below) or below[0] == 0:
        return float("nan")
    i = below[0]
    return float(freq[i - 1] + (mtf[i - 1] - 0.5) * (freq[i] - freq[i - 1]) / (mtf[i - 1] - mtf[i]))


def overshoot_pct(t: np.ndarray, esf: np.ndarray) -> tuple[float, float]:
    """(rise above the bright plateau, dip below the dark plateau) of a normalised ESF, in % of the step."""
    hi = (t >= PLATEAU_FROM_PX)
    lo = (t <= -PLATEAU_FROM_PX)
    if not hi.any() or not lo.any():
        return float("nan"), float("nan")
    top, bottom = float(esf[hi].mean()), float(esf[lo].mean())
    step = top - bottom
    near = np.abs(t) < PLATEAU_FROM_PX
    return (100.0 * max(0.0, float(esf[near & (t > 0)].max()) - top) / step,
            100.0 * max(0.0, bottom - float(esf[near & (t < 0)].min())) / step)


def blur(image: np.ndarray, lines: BoardLines) -> dict:
    """Per orientation: median ERF σ (stored and sRGB-decoded values), relative fit residuals, e-SFR MTF50 and
    overshoot of the pooled ESF (module docstring)."""
    return blur_of_samples(side_samples(image, lines))


def blur_of_samples(smp: SideSamples) -> dict:
    """``blur`` of edge samples of any shape (a circle's arcs: ``twin.measure_circles``): per orientation, the
    ERF fit of every edge's (distance, value) samples, pooled."""
    enc = fit_erf_batch(smp.d, smp.v)
    lin_v = [srgb_decode(v / 255.0) for v in smp.v]
    lin = fit_erf_batch(smp.d, lin_v)
    out = {}
    for o, name in enumerate(ORIENTATIONS):
        which = smp.orientation == o
        ok_e, ok_l = which & enc["converged"], which & lin["converged"]
        t, e = pooled_esf(smp, enc, which)
        f, m = esf_mtf(t, e)
        over, under = overshoot_pct(t, e)
        smp_lin = SideSamples(smp.d, lin_v, smp.orientation)
        tl, el = pooled_esf(smp_lin, lin, which)
        fl, ml = esf_mtf(tl, el)
        out[name] = {
            "sides": int(ok_e.sum()),
            "sigma_px": float(np.median(enc["sigma"][ok_e])) if ok_e.any() else float("nan"),
            "sigma_iqr_px": _iqr(enc["sigma"][ok_e]),
            "sigma_linear_px": float(np.median(lin["sigma"][ok_l])) if ok_l.any() else float("nan"),
            "fit_rms_rel": float(np.median(enc["rms"][ok_e] / np.abs(enc["B"][ok_e]))) if ok_e.any() else float("nan"),
            "fit_rms_rel_linear": float(np.median(lin["rms"][ok_l] / np.abs(lin["B"][ok_l]))) if ok_l.any()
            else float("nan"),
            "mtf50_cy_px": mtf50(f, m),
            "mtf50_linear_cy_px": mtf50(fl, ml),
            "overshoot_pct": over,
            "undershoot_pct": under,
            "esf": (t, e),  # the pooled normalised ESF (bin centres, values): arrays, not for JSON
        }
    return out


def _iqr(a) -> float:
    a = np.asarray(a, float)
    return float(np.subtract(*np.percentile(a, [75, 25]))) if a.size else float("nan")


# --- flat regions: noise, levels, dithering --------------------------------------------------------
def _outward(lines: BoardLines) -> tuple[np.ndarray, np.ndarray]:
    """The side lines n . p = d (S, 4, 2) / (S, 4) with every normal pointing out of its square."""
    with np.errstate(invalid="ignore"):
        centre = lines.corners.mean(axis=1)  # (S, 2); NaN for a square with a missing corner (left out anyway)
    n = lines.normal.copy()
    d = lines.offset.copy()
    inside = np.einsum("ski,si->sk", n, centre) - d  # < 0: the normal points outward
    flip = inside > 0
    n[flip] *= -1.0
    d[flip] *= -1.0
    return n, d


def _offset_quads(lines: BoardLines, margin_px: float) -> np.ndarray:
    """(S, 4, 2) each square's outline moved ``margin_px`` outward (< 0: inward) along its side normals; NaN
    where a side is missing."""
    n, d = _outward(lines)
    return intersect_sides(n, d + margin_px)


def _side_bands(lines: BoardLines, near_px: float, far_px: float, cap_px: float) -> np.ndarray:
    """(S, 4, 4, 2) beside each side k, the quad between its line moved ``near_px`` and ``far_px`` outward, capped
    by the neighbouring sides' lines moved ``cap_px`` inward: the light ground beside the side alone, clear of
    what lies diagonally off the square's corners (on a chessboard, the next dark square)."""
    n, d = _outward(lines)
    n0, d0 = np.roll(n, 1, axis=1), np.roll(d, 1, axis=1) - cap_px  # side k - 1, moved inward
    n1, d1 = np.roll(n, -1, axis=1), np.roll(d, -1, axis=1) - cap_px  # side k + 1
    return np.stack([meet(n0, d0, n, d + near_px), meet(n, d + near_px, n1, d1), meet(n1, d1, n, d + far_px),
                     meet(n, d + far_px, n0, d0)], axis=2)


def flat_labels(shape: tuple[int, int], lines: BoardLines, beside_sides: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(black, white) int32 label images: square s + 1 inside the square (``FLAT_MARGIN_PX`` in) and in its ring
    (``FLAT_MARGIN_PX`` to ``RING_OUTER_PX`` out); 0 elsewhere.  Squares with a missing side are left out.
    ``beside_sides`` (a chessboard, whose dark squares touch at their corners): the white region is only the ring's
    parts beside the sides (``_side_bands``), ``FLAT_MARGIN_PX`` clear of the lines through the corners."""
    inner = _offset_quads(lines, -FLAT_MARGIN_PX)
    near = _offset_quads(lines, FLAT_MARGIN_PX)
    outer = _offset_quads(lines, RING_OUTER_PX)
    bands = _side_bands(lines, FLAT_MARGIN_PX, RING_OUTER_PX, FLAT_MARGIN_PX) if beside_sides else None
    black = np.zeros(shape, np.int32)
    white = np.zeros(shape, np.int32)
    claimed = np.zeros(shape, np.int32)  # rings that overlap another square's ring or square are dropped there
    ok = lines.covered.all(axis=1)
    for s in np.flatnonzero(ok):
        if not (np.all(np.isfinite(inner[s])) and np.all(np.isfinite(outer[s]))):
            continue
        cv2.fillPoly(black, [np.round(inner[s] * 16).astype(np.int32)], int(s) + 1, shift=4)
        ring = np.zeros(shape, np.uint8)
        if bands is not None:
            if not np.all(np.isfinite(bands[s])):
                continue
            cv2.fillPoly(ring, [np.round(b * 16).astype(np.int32) for b in bands[s]], 1, shift=4)
        else:
            cv2.fillPoly(ring, [np.round(outer[s] * 16).astype(np.int32)], 1, shift=4)
            cv2.fillPoly(ring, [np.round(near[s] * 16).astype(np.int32)], 0, shift=4)
        claimed += ring
        white[ring > 0] = int(s) + 1
    white[claimed > 1] = 0
    return black, white


def region_noise(image: np.ndarray, labels: np.ndarray) -> dict:
    """Noise of the labelled flat regions (module docstring)."""
    img = np.asarray(image, np.float64)
    resid = np.full(img.shape, np.nan)
    means, counts, centres = [], [], []
    ss, dof = 0.0, 0
    for s in np.unique(labels[labels > 0]):
        yy, xx = np.nonzero(labels == s)
        if len(yy) < 30:
            continue
        v = img[yy, xx]
        xc, yc = xx - xx.mean(), yy - yy.mean()
        a = np.stack([np.ones_like(xc), xc, yc, xc * xc, yc * yc, xc * yc], axis=1)
        coef, *_ = np.linalg.lstsq(a, v, rcond=None)
        r = v - a @ coef
        resid[yy, xx] = r
        ss += float(r @ r)
        dof += len(r) - 6
        means.append(float(v.mean()))
        counts.append(len(v))
        centres.append((xx.mean(), yy.mean()))
    if dof <= 0:
        return {"mean": float("nan"), "sd": float("nan"), "rho_x": float("nan"), "rho_y": float("nan"),
                "mean_abs_dx": float("nan"), "levels": 0, "pixels": 0, "regions": 0, "at_max_fraction": float("nan"),
                "falloff_x_pct": float("nan"), "falloff_y_pct": float("nan")}
    same_x = (labels[:, 1:] == labels[:, :-1]) & (labels[:, 1:] > 0) & np.isfinite(resid[:, 1:]) & np.isfinite(resid[:, :-1])
    same_y = (labels[1:] == labels[:-1]) & (labels[1:] > 0) & np.isfinite(resid[1:]) & np.isfinite(resid[:-1])

    def corr(a, b):
        return float(np.sum(a * b) / math.sqrt(np.sum(a * a) * np.sum(b * b)))

    vals = img[labels > 0]
    return {"mean": float(np.average(means, weights=counts)), "sd": math.sqrt(ss / dof),
            "rho_x": corr(resid[:, 1:][same_x], resid[:, :-1][same_x]),
            "rho_y": corr(resid[1:][same_y], resid[:-1][same_y]),
            "mean_abs_dx": float(np.mean(np.abs(img[:, 1:][same_x] - img[:, :-1][same_x]))),
            "levels": int(len(np.unique(np.round(vals, 6)))), "pixels": int(vals.size), "regions": len(means),
            "at_max_fraction": float(np.mean(vals >= float(np.percentile(vals, 99)) - 0.5)),
            **falloff(np.array(centres), np.array(means), np.array(counts))}


def falloff(centres: np.ndarray, means: np.ndarray, counts: np.ndarray) -> dict:
    """How the regions' level changes across them: a plane through their means over their centres (weighted by
    their pixels), its change from the leftmost to the rightmost centre and from the top to the bottom one, in %
    of the level at their mean centre (> 0: brighter to the right, or down).  NaN with fewer than 3 regions."""
    if len(means) < 3:
        return {"falloff_x_pct": float("nan"), "falloff_y_pct": float("nan")}
    c = centres - np.average(centres, axis=0, weights=counts)
    a = np.c_[np.ones(len(c)), c] * np.sqrt(counts)[:, None]
    (c0, gx, gy), *_ = np.linalg.lstsq(a, means * np.sqrt(counts), rcond=None)
    return {"falloff_x_pct": float(100.0 * gx * np.ptp(centres[:, 0]) / c0),
            "falloff_y_pct": float(100.0 * gy * np.ptp(centres[:, 1]) / c0)}


def srgb_slope(encoded_8bit: float) -> float:
    """d(linear) / d(stored value) of the sRGB curve at an 8-bit stored value."""
    e = float(encoded_8bit)
    h = 0.5
    return float((srgb_decode((e + h) / 255.0) - srgb_decode((e - h) / 255.0)) / (2 * h))


def noise(image: np.ndarray, lines: BoardLines, beside_sides: bool = False) -> dict:
    """Black and white flat regions: noise, levels, dithering; and the noise carried to linear values.
    ``beside_sides``: a chessboard's white regions (``flat_labels``)."""
    black, white = flat_labels(image.shape, lines, beside_sides)
    out = {"black": region_noise(image, black), "white": region_noise(image, white)}
    for k in ("black", "white"):
        r = out[k]
        if np.isfinite(r["mean"]):
            r["mean_linear"] = float(srgb_decode(r["mean"] / 255.0))
            r["sd_linear"] = r["sd"] * srgb_slope(r["mean"])
    return out


def colours(path) -> dict | None:
    """For a colour file: the number of colours used and each channel's distinct values over them (a product
    palette shows as few values per channel); None for a gray file."""
    with quiet_stderr():
        img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        return None
    if np.array_equal(img[..., 0], img[..., 1]) and np.array_equal(img[..., 1], img[..., 2]):
        return None
    used = np.unique(img.reshape(-1, 3), axis=0)
    b, g, r = (np.unique(used[:, i]) for i in range(3))
    return {"colours": int(len(used)), "levels_rgb": [len(r), len(g), len(b)],
            "values_r": r.astype(int).tolist(), "values_g": g.astype(int).tolist(),
            "values_b": b.astype(int).tolist()}


def measure_photo(image: np.ndarray, model: BoardModel, name: str = "", path=None) -> dict:
    """Every measurement of one photo (or render) of the board (module docstring)."""
    img = np.asarray(image, np.float64)
    lines = board_lines(img, model)
    out = {"photo": name, "levels": int(len(np.unique(np.round(img, 6)))),
           "mean_abs_dx": float(np.mean(np.abs(np.diff(img, axis=1)))),
           "max_value": float(img.max()), "colours": colours(path) if path is not None else None}
    if lines is None:
        out["found"] = False
        return out
    out["found"] = True
    out["sides_covered"] = int(lines.covered.sum())
    out["blur"] = blur(img, lines)
    out["noise"] = noise(img, lines, model.pattern is not None)
    out["channel_means"] = channel_means(path, lines, img.shape) if path is not None else None
    return out


def measure_photos(paths, model: BoardModel, channel: str = "luma") -> list[dict]:
    """``measure_photo`` of each photo file (read with ``edgetruth.image_io.read_gray``)."""
    return [measure_photo(read_gray(p, channel=channel), model, Path(p).name, p) for p in paths]


# --- from the measurements to a twin's settings ----------------------------------------------------
#: A photo with fewer distinct gray levels than this was reduced to a coarse palette (Zhang's 3-3-2 photos hold
#: 74-84; his others, from an adaptive 256-colour palette, 244-250).
PALETTE_LEVELS = 128
#: A white region with more than this share of its pixels at its largest value is clipped.
CLIPPED_SHARE = 0.3
#: Overshoot (either side, % of the step) above which an orientation's ESF is fitted with sharpening.
SHARPENED_PCT = 3.0


def esf_model(t: np.ndarray, camera, sigma_ab_um: float, defocus_px: float, black: float, white: float,
              gain: float = 1.0, amount: float = 0.0, sigma_s: float = 1.0, gamma: float | None = None) -> np.ndarray:
    """The stored 8-bit value of a pixel centred at signed distance ``t`` (px) from a straight edge, with no noise:
    the pixel-integrated ESF along one axis from the analytic OTF (pixel box, ``camera``'s diffraction, a
    Gaussian aberration ``sigma_ab_um``, a defocus disk), between linear levels ``black`` and ``white`` (fractions
    of full scale), through the sRGB curve (or with ``gamma`` the power curve v^(1/gamma), the sensor's
    ``output_gamma``), ``gain``, and an unsharp mask of ``amount`` and ``sigma_s`` (px) on the pixel grid (the
    renderer's pipeline, ``edgetruth.render.sensor.pipeline``)."""
    p = camera.pitch_um
    cutoff = mtf.diffraction_cutoff_cy_px(p, camera.diffraction_wavelength_nm, camera.f_number)
    step, n = 1.0 / 64.0, 8192
    nu = np.fft.rfftfreq(n, d=step)
    otf = (np.sinc(nu) * mtf.diffraction_mtf(nu, cutoff) * mtf.gaussian_mtf(nu, sigma_ab_um / p)
           * mtf.defocus_otf(nu, defocus_px))
    lsf = np.fft.fftshift(np.fft.irfft(otf, n=n))
    grid = (np.arange(n) - n // 2) * step
    esf = np.cumsum(lsf)
    esf = (esf - esf[0]) / (esf[-1] - esf[0])
    v = black + (white - black) * esf
    e = (srgb_encode(v) if gamma is None else np.maximum(v, 0.0) ** (1.0 / gamma)) * gain
    if amount:
        r = int(5.0 * sigma_s + 0.5)
        j = np.arange(-r, r + 1)
        g = np.exp(-0.5 * (j / sigma_s) ** 2)
        g /= g.sum()
        k = int(round(1.0 / step))
        pad = np.concatenate([np.full(r * k, e[0]), e, np.full(r * k, e[-1])])
        blurred = sum(w * pad[(r + jj) * k:(r + jj) * k + n] for w, jj in zip(g, j))
        e = e + amount * (e - blurred)
    return 255.0 * np.interp(t, grid, np.clip(e, 0.0, 1.0))


def normalised_model(t_bins: np.ndarray, **kw) -> np.ndarray:
    """``esf_model`` as ``pooled_esf`` sees it: an ERF fitted to its samples within ``ESF_HALF_WIDTH_PX`` gives
    A, B, μ; the curve (v − A) / B at t + μ."""
    t = np.linspace(-ESF_HALF_WIDTH_PX, ESF_HALF_WIDTH_PX, 769)
    v = esf_model(t, **kw)
    f = fit_erf_batch([t], [v])
    return (esf_model(t_bins + f["mu"][0], **kw) - f["A"][0]) / f["B"][0]


def fit_esf(t_bins, esf_bins, camera, defocus_px: float, black: float, white: float, sharpen: bool) -> dict:
    """The aberration σ (µm) -- and with ``sharpen`` the unsharp mask's amount and σ -- whose ``normalised_model``
    best fits a photo's pooled ESF along one axis (least squares over the bins)."""
    base = dict(camera=camera, defocus_px=defocus_px, black=black, white=white)

    def resid(q):
        kw = dict(sigma_ab_um=q[0])
        if sharpen:
            kw.update(amount=q[1], sigma_s=q[2])
        return normalised_model(t_bins, **base, **kw) - esf_bins

    p = camera.pitch_um
    if sharpen:
        # the model is piecewise smooth in the mask's sigma (its kernel's radius and the 1/64-px grid step
        # in whole samples): a default finite-difference step sees those kinks and stops on one, at a spot
        # that depends on the last bits of the ESF (a fresh environment moved it by 0.06 um); a step of
        # 1e-3 spans them and finds a lower cost.  The blur/sharpening split stays weakly determined along
        # a valley (docs/board.md): fits within 0.5 % of the best RMS span ~0.1 um of sigma
        r = least_squares(resid, [0.5 * p, 0.5, 1.0], bounds=([0.0, 0.0, 0.3], [4.0 * p, 5.0, 4.0]), diff_step=1e-3)
        q = {"aberration_sigma_um": float(r.x[0]), "sharpen_amount": float(r.x[1]), "sharpen_sigma_px": float(r.x[2])}
    else:
        r = least_squares(resid, [0.5 * p], bounds=([0.0], [4.0 * p]))
        q = {"aberration_sigma_um": float(r.x[0]), "sharpen_amount": 0.0, "sharpen_sigma_px": float("nan")}
    q["fit_rms"] = float(np.sqrt(np.mean(r.fun ** 2)))
    return q


def esf_fit_rms(t_bins, esf_bins, camera, defocus_px: float, black: float, white: float, sigma_ab_um: float,
                amount: float = 0.0, sigma_s: float = 1.0) -> float:
    """RMS of ``normalised_model`` with these settings against a pooled ESF (the cost ``fit_esf`` minimises)."""
    r = normalised_model(t_bins, camera=camera, defocus_px=defocus_px, black=black, white=white,
                         sigma_ab_um=sigma_ab_um, amount=amount, sigma_s=sigma_s) - esf_bins
    return float(np.sqrt(np.mean(r ** 2)))


def clipped_white(white: dict, noise_dn: float, clip: float = 255.0) -> float:
    """The white level before a clip: ``white`` (``region_noise`` of a white region) has ``at_max_fraction`` of its
    pixels at the clip; with Gaussian noise of SD ``noise_dn`` the level lies ``noise_dn`` Φ⁻¹(1 − f) below the
    photo's clip, returned at the same distance below ``clip``."""
    f = float(np.clip(white["at_max_fraction"], 1e-3, 0.999))
    return clip + noise_dn * float(ndtri(f))


def derive_twin(measurements: list[dict], camera, defocus_px: list[float], base_white: float,
                base_black: float) -> dict:
    """A twin's settings from the photos' measurements (``measure_photo``), each with how it was derived.  ``base_white`` / ``base_black``: the twin's stored white and black with
    output_gain 1 (its scene's exposure and print).

    Per photo:

    - ``palette``: reduced to a palette when its flat regions hold fewer than ``PALETTE_LEVELS`` distinct
      values; for a colour file the per-channel levels of its colours (``output_levels_rgb``) and the channel
      gains that map the gray (luma) of its flat regions to their channel means (least squares through 0:
      ``output_rgb_gains``);
    - ``output_noise_dn``: the black regions' SD with the 8-bit rounding (1/12) taken off, from the photos *not*
      reduced to a coarse palette (their noise is the camera's; a coarse palette's dither adds its own); the
      lowest of them (texture in a flat region, such as a reflection of the room, only adds to its SD);
    - the optics: the aberration σ along x (vertical sides) and along y (horizontal sides) whose ESF, through the
      camera's pixel, diffraction and the photo's defocus, the sRGB curve at the photo's black and white, and an
      unsharp mask where the ESF overshoots by more than ``SHARPENED_PCT`` %, fits the photo's pooled ESF
      (``fit_esf``);
    - ``output_gain`` and ``output_offset_dn``: the affine map of the encoded values that takes the twin's black
      and white (``base_black``, ``base_white``) to the photo's; a clipped white (more than ``CLIPPED_SHARE`` of
      its pixels at its largest value) is first carried to its level before the clip (``clipped_white``).
    """
    per = []
    clean = [m for m in measurements if m["levels"] >= PALETTE_LEVELS]
    noise_dn = float(np.min([math.sqrt(max(m["noise"]["black"]["sd"] ** 2 - 1.0 / 12.0, 0.0))
                             for m in (clean or measurements)]))
    for m, dp in zip(measurements, defocus_px):
        nz, b = m["noise"], m["blur"]
        palette = m["levels"] < PALETTE_LEVELS
        white_region = nz["white"]
        clipped = white_region["at_max_fraction"] > CLIPPED_SHARE
        white = clipped_white(white_region, noise_dn) if clipped else white_region["mean"]
        black = nz["black"]["mean"]
        lin_b, lin_w = float(srgb_decode(black / 255.0)), float(srgb_decode(min(white, 255.0) / 255.0))
        gain = (white - black) / (base_white - base_black)
        row = {"photo": m["photo"], "palette_reduced": bool(palette), "white_clipped": bool(clipped),
               "white": float(white), "black": float(black), "defocus_px": float(dp),
               "output_gain": float(gain), "output_offset_dn": float(black - gain * base_black)}
        for axis, name in (("x", "vertical"), ("y", "horizontal")):
            t, e = b[name]["esf"]
            sharp = max(b[name]["overshoot_pct"], b[name]["undershoot_pct"]) > SHARPENED_PCT
            row[axis] = fit_esf(t, e, camera, dp, lin_b, lin_w, sharp)
        col = m.get("colours")
        if palette and col is not None:
            row["output_levels_rgb"] = col["levels_rgb"]
        if palette and m.get("channel_means") is not None:
            row["output_rgb_gains"] = m["channel_means"]["gains"]
        per.append(row)
    return {"per_photo": per, "output_noise_dn": noise_dn,
            "noise_from": [m["photo"] for m in (clean or measurements)]}


def channel_means(path, lines: BoardLines, shape) -> dict | None:
    """For a colour file: per channel (R, G, B) the mean of the black and white flat regions, and the gains g_c that
    best map their luma to them (least squares through 0)."""
    with quiet_stderr():
        bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if bgr is None or (np.array_equal(bgr[..., 0], bgr[..., 1]) and np.array_equal(bgr[..., 1], bgr[..., 2])):
        return None
    rgb = bgr[..., ::-1].astype(np.float64)
    luma = rgb @ np.array([0.299, 0.587, 0.114])
    black, white = flat_labels(shape, lines)
    out = {}
    ys, xs = [], []
    for k, lab in (("black", black), ("white", white)):
        m = lab > 0
        out[k] = [float(rgb[..., c][m].mean()) for c in range(3)]
        xs.append(float(luma[m].mean()))
        ys.append(out[k])
    xs, ys = np.asarray(xs), np.asarray(ys)
    out["gains"] = [float(xs @ ys[:, c] / (xs @ xs)) for c in range(3)]
    return out
