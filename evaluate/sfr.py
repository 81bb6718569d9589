"""Slanted-edge spatial frequency response (ISO 12233 e-SFR), written for edgetruth.

Given an image region holding one straight edge a few degrees off the pixel columns (or rows):

1. orientation and polarity: the region is transposed when the edge runs along the rows, and
   the gray levels are read so that they rise across the edge (the MTF does not depend on which
   side is bright);
2. the edge line (ISO 12233 style, hardened for real photographs): the *signed* derivative along
   each row, its centroid under a Hann window centred on the current line (half-width a few times
   the measured 10-90 % rise), and a robust (Tukey biweight) least-squares line x = a + b·y through
   the centroids, iterated to a fixed point.  Rows whose centroid is an outlier (dust or a scratch
   on the edge) get weight 0.  ``edge_order`` > 1 fits a polynomial x = f(y) for the projection
   (sfrmat5's ``npol``); the reported angle is always the straight line's;
3. the edge spread function: every pixel's signed perpendicular distance to the edge, averaged in
   bins of 1/``oversample`` px (the slant spreads the pixels over every phase); pixels that miss
   the binned ESF by more than 5 local robust standard deviations (dust, hot pixels) are left out;
4. shading: straight lines fitted to the outer halves of the ESF's two plateaus normalise it,
   (ESF − dark(t)) / (bright(t) − dark(t)), which removes an additive or a multiplicative linear
   illumination ramp across the edge exactly (a ramp along the edge averages out in the bins);
5. the line spread function: its central difference, times a Tukey window (flat on the middle
   half, so a narrow LSF is not reshaped);
6. MTF = |FFT(LSF)| / DC, divided by the transfer of the two steps that are not the camera's:
   the central difference, sinc(2νΔ), and the bin averaging, sinc(νΔ) (Δ the bin width).

Frequencies are cycles per pixel along the edge normal (the perpendicular distances already carry
ISO's cos(angle) scaling).  Checked against Burns' sfrmat5 (C++ port) on real edges, see
tests/evaluate/data/sfr/PROVENANCE.md and docs/optics.md ("e-SFR on real edges").
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from edgetruth.errors import InputError

_OUTLIER_SIGMAS = 5.0  # ESF pixel rejection (robust local standard deviations)
_BIWEIGHT_C = 4.685  # Tukey biweight tuning constant (95 % efficiency for Gaussian residuals)


@dataclass(frozen=True)
class Sfr:
    freq_cy_px: np.ndarray
    mtf: np.ndarray
    edge_angle_deg: float  # angle of the edge from the pixel columns (rows when transposed)
    edge_offset_px: float  # x of the edge line at the region's first row (region coordinates)
    transposed: bool
    esf_x_px: np.ndarray
    esf: np.ndarray

    def mtf50(self) -> float:
        return crossing(self.freq_cy_px, self.mtf, 0.5)

    def at(self, nu) -> np.ndarray:
        return np.interp(nu, self.freq_cy_px, self.mtf)


def crossing(freq: np.ndarray, values: np.ndarray, level: float) -> float:
    """The first frequency where ``values`` falls to ``level`` (linear interpolation)."""
    below = np.nonzero(values <= level)[0]
    if not len(below) or below[0] == 0:
        return float("nan")
    i = below[0]
    f0, f1, v0, v1 = freq[i - 1], freq[i], values[i - 1], values[i]
    return float(f0 + (v0 - level) * (f1 - f0) / (v0 - v1))


# --- the edge line -------------------------------------------------------------------------
def _robust_polyfit(y: np.ndarray, x: np.ndarray, order: int, w0: np.ndarray | None = None,
                    floor: float = 1e-3, n_iter: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """x ≈ polyval(coef, y) by iteratively reweighted least squares with Tukey's biweight.

    Returns (coef, weights); the scale is 1.4826·MAD of the residuals (at least ``floor`` px).
    """
    w = np.ones_like(x) if w0 is None else w0.astype(float)
    coef = np.polyfit(y, x, order, w=np.sqrt(w))  # polyfit scales its Vandermonde columns
    for _ in range(n_iter):
        r = x - np.polyval(coef, y)
        live = w > 0
        scale = max(1.4826 * float(np.median(np.abs(r[live] - np.median(r[live])))), floor)
        u = r / (_BIWEIGHT_C * scale)
        w_new = np.where(np.abs(u) < 1.0, (1.0 - u * u) ** 2, 0.0)
        if w0 is not None:
            w_new = w_new * (w0 > 0)
        if np.count_nonzero(w_new) < order + 2:
            break
        done = np.allclose(w_new, w, atol=1e-6)
        w = w_new
        coef = np.polyfit(y, x, order, w=np.sqrt(w))
        if done:
            break
    return coef, w


def _initial_positions(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per row: the peak of the derivative smoothed along the row (parabolic sub-pixel), and
    whether that peak stands out (at least half the median row's peak)."""
    k = np.array([1.0, 2.0, 3.0, 2.0, 1.0]) / 9.0
    pad = np.pad(d, ((0, 0), (2, 2)), mode="edge")
    ds = sum(k[i] * pad[:, i:i + d.shape[1]] for i in range(5))
    j = np.argmax(ds, axis=1)
    rows = np.arange(d.shape[0])
    jm, jp = np.clip(j - 1, 0, d.shape[1] - 1), np.clip(j + 1, 0, d.shape[1] - 1)
    a, b, c = ds[rows, jm], ds[rows, j], ds[rows, jp]
    den = a - 2 * b + c
    off = np.where((den < 0) & (jm != j) & (jp != j), 0.5 * (a - c) / np.where(den < 0, den, -1.0), 0.0)
    peak = b
    ok = peak > 0.5 * np.median(peak)
    return j + 0.5 + np.clip(off, -0.5, 0.5), ok


