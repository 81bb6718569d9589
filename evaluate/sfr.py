"""Slanted-edge spatial frequency response (ISO 12233 e-SFR), written for edgetruth.

Given an image region holding one straight edge a few degrees off the pixel columns (or rows):

1. the edge: centroid of the row-wise derivative in every row, a least-squares line
   x = a + b·y through them (or the known line, ``edge=(a, b)``);
2. the edge spread function: every pixel's signed perpendicular distance to that line,
   averaged in bins of 1/``oversample`` px (the slant spreads the pixels over every phase);
3. the line spread function: its central difference, times a Tukey window (flat on the middle
   half, so a narrow LSF is not reshaped; ISO's Hamming window would lift the MTF of a sharp
   edge by ~1 % at Nyquist);
4. MTF = |FFT(LSF)| / DC, divided by the transfer of the two steps that are not the camera's:
   the central difference, sinc(2νΔ), and the bin averaging, sinc(νΔ) (Δ the bin width).

Frequencies are cycles per pixel along the edge normal.  Sign convention: the MTF does not
depend on which side is bright.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from edgetruth.errors import InputError


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


def _row_centroids(img: np.ndarray) -> np.ndarray:
    d = np.abs(np.diff(img, axis=1))  # between columns j and j+1: position j + 0.5
    pos = np.arange(d.shape[1]) + 0.5
    w = d.sum(axis=1)
    return (d * pos).sum(axis=1) / np.where(w > 0, w, 1.0)


def esfr(region: np.ndarray, oversample: int = 4, edge: tuple[float, float] | None = None,
         n_fft: int = 4096) -> Sfr:
    """e-SFR of ``region`` (2-D, one straight edge within 45° of the columns or of the rows).

    ``edge`` = (a, b): the edge line x = a + b·y in region pixel coordinates (OpenCV: pixel
    (r, c) centre at x = c, y = r), instead of fitting it.
    """
    img = np.asarray(region, dtype=np.float64)
    if img.ndim != 2 or min(img.shape) < 8:
        raise InputError("e-SFR needs a 2-D region of at least 8 x 8 pixels")
    gy = np.abs(np.diff(img, axis=0)).sum()
    gx = np.abs(np.diff(img, axis=1)).sum()
    transposed = gy > gx  # the edge runs along the rows: work on the transpose
    if transposed:
        img = img.T
        if edge is not None:
            raise InputError("e-SFR: give edge=(a, b) for a near-vertical edge only")
    h, w = img.shape
    ys = np.arange(h, dtype=float)
    if edge is None:
        c = _row_centroids(img)
        b, a = np.polyfit(ys, c, 1)
        for _ in range(2):  # refine: centroids of a window around the first line (less noise from afar)
            xs = np.arange(w - 1) + 0.5
            d = np.abs(np.diff(img, axis=1))
            win = np.abs(xs[None, :] - (a + b * ys)[:, None]) <= max(6.0, 0.25 * w)
            d = d * win
            c = (d * xs).sum(axis=1) / np.maximum(d.sum(axis=1), 1e-300)
            b, a = np.polyfit(ys, c, 1)
    else:
        a, b = edge
    cos_t = 1.0 / np.sqrt(1.0 + b * b)
    xs, yy = np.meshgrid(np.arange(w, dtype=float), ys)
    dist = (xs - (a + b * yy)) * cos_t  # signed perpendicular distance, px
    delta = 1.0 / oversample
    lo = np.floor(dist.min() / delta) * delta
    idx = np.floor((dist - lo) / delta).astype(int).ravel()
    n_bins = idx.max() + 1
    counts = np.bincount(idx, minlength=n_bins)
    sums = np.bincount(idx, weights=img.ravel(), minlength=n_bins)
    centres = lo + (np.arange(n_bins) + 0.5) * delta
    # keep the bins whose full perpendicular range is covered by every row (no ragged ends)
    reach = min(np.abs(dist[:, 0]).min(), np.abs(dist[:, -1]).min())
    keep = (np.abs(centres) <= reach - delta) & (counts > 0)
    esf_x = centres[keep]
    esf = sums[keep] / counts[keep]
    k0, k1 = np.round((esf_x[[0, -1]] - lo) / delta - 0.5).astype(int)
    full = lo + (np.arange(k0, k1 + 1) + 0.5) * delta  # every bin centre in the kept range
    esf = np.interp(full, esf_x, esf)  # fills the rare empty bins only
    if esf[-1] < esf[0]:
        esf = esf[::-1]
        full = -full[::-1]
    lsf = np.zeros_like(esf)
    lsf[1:-1] = 0.5 * (esf[2:] - esf[:-2])
    n = len(lsf)
    centre = int(np.argmax(np.convolve(lsf, np.ones(5) / 5, mode="same")))
    half = min(centre, n - 1 - centre)
    lsf = lsf[centre - half:centre + half + 1]
    full = full[centre - half:centre + half + 1]
    t = np.linspace(-1.0, 1.0, len(lsf))
    taper = np.where(np.abs(t) <= 0.5, 1.0, 0.5 * (1.0 + np.cos(np.pi * (np.abs(t) - 0.5) / 0.5)))
    lsf = lsf * taper
    spec = np.abs(np.fft.rfft(lsf, n=max(n_fft, len(lsf))))
    freq = np.fft.rfftfreq(max(n_fft, len(lsf)), d=delta)
    mtf = spec / spec[0] / (np.sinc(2.0 * freq * delta) * np.sinc(freq * delta))
    sel = freq <= 1.0
    angle = float(np.degrees(np.arctan(b)))
    return Sfr(freq[sel], mtf[sel], angle, float(a), bool(transposed), full, esf)
