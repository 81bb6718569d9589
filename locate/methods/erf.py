"""The study's ERF family: fixed-window 2P/4P fits and the entropy-guided dynamic window.

Ids: erf2p_fixed5|7|9|11, erf4p_fixed5|7|9|11, dynamic_erf_2p, dynamic_erf_4p.
Definitions in BRIEF §2; kernels in ``edgetruth.locate.erf_kernels``.

Extras per point: A, B, s (blur scale, px), offset (mu, px along n),
window (samples used), entropy (normalised gradient entropy of the
11-sample profile), rss, iterations, status, se (standard error of the
position, px).  ``se`` = sigma * sqrt((J^T J)^-1_mumu) with sigma^2 the
image's pooled residual variance (sum rss / sum dof over converged points):
a per-point estimate from 1-7 degrees of freedom is too noisy to give
honest intervals.  For 2P the covariance treats A, B as known, so its se
is optimistic.
"""
from __future__ import annotations

import numpy as np

from edgetruth.errors import InputError
from edgetruth.locate import erf_kernels as K
from edgetruth.locate import footprints as FP
from edgetruth.locate import thresholds as _thr
from edgetruth.locate.registry import register
from edgetruth.locate.result import Refinement

WINDOWS = (5, 7, 9, 11)
MAXIT = 50
TOL_PX = 1e-5  # accepted step < 1e-5 px: quadratic convergence leaves ~1e-10 px; agreement with scipy ~5e-7 px


def erf_refine(image, cand, four_param: bool, window: int = 0, tau=None, maxit: int = MAXIT, tol_px: float = TOL_PX):
    """Run the ERF kernel on every candidate; ``window=0`` selects the dynamic window."""
    if window not in (0,) + WINDOWS:
        raise InputError(f"window={window}: must be one of {WINDOWS} (or 0 for the dynamic window)")
    if tau is None:
        tau = _thr.load("4p" if four_param else "2p")
    t1, t2, t3 = _thr.validate(tau)
    n = len(cand)
    profiles = np.empty((n, K.PROFILE_LEN))
    entropy = np.empty(n)
    windows = np.empty(n, np.int64)
    out = np.empty((n, 8))
    K.refine_erf(image, cand.x, cand.y, cand.nx, cand.ny, int(window), t1, t2, t3, bool(four_param),
                 int(maxit), float(tol_px), profiles, entropy, windows, out)
    return finish(cand, out, windows, entropy, four_param)


def finish(cand, out, windows, entropy, four_param: bool) -> Refinement:
    status = out[:, 7].astype(np.int64)
    conv = status == K.OK
    mu = np.where(conv, out[:, 2], 0.0)
    npar = 4 if four_param else 2
    dof = windows - npar
    use = conv & (dof > 0) & np.isfinite(out[:, 4])
    sigma2 = out[use, 4].sum() / dof[use].sum() if use.any() else np.nan
    c_mumu = out[:, 5]
    se = np.sqrt(sigma2 * np.where(c_mumu > 0, c_mumu, np.nan))
    return Refinement.from_offset(
        cand, mu, conv,
        A=out[:, 0], B=out[:, 1], s=out[:, 3], window=windows, entropy=entropy,
        rss=out[:, 4], iterations=out[:, 6].astype(np.int64), status=status, se=np.where(conv, se, np.nan),
    )


def _make(method_id: str, label: str, family: str, four_param: bool, window: int):
    def fn(image, cand, tau=None, maxit: int = MAXIT, tol_px: float = TOL_PX):
        return erf_refine(image, cand, four_param, window, tau, maxit, tol_px)

    fn.__doc__ = f"{label}: ERF {'4P' if four_param else '2P'} fit, " + (
        f"fixed {window}-sample window" if window else "entropy-guided dynamic window")
    # the fit reads its window's samples; the dynamic window's choice reads all 11
    register(method_id, label, family, footprint=FP.profile((window - 1) // 2 if window else K.PROFILE_HALF))(fn)


for _w in WINDOWS:
    _make(f"erf2p_fixed{_w}", f"ERF2P-fixed{_w}", "erf-fixed", False, _w)
for _w in WINDOWS:
    _make(f"erf4p_fixed{_w}", f"ERF4P-fixed{_w}", "erf-fixed", True, _w)
_make("dynamic_erf_2p", "ProposedDynamicERF_2P", "proposed", False, 0)
_make("dynamic_erf_4p", "ProposedDynamicERF_4P", "proposed", True, 0)
