"""ArctanFit2016: arctangent edge model fitted to the gray profile.

Paper: Q. Sun, Y. Hou, Q. Tan, G. Li, "A subpixel edge detection method based
on an arctangent edge model", Optik 127 (2016).  The gray transition across
an edge is modelled by an arctangent; the edge is its centre.

Implementation in the study's unified framework (same Canny candidates, the
same 11-sample normal profile p + t n, t = -5..5):

    I(t) = A + B * (1/2 + atan((t - mu) / w) / pi)

4-parameter least squares (A, B, mu, w) over the 11 samples by
Levenberg-Marquardt (``edgetruth.locate.curve_fit_kernels``, model code ARCTAN).  The
model is point-symmetric about (mu, A + B/2), so a symmetric blurred step
gives mu at its 50 % crossing; its heavy (Cauchy) tails do not match a
Gaussian-blurred edge, which costs precision, not bias, on symmetric edges.

Choices left open: window 11 samples (t = -5..5); initial A = min,
B = max - min, mu and a width from the positive profile differences, w
matched to that width by equal central slope (w = sd sqrt(2/pi)); stopping
|d mu| < 1e-7 px and |d w| < 1e-5 px per step, 100 iterations; failure (converged=False,
candidate pixel kept) when there is no contrast, no convergence, mu outside
[-5, 5], w outside (0.05, 20) px or B <= 0.

Extras: A, B, width (w, px), offset, rss, iterations, status, se.
"""
from __future__ import annotations

from edgetruth.locate import curve_fit_kernels as CF
from edgetruth.locate import footprints as FP
from edgetruth.locate.registry import register

MAXIT = 100
TOL_PX = 1e-7  # accepted step (px); quadratic convergence leaves far less, as in locate.methods.erf


@register("arctan_fit2016", "ArctanFit2016", family="baseline", footprint=FP.profile(5))
def arctan_fit2016(image, cand, maxit: int = MAXIT, tol_px: float = TOL_PX):
    """ArctanFit2016: 4-parameter arctangent fit of the 11-sample normal profile."""
    return CF.refine_step_model(image, cand, CF.ARCTAN, maxit, tol_px)
