"""Cramér–Rao bound for the position of a pixel-integrated blurred step (BRIEF §6).

A row across an axis-aligned edge: pixel k (centre t_k, relative to the
window centre) integrates I(t) = A + B Phi((t - mu)/s) over [t_k - 1/2,
t_k + 1/2]; noise N(0, sigma_n^2) per pixel.  The pixel mean of Phi is
    m_k = s [G1(u+) - G1(u-)],  u+- = (t_k +- 1/2 - mu) / s,  G1(u) = u Phi(u) + phi(u)
with dm/dmu = -(Phi(u+) - Phi(u-)) and dm/ds = phi(u+) - phi(u-).
Fisher matrix F = J^T J / sigma_n^2 over (A, B, mu, s); the bound on
std(mu) is sqrt((F^-1)_mumu) (all four unknown) or 1/sqrt(F_mumu) (mu only).
"""
from __future__ import annotations

import numpy as np
from scipy.special import ndtr

_INV_SQRT2PI = 1.0 / np.sqrt(2.0 * np.pi)


def _jacobian(mu, s, window, B=1.0):
    """(..., window, 4) Jacobian of the pixel means w.r.t. (A, B, mu, s); mu, s broadcast."""
    half = (window - 1) / 2.0
    t = np.arange(window) - half
    mu = np.asarray(mu, float)[..., None]
    s = np.asarray(s, float)[..., None]
    up = (t + 0.5 - mu) / s
    um = (t - 0.5 - mu) / s
    g1 = lambda u: u * ndtr(u) + _INV_SQRT2PI * np.exp(-0.5 * u * u)
    phi = lambda u: _INV_SQRT2PI * np.exp(-0.5 * u * u)
    m = s * (g1(up) - g1(um))
    d_mu = -(ndtr(up) - ndtr(um))
    d_s = phi(up) - phi(um)
    return np.stack([np.ones_like(m), m, B * d_mu, B * d_s], axis=-1)


def position_std_bound(blur_px: float, noise_rel: float, window: int = 11, mu_px: float = 0.0,
                       unknowns: str = "4p") -> float:
    """Lower bound on std(mu) in px for noise sigma_n / B = ``noise_rel``.

    ``unknowns``: "4p" (A, B, mu, s unknown), "mu" (only mu unknown),
    "2p" (mu, s unknown).  ``window``: number of pixels in the row (use a
    large odd number, e.g. 201, for an unlimited row).
    """
    return float(position_std_bound_many(blur_px, noise_rel, mu_px, window, unknowns))


def position_std_bound_many(blur_px, noise_rel, mu_px, window: int = 11, unknowns: str = "4p") -> np.ndarray:
    """``position_std_bound`` over broadcast arrays of blur, noise and offset (batched Fisher matrices)."""
    blur, noise, mu = np.broadcast_arrays(np.asarray(blur_px, float), np.asarray(noise_rel, float),
                                          np.asarray(mu_px, float))
    J = _jacobian(mu, blur, window)
    if unknowns == "mu":
        return noise / np.sqrt(np.sum(J[..., 2] ** 2, axis=-1))
    cols = {"4p": [0, 1, 2, 3], "2p": [2, 3]}[unknowns]
    Jc = J[..., cols]
    F = np.swapaxes(Jc, -1, -2) @ Jc
    cov = np.linalg.inv(F)
    i = cols.index(2)
    return noise * np.sqrt(cov[..., i, i])


def continuous_mu_only_bound(blur_px: float, noise_rel: float) -> float:
    """The closed form (4 pi)^(1/4) (sigma_n/B) sqrt(s_eff), s_eff = sqrt(s^2 + 1/12), for an unlimited row."""
    s_eff = np.sqrt(blur_px**2 + 1.0 / 12.0)
    return float((4 * np.pi) ** 0.25 * noise_rel * np.sqrt(s_eff))
