"""SigmoidLogisticFit2023: logistic (sigmoid) model fitted to the gray profile.

The study's reference [24] (2023) describes the gray-level transition across
an edge by a logistic function; the edge is the sigmoid's centre.

Implementation in the study's unified framework (same Canny candidates, the
same 11-sample normal profile p + t n, t = -5..5):

    I(t) = A + B / (1 + exp(-(t - mu) / w))

4-parameter least squares (A, B, mu, w) over the 11 samples by
Levenberg-Marquardt (``edgetruth.locate.curve_fit_kernels``, model code LOGISTIC,
evaluated overflow-free).  The model is point-symmetric about its centre, so
a symmetric blurred step gives mu at the 50 % crossing.  The logistic is
close to a Gaussian-blurred step (w ~ 0.6 sigma), which is why this baseline
performs close to the erf fits.

Choices left open (the reference's exact fitting procedure is not available
here): window 11 samples; initial A = min, B = max - min, mu and a width
from the positive profile differences, w matched by equal central slope
(w = sd sqrt(2 pi)/4); stopping |d mu| < 1e-7 px and |d w| < 1e-5 px per step, 100 iterations;
failure (converged=False, candidate pixel kept) when there is no contrast,
no convergence, mu outside [-5, 5], w outside (0.05, 20) px or B <= 0.

Extras: A, B, width (w, px), offset, rss, iterations, status, se.
"""
from __future__ import annotations

from edgetruth.locate import curve_fit_kernels as CF
from edgetruth.locate import footprints as FP
from edgetruth.locate.registry import register

MAXIT = 100
TOL_PX = 1e-7  # accepted step (px); quadratic convergence leaves far less, as in locate.methods.erf


@register("sigmoid_logistic_fit2023", "SigmoidLogisticFit2023", family="baseline", footprint=FP.profile(5))
def sigmoid_logistic_fit2023(image, cand, maxit: int = MAXIT, tol_px: float = TOL_PX):
    """SigmoidLogisticFit2023: 4-parameter logistic fit of the 11-sample normal profile."""
    return CF.refine_step_model(image, cand, CF.LOGISTIC, maxit, tol_px)
