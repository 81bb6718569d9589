"""Small dense linear solves inside numba kernels (per-point normal equations)."""
from __future__ import annotations

import numba


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
