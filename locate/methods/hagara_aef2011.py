"""HagaraAEF2011: error-function fit of the gray profile over a fixed long window.

Paper: M. Hagara, P. Kulla, "Edge detection with sub-pixel accuracy based on
approximation of edge with Erf function", Measurement Science Review 11(3),
2011 (citation as given in the project brief).  A 1-D edge is approximated
by an error function and its position is the fitted inflection point; the
paper evaluates the method for various numbers of samples of one fixed
window -- there is no adaptive window.

Implementation in the study's unified framework (same Canny candidates and
the same 11-sample normal profile p + t n, t = -5..5, as every method):

    I(t) = a + b * erf((t - mu) / (sqrt(2) sigma))
         = A + B * Phi((t - mu) / sigma),   A = a - b, B = 2 b,

least squares over ALL 11 samples (the fixed long window; the seed's
"fixed-window ERF" also uses 11), all four parameters free,
Levenberg-Marquardt in ``edgetruth.locate.curve_fit_kernels`` (model code ERF).
The edge point is p + mu n.

Choices the paper leaves open here:
  * window: 11 samples (t = -5..5, unit step) -- the longest window the
    shared candidates guarantee inside the image; not extended further.
  * initial values: A = min, B = max - min of the profile, mu and sigma
    from the mean and spread of the positive profile differences (the
    paper's own closed-form starting estimates are not reproduced).
  * stopping: |d mu| < 1e-7 px and |d sigma| < 1e-5 px per step, 100 iterations.
  * failure (converged=False, candidate pixel kept): no contrast, no
    convergence, mu outside [-5, 5], sigma outside (0.05, 20) px or B <= 0.

Mathematically this is the same estimator as ERF4P-fixed11 (BRIEF §2); the
two differ only in starting values, stopping rule and Phi (A&S 7.1.26 there,
|error| 1.5e-7; ``locate.normal_cdf`` here, 2e-13), so on well-posed profiles
they agree to the LM tolerance.

Extras: A, B, width (= sigma, px), a, b (the paper's parametrisation), offset,
rss, iterations, status, se.
"""
from __future__ import annotations

from edgetruth.locate import curve_fit_kernels as CF
from edgetruth.locate import footprints as FP
from edgetruth.locate.registry import register

MAXIT = 100
TOL_PX = 1e-7  # accepted step (px); quadratic convergence leaves far less, as in locate.methods.erf


@register("hagara_aef2011", "HagaraAEF2011", family="baseline", footprint=FP.profile(5))
def hagara_aef2011(image, cand, maxit: int = MAXIT, tol_px: float = TOL_PX):
    """HagaraAEF2011: 4-parameter erf fit of the whole 11-sample normal profile."""
    r = CF.refine_step_model(image, cand, CF.ERF, maxit, tol_px)
    r.extras["b"] = 0.5 * r.extras["B"]
    r.extras["a"] = r.extras["A"] + r.extras["b"]
    return r
