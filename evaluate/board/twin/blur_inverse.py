"""The lens blur a twin renders with, from the edge blur a photo shows: the inverse of the photo model's ERF σ.

``photo_model.blur`` measures a side's blur as the σ of an ERF fitted to its pixels within ``ESF_HALF_WIDTH_PX``
of the line.  The renderer's edge is the pixel box, the diffraction of the circular pupil, a Gaussian aberration
σ_ab and a defocus disk (``render.optics.mtf.system_otf``), stored through the output's tone curve.  Taking the
pixel (1/12 px²) and the Airy core (σ = 0.42 λN) off the measured σ in quadrature leaves σ_ab too large: the
Airy pattern's tails widen the fitted ERF about twice as much as its core (at f/4, 6 µm and 550 nm: σ_ab 0.71 px
renders an ERF σ of 0.83 px, not 0.78).  ``aberration_sigma_px`` instead solves ``erf_sigma_px(σ_ab) = σ``.

A JPEG photo's σ is read after its JPEG, and the twin's JPEG blurs its renders again: what it adds is measured
apart (``jpeg_synthetic.jpeg_blur_px``) and taken off the photo's σ before this inverse.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

from edgetruth.evaluate.board.tone.photo_model import ESF_HALF_WIDTH_PX, fit_erf_batch
from edgetruth.render.optics.mtf import system_otf


#: the ESF's grid step (px) and length (samples) for the numerical LSF
STEP_PX = 1.0 / 64.0
N_SAMPLES = 8192
#: the largest aberration σ (px) the inverse looks for
MAX_SIGMA_AB_PX = 6.0


def model_esf(t_px: np.ndarray, sigma_ab_px: float, cutoff_cy_px: float, defocus_px: float = 0.0,
              linear_contrast: float = math.inf, gamma: float = 1.0) -> np.ndarray:
    """The stored edge, 0 to 1, at signed distances ``t_px`` from a straight edge along a pixel axis: the inverse
    transform of ``system_otf`` (pixel box, diffraction to ``cutoff_cy_px``, Gaussian ``sigma_ab_px``, defocus disk
    of radius ``defocus_px``), from a dark of 1/``linear_contrast`` of the white to the white in linear light, then
    stored as v^(1/``gamma``) (``render.sensor.pipeline``'s ``output_gamma``) and rescaled to 0..1."""
    nu = np.fft.rfftfreq(N_SAMPLES, d=STEP_PX)
    otf = system_otf(nu, 0.0, cutoff_cy_px=cutoff_cy_px, sigma_px=sigma_ab_px, defocus_px=defocus_px)
    lsf = np.fft.fftshift(np.fft.irfft(otf, n=N_SAMPLES))
    grid = (np.arange(N_SAMPLES) - N_SAMPLES // 2) * STEP_PX
    esf = np.cumsum(lsf)
    esf = (esf - esf[0]) / (esf[-1] - esf[0])
    if gamma != 1.0:
        dark = 0.0 if math.isinf(linear_contrast) else 1.0 / linear_contrast
        lo, hi = dark ** (1.0 / gamma), 1.0
        esf = ((dark + (1.0 - dark) * np.clip(esf, 0.0, 1.0)) ** (1.0 / gamma) - lo) / (hi - lo)
    return np.interp(np.asarray(t_px, float), grid, esf)


def erf_sigma_px(sigma_ab_px: float, cutoff_cy_px: float, defocus_px: float = 0.0,
                 linear_contrast: float = math.inf, gamma: float = 1.0) -> float:
    """The σ (px) ``photo_model.fit_erf_batch`` fits to ``model_esf`` sampled densely within ``ESF_HALF_WIDTH_PX``
    of the edge: what ``photo_model.blur`` reads on a render of these optics (no noise, no JPEG)."""
    t = np.linspace(-ESF_HALF_WIDTH_PX, ESF_HALF_WIDTH_PX, 1537)
    v = model_esf(t, sigma_ab_px, cutoff_cy_px, defocus_px, linear_contrast, gamma)
    return float(fit_erf_batch([t], [v])["sigma"][0])


def aberration_sigma_px(sigma_px: float, cutoff_cy_px: float, defocus_px: float = 0.0,
                        linear_contrast: float = math.inf, gamma: float = 1.0) -> float:
    """The Gaussian aberration σ_ab (px) whose rendered edge reads ERF σ = ``sigma_px`` (``erf_sigma_px``); 0 when
    the pixel, diffraction and defocus alone already read ``sigma_px`` or more."""
    def gap(s: float) -> float:
        return erf_sigma_px(s, cutoff_cy_px, defocus_px, linear_contrast, gamma) - sigma_px

    if not math.isfinite(sigma_px) or gap(0.0) >= 0.0:
        return 0.0
    if gap(MAX_SIGMA_AB_PX) < 0.0:
        return MAX_SIGMA_AB_PX
    return float(brentq(gap, 0.0, MAX_SIGMA_AB_PX, xtol=1e-6))

