"""Small dense linear solves inside numba kernels (per-point normal equations)."""
from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True)
def solve_small(m, n):
    """Solve the n x n system in the augmented array m[:n, :n+1] in place (partial pivoting).
    Returns False if singular; the solution is left in m[:, n]."""
    for c in range(n):
        piv = c
        best = abs(m[c, c])
        for r in range(c + 1, n):
            if abs(m[r, c]) > best:
                best = abs(m[r, c])
                piv = r
        if not best > 1e-300:
            return False
        if piv != c:
            for k in range(n + 1):
                tmp = m[c, k]
                m[c, k] = m[piv, k]
                m[piv, k] = tmp
        for r in range(c + 1, n):
            f = m[r, c] / m[c, c]
            for k in range(c, n + 1):
                m[r, k] -= f * m[c, k]
    for c in range(n - 1, -1, -1):
        acc = m[c, n]
        for k in range(c + 1, n):
            acc -= m[c, k] * m[k, n]
        m[c, n] = acc / m[c, c]
    return True


@numba.njit(cache=True)
def cholesky_solve(H, g, n, x):
    """Solve H x = g for the leading n x n block of a symmetric positive-definite H by Cholesky, the
    factor written over H's lower triangle; False (x undefined) if H is not positive definite.
    (The per-point Levenberg-Marquardt step of ``locate.methods.patch_psf_fit``: a failed factor
    tells the fit to raise its damping.)"""
    for j in range(n):
        v = H[j, j]
        for k in range(j):
            v -= H[j, k] * H[j, k]
        if not v > 0.0:
            return False
        v = math.sqrt(v)
        H[j, j] = v
        for i in range(j + 1, n):
            w = H[i, j]
            for k in range(j):
                w -= H[i, k] * H[j, k]
            H[i, j] = w / v
    for i in range(n):
        w = g[i]
        for k in range(i):
            w -= H[i, k] * x[k]
        x[i] = w / H[i, i]
    for i in range(n - 1, -1, -1):
        w = x[i]
        for k in range(i + 1, n):
            w -= H[k, i] * x[k]
        x[i] = w / H[i, i]
    return True


@numba.njit(cache=True)
def inverse_00(H, n, work, e0, x):
    """(H^-1)_00 of the leading n x n block of a symmetric positive-definite H, by ``cholesky_solve`` of
    H x = e_0 on a copy (``work``, ``e0`` and ``x`` are scratch); inf if H is not positive definite.  The
    variance of a per-point fit's first parameter (its position) from its normal equations."""
    for a in range(n):
        e0[a] = 0.0
        for b in range(n):
            work[a, b] = H[a, b]
    e0[0] = 1.0
    return x[0] if cholesky_solve(work, e0, n, x) else np.inf