def _row_centroids(d: np.ndarray, centre: np.ndarray, half: float) -> tuple[np.ndarray, np.ndarray]:
    """Centroid of each row's derivative under a Hann window of half-width ``half`` centred on
    ``centre`` (cut symmetrically where the row ends).  Derivative sample j sits at x = j + 0.5."""
    n = d.shape[1]
    xs = np.arange(n) + 0.5
    h = np.minimum(half, np.minimum(centre - 0.0, n - centre))  # symmetric inside [0, n]
    ok = h >= 1.5
    h = np.maximum(h, 1e-9)
    u = (xs[None, :] - centre[:, None]) / h[:, None]
    win = np.where(np.abs(u) < 1.0, np.cos(0.5 * np.pi * u) ** 2, 0.0)
    wd = win * d
    s = wd.sum(axis=1)
    ok &= s > 0
    c = (wd * xs).sum(axis=1) / np.where(s > 0, s, 1.0)
    return c, ok


def _rise_width(t: np.ndarray, esf: np.ndarray) -> float:
    """10-90 % rise distance of a binned ESF (plateaus: medians of its outer fifths), px."""
    n = len(esf)
    q = max(1, n // 5)
    lo, hi = np.median(esf[:q]), np.median(esf[-q:])
    if not hi > lo:
        return float("nan")
    e = (esf - lo) / (hi - lo)
    c = int(np.argmin(np.abs(e - 0.5)))

    def cross(level):  # nearest crossing of ``level`` to the middle, walking outwards
        if level < 0.5:
            idx = np.nonzero(e[:c + 1] <= level)[0]
            if not len(idx):
                return t[0]
            i = idx[-1]
            return t[i] + (level - e[i]) * (t[i + 1] - t[i]) / max(e[i + 1] - e[i], 1e-12)
        idx = np.nonzero(e[c:] >= level)[0]
        if not len(idx):
            return t[-1]
        i = c + idx[0]
        return t[i - 1] + (level - e[i - 1]) * (t[i] - t[i - 1]) / max(e[i] - e[i - 1], 1e-12)

    return float(cross(0.9) - cross(0.1))


# --- the edge spread function ---------------------------------------------------------------
def _bin(dist: np.ndarray, vals: np.ndarray, lo: float, delta: float, n_bins: int):
    idx = np.floor((dist - lo) / delta).astype(int)
    inside = (idx >= 0) & (idx < n_bins)
    counts = np.bincount(idx[inside], minlength=n_bins)
    sums = np.bincount(idx[inside], weights=vals[inside], minlength=n_bins)
    return counts, sums, idx


def _binned_esf(img: np.ndarray, dist: np.ndarray, delta: float, contrast: float):
    """ESF bins (centres, means) over the distance range every row covers, with outliers out."""
    lo = np.floor(dist.min() / delta) * delta
    n_bins = int(np.floor((dist.max() - lo) / delta)) + 1
    dv, vv = dist.ravel(), img.ravel()
    counts, sums, idx = _bin(dv, vv, lo, delta, n_bins)
    centres = lo + (np.arange(n_bins) + 0.5) * delta
    reach = min(np.abs(dist[:, 0]).min(), np.abs(dist[:, -1]).min())
    keep = (np.abs(centres) <= reach - delta) & (counts > 0)
    if np.count_nonzero(keep) < 8:
        raise InputError("e-SFR: the edge must cross the region, with pixels on both sides in every row")
    # reject pixels far from the ESF (dust, hot pixels): local robust scale per bin, pooled
    means = np.where(counts > 0, sums / np.maximum(counts, 1), np.nan)
    good = np.isfinite(means)
    pred = np.interp(dv, centres[good], means[good])
    res = vv - pred
    order = np.lexsort((np.abs(res), idx))
    starts = np.searchsorted(idx[order], np.arange(n_bins))
    med = np.zeros(n_bins)
    nz = counts > 0
    med[nz] = np.abs(res[order][starts[nz] + counts[nz] // 2])
    # pool over +-4 bins (one pixel) the largest local median absolute residual and the largest
    # step between neighbouring bins (on the rise a pixel may lie half a bin off its bin's mean)
    step = np.zeros(n_bins)
    filled = np.interp(centres, centres[good], means[good])
    step[1:] = np.abs(np.diff(filled))
    step[:-1] = np.maximum(step[:-1], step[1:])

    def pool(v):
        padded = np.pad(v, 4, mode="edge")
        return np.max(np.stack([padded[i:i + n_bins] for i in range(9)]), axis=0)

    thr = np.maximum.reduce([_OUTLIER_SIGMAS * 1.4826 * pool(med), 2.0 * pool(step),
                             np.full(n_bins, 0.02 * abs(contrast))])
    inlier = np.abs(res) <= thr[np.clip(idx, 0, n_bins - 1)]
    counts2, sums2, _ = _bin(dv[inlier], vv[inlier], lo, delta, n_bins)
    keep &= counts2 > 0
    esf_x = centres[keep]
    esf = sums2[keep] / counts2[keep]
    k0, k1 = np.round((esf_x[[0, -1]] - lo) / delta - 0.5).astype(int)
    full = lo + (np.arange(k0, k1 + 1) + 0.5) * delta  # every bin centre in the kept range
    return full, np.interp(full, esf_x, esf)  # fills the rare empty bins only


def _normalise(t: np.ndarray, esf: np.ndarray, centre: float, rise: float) -> np.ndarray:
    """(ESF − dark(t)) / (bright(t) − dark(t)), dark and bright straight lines fitted to the outer
    half of each plateau (and at least 3 rise-widths, 3 px, from ``centre``); constant plateaus
    where those are too short.  The outer half only: a real lens's flare and halo make the ESF
    creep towards its plateaus over tens of pixels, and that tail is the camera's (low-frequency)
    MTF, not shading -- fitted closer in, it would be taken off and lift the MTF by 2-4 %."""
    reach = min(centre - t[0], t[-1] - centre)
    gap = max(3.0 * rise if np.isfinite(rise) else 3.0, 3.0, 0.5 * reach)
    dark = (t <= centre - gap) & (t >= centre - reach)
    bright = (t >= centre + gap) & (t <= centre + reach)
    if reach - gap >= 2.0 and dark.sum() >= 8 and bright.sum() >= 8:
        pd = np.polyfit(t[dark], esf[dark], 1)
        pb = np.polyfit(t[bright], esf[bright], 1)
        lo, hi = np.polyval(pd, t), np.polyval(pb, t)
    else:
        q = max(1, len(esf) // 8)
        lo, hi = np.full_like(esf, np.mean(esf[:q])), np.full_like(esf, np.mean(esf[-q:]))
    span = hi - lo
    if np.any(span <= 0):
        raise InputError("e-SFR: no edge contrast in the region")
    return (esf - lo) / span


def _orient(img: np.ndarray) -> tuple[bool, float]:
    """(transposed, sign): transposed when the gray level changes more from top to bottom than
    from left to right (plateau means of the outer strips); sign makes it rise along +x."""
    h, w = img.shape
    kx, ky = max(2, w // 8), max(2, h // 8)
    dx = img[:, -kx:].mean() - img[:, :kx].mean()
    dy = img[-ky:, :].mean() - img[:ky, :].mean()
    transposed = abs(dy) > abs(dx)
    step = dy if transposed else dx
    return bool(transposed), (1.0 if step >= 0 else -1.0)


def esfr(region: np.ndarray, oversample: int = 4, edge: tuple[float, float] | None = None,
         n_fft: int = 4096, *, edge_order: int = 1) -> Sfr:
    """e-SFR of ``region`` (2-D, one straight edge within 45° of the columns or of the rows).

    ``edge`` = (a, b): the edge line x = a + b·y in region pixel coordinates (OpenCV: pixel
    (r, c) centre at x = c, y = r), instead of fitting it.  ``edge_order``: order of the
    polynomial x = f(y) the pixels are projected onto (1: a straight line, ISO 12233:2017;
    sfrmat5's default is 5, for edges bent by distortion).
    """
    img = np.asarray(region, dtype=np.float64)
    if img.ndim != 2 or min(img.shape) < 8:
        raise InputError("e-SFR needs a 2-D region of at least 8 x 8 pixels")
    if not 1 <= int(edge_order) <= 5:
        raise InputError("e-SFR: edge_order must be 1 ... 5")
    transposed, sign = _orient(img)
    if transposed:
        img = img.T
        if edge is not None:
            raise InputError("e-SFR: give edge=(a, b) for a near-vertical edge only")
    g = sign * img  # rises along +x; every step below is offset-invariant, so polarity is moot
    h, w = g.shape
    ys = np.arange(h, dtype=float)
    xs = np.arange(w, dtype=float)
    contrast = float(g[:, -max(2, w // 8):].mean() - g[:, :max(2, w // 8)].mean())
    delta = 1.0 / oversample

    def distances(coef, slope):
        cos_t = 1.0 / np.sqrt(1.0 + slope * slope)
        return (xs[None, :] - np.polyval(coef, ys)[:, None]) * cos_t

    if edge is None:
        d = np.diff(g, axis=1)
        p0, ok = _initial_positions(d)
        if np.count_nonzero(ok) < 3:
            raise InputError("e-SFR: no edge found in the region")
        line, wts = _robust_polyfit(ys[ok], p0[ok], 1, floor=0.25)
        coef = line
        half = max(4.0, min(16.0, 0.25 * w))
        for it in range(6):
            c, ok = _row_centroids(d, np.polyval(coef, ys), half)
            if np.count_nonzero(ok) < max(3, edge_order + 2):
                raise InputError("e-SFR: the edge leaves the region")
            line_new, wts = _robust_polyfit(ys[ok], c[ok], 1)
            coef_new = line_new if edge_order == 1 else _robust_polyfit(ys[ok], c[ok], edge_order, w0=wts)[0]
            # the window follows the LSF: a few 10-90 % widths (along x), from a quick ESF
            t, e = _binned_esf(g, distances(coef_new, line_new[0]), delta, contrast)
            rise = _rise_width(t, e) * np.sqrt(1.0 + line_new[0] ** 2)
            new_half = float(np.clip(2.5 * rise + 3.0, 4.0, max(4.0, 0.5 * w))) if np.isfinite(rise) else half
            moved = np.max(np.abs(np.polyval(coef_new, ys) - np.polyval(coef, ys)))
            coef, line = coef_new, line_new
            if it >= 1 and moved < 1e-4 and abs(new_half - half) < 0.25:
                break
            half = new_half
        b = float(line[0])
    else:
        a, b = edge
        coef = np.array([b, a], float)
    full, esf = _binned_esf(g, distances(coef, b), delta, contrast)
    lsf0 = np.gradient(esf)
    centre_i = int(np.argmax(np.convolve(lsf0, np.ones(5) / 5, mode="same")))
    esf = _normalise(full, esf, full[centre_i], _rise_width(full, esf))
    lsf = np.zeros_like(esf)
    lsf[1:-1] = 0.5 * (esf[2:] - esf[:-2])
    n = len(lsf)
    centre = int(np.argmax(np.convolve(lsf, np.ones(5) / 5, mode="same")))
    half_n = min(centre, n - 1 - centre)
    lsf = lsf[centre - half_n:centre + half_n + 1]
    tt = np.linspace(-1.0, 1.0, len(lsf))
    taper = np.where(np.abs(tt) <= 0.5, 1.0, 0.5 * (1.0 + np.cos(np.pi * (np.abs(tt) - 0.5) / 0.5)))
    lsf = lsf * taper
    spec = np.abs(np.fft.rfft(lsf, n=max(n_fft, len(lsf))))
    freq = np.fft.rfftfreq(max(n_fft, len(lsf)), d=delta)
    mtf = spec / spec[0] / (np.sinc(2.0 * freq * delta) * np.sinc(freq * delta))
    sel = freq <= 1.0
    angle = float(np.degrees(np.arctan(b)))
    return Sfr(freq[sel], mtf[sel], angle, float(np.polyval(coef, 0.0)), bool(transposed), full, esf)
