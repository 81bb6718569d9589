"""GaussianFit2014: Gaussian fit of the gradient profile; the peak is the edge.

Reference: A. Fabijanska, "Gaussian-based approach to subpixel detection of
blurred and unsharp edges", Proc. FedCSIS 2014 (the study's [20]; the idea
goes back to her 2012 AMCS survey): the image gradient across the edge is
reconstructed with a Gaussian function and the edge is the Gaussian's peak.

Implementation in the study's unified framework (same Canny candidates, the
same 11-sample normal profile I_k = I(p + t_k n), t_k = -5..5):

  * gradient profile: the 10 first differences g_k = I_{k+1} - I_k, placed
    at the mid-points t = -4.5 .. 4.5.  (Chosen over sampling the smoothed
    Sobel field along n: it uses exactly the samples every other profile
    method uses, adds no second interpolation of a derivative field, and for
    a symmetric blurred step it is a symmetric bump centred on the edge.)
  * model, constant-free:  g(t) = a exp(-(t - mu)^2 / (2 w^2)).
  * variant "lsq" (default): least squares over all 10 differences,
    Levenberg-Marquardt in ``edgetruth.locate.curve_fit_kernels`` (model code GAUSS),
    started from the log-parabola estimate below.
  * variant "log3": the classic closed form -- the parabola through
    ln g at the largest difference and its two neighbours,
    mu = t_m + (ln g_- - ln g_+) / (2 (ln g_- - 2 ln g_m + ln g_+)).

Which of the two the 2014 paper uses is not settled by the material
available here (the paper is described as reconstructing the gradient
function with a Gaussian, i.e. a fit); the default is therefore the full
least-squares fit, and "log3" is offered for comparison.

Failure (converged=False, candidate pixel kept): no positive difference, no
convergence, peak outside [-4.5, 4.5], w outside (0.05, 18) px or a <= 0;
for "log3": the largest difference at the window's end or a non-positive
neighbour (log undefined), or a non-concave log-parabola.

Extras: amplitude (a, gray levels/px), width (w, px), offset, rss,
iterations, status, se (lsq); amplitude, width, offset (log3).
"""
from __future__ import annotations

import numpy as np

from edgetruth.errors import InputError
from edgetruth.locate import curve_fit_kernels as CF
from edgetruth.locate.profiles import profile_offsets, sample_profiles
from edgetruth.locate import footprints as FP
from edgetruth.locate.registry import register
from edgetruth.locate.result import Refinement

MAXIT = 100
TOL_PX = 1e-7  # accepted step (px); quadratic convergence leaves far less, as in locate.methods.erf
VARIANTS = ("lsq", "log3")


def gradient_profiles(image, cand):
    """(N, 10) first differences of the 11-sample normal profiles and their positions t (10,)."""
    t = profile_offsets()
    prof = sample_profiles(image, cand)
    return np.diff(prof, axis=1), 0.5 * (t[1:] + t[:-1])


def log_parabola(g, tg):
    """Vectorised three-point Gaussian (log-parabola) peak: (mu, w, a, ok) per row of g."""
    n = g.shape[0]
    rows = np.arange(n)
    k = np.argmax(g, axis=1)
    inner = (k > 0) & (k < g.shape[1] - 1)
    kk = np.clip(k, 1, g.shape[1] - 2)
    gm, g0, gp = g[rows, kk - 1], g[rows, kk], g[rows, kk + 1]
    pos = inner & (gm > 0) & (g0 > 0) & (gp > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        lm, l0, lp = np.log(np.where(pos, gm, 1.0)), np.log(np.where(pos, g0, 1.0)), np.log(np.where(pos, gp, 1.0))
        den = lm - 2.0 * l0 + lp
        ok = pos & (den < 0)
        off = np.where(ok, 0.5 * (lm - lp) / np.where(ok, den, -1.0), 0.0)
        h = tg[1] - tg[0]
        mu = tg[kk] + off * h
        w = np.where(ok, h * np.sqrt(-1.0 / np.where(ok, den, -1.0)), np.nan)
        a = np.where(ok, np.exp(l0 - 0.25 * (lm - lp) * off), np.nan)
    return mu, w, a, ok


@register("gaussian_fit2014", "GaussianFit2014", family="baseline", footprint=FP.profile(5))
def gaussian_fit2014(image, cand, variant: str = "lsq", maxit: int = MAXIT, tol_px: float = TOL_PX):
    """GaussianFit2014: Gaussian fit of the profile differences along the normal; peak = edge."""
    if variant not in VARIANTS:
        raise InputError(f"variant={variant!r}: choose one of {', '.join(VARIANTS)}")
    if variant == "log3":
        g, tg = gradient_profiles(image, cand)
        mu, w, a, ok = log_parabola(g, tg)
        ok &= np.abs(mu) <= tg[-1]
        return Refinement.from_offset(cand, np.where(ok, mu, 0.0), ok, amplitude=a, width=w)
    return CF.refine_gauss_differences(image, cand, maxit, tol_px)
