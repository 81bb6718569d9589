"""The robust line fit's loops as numba kernels, bit for bit the numpy code they replace.

``fit_line_robust`` (``edgetruth.evaluate.ranging.size``) runs ~33,000 times per quick run (12 lines per
square, per method, per image): RANSAC on point pairs, then Tukey-biweight IRLS total least squares to
1e-7 px.  In numpy each IRLS step is a dozen small-array calls; here one kernel runs the whole fit.
The answers are the same to the last bit: sums use numpy's own pairwise summation (``pairwise_sum``:
8 accumulators up to 128 elements, halving above), medians the same order statistics, and every
expression keeps numpy's operation order (tests/evaluate/ranging/test_line_kernels.py checks equality
with the numpy implementation).
"""
from __future__ import annotations

import math

import numpy as np

from edgetruth.jit import njit
from edgetruth.locate import exact_sum as XS


@njit(cache=True)
def pairwise_sum(a, lo, n):
    """numpy's ``add.reduce`` of the contiguous float64 ``a[lo:lo + n]``, bit for bit: blocks of <= 128,
    halved (at a multiple of 8) above.  Iterative, with its own stack: numba's on-disk cache cannot
    reload a recursive function (it crashes the process)."""
    if n <= XS.BLOCK:
        return XS.block_sum(a, lo, n)
    los = np.empty(64, np.int64)
    ns = np.empty(64, np.int64)
    state = np.zeros(64, np.int64)  # 0: split next, 1: left done, 2: both done
    vals = np.empty(64)
    sp, vt = 1, 0
    los[0], ns[0], state[0] = lo, n, 0
    while sp > 0:
        top = sp - 1
        m = ns[top]
        if m <= XS.BLOCK:
            vals[vt] = XS.block_sum(a, los[top], m)
            vt += 1
            sp -= 1
            continue
        n2 = m // 2
        n2 -= n2 % 8
        if state[top] == 0:
            state[top] = 1
            los[sp], ns[sp], state[sp] = los[top], n2, 0
            sp += 1
        elif state[top] == 1:
            state[top] = 2
            los[sp], ns[sp], state[sp] = los[top] + n2, m - n2, 0
            sp += 1
        else:
            vals[vt - 2] = vals[vt - 2] + vals[vt - 1]
            vt -= 1
            sp -= 1
    return vals[0]


@njit(cache=True)
def _sum(a):
    # np.int64(0), not 0: a literal argument makes numba compile another copy of pairwise_sum and
    # block_sum specialised to it (1.4 s of a cold start for the same code)
    return pairwise_sum(a, np.int64(0), a.size)


@njit(cache=True, forceinline=True)
def _before(a, b):
    """``a`` sorts before ``b`` in ``np.sort``'s order (NaN last)."""
    return a < b or (b != b and a == a)


@njit(cache=True)
def _heapsort(s):
    """Sort ``s`` in place into ``np.sort``'s order (a sort's order statistics are the same whatever the
    algorithm).  numba's own ``np.sort`` costs ~2 s of a cold start to compile; this, a fraction."""
    n = s.size
    for start in range(n // 2 - 1, -1, -1):
        _sift(s, start, n)
    for end in range(n - 1, 0, -1):
        s[0], s[end] = s[end], s[0]
        _sift(s, np.int64(0), end)  # typed: a literal 0 compiles a second _sift


@njit(cache=True, forceinline=True)
def _sift(s, i, n):
    while True:
        c = 2 * i + 1
        if c >= n:
            return
        if c + 1 < n and _before(s[c], s[c + 1]):
            c += 1
        if not _before(s[i], s[c]):
            return
        s[i], s[c] = s[c], s[i]
        i = c


@njit(cache=True)
def _median(v):
    """``np.median`` of a 1-D array (the middle order statistic, or the mean of the two)."""
    n = v.size
    if n == 0:
        return np.nan
    s = v.copy()
    _heapsort(s)
    k = n // 2
    if n % 2:
        return s[k]
    return (s[k - 1] + s[k]) / 2.0


@njit(cache=True)
def _tls(x, y, w, buf):
    """Weighted total-least-squares line (nx, ny, d), as ``size._tls``; ``buf`` scratch of len(x)."""
    sw = _sum(w)
    for i in range(x.size):
        buf[i] = w[i] * x[i]
    mx = _sum(buf) / sw
    for i in range(x.size):
        buf[i] = w[i] * y[i]
    my = _sum(buf) / sw
    for i in range(x.size):
        buf[i] = w[i] * (x[i] - mx) * (x[i] - mx)
    sxx = _sum(buf)
    for i in range(x.size):
        buf[i] = w[i] * (x[i] - mx) * (y[i] - my)
    sxy = _sum(buf)
    for i in range(x.size):
        buf[i] = w[i] * (y[i] - my) * (y[i] - my)
    syy = _sum(buf)
    theta = 0.5 * math.atan2(2.0 * sxy, sxx - syy)
    nx, ny = -math.sin(theta), math.cos(theta)
    return nx, ny, nx * mx + ny * my


@njit(cache=True)
def ransac_best(x, y, nx, ny, d, threshold_px):
    """Index of the candidate line (nx, ny, d) with the most points within ``threshold_px`` (the first of
    equals, as ``np.argmax``)."""
    best_k, best_c = 0, -1
    for k in range(nx.size):
        c = 0
        for j in range(x.size):
            if abs(nx[k] * x[j] + ny[k] * y[j] - d[k]) < threshold_px:
                c += 1
        if c > best_c:
            best_k, best_c = k, c
    return best_k


@njit(cache=True)
def irls_line(x, y, w, tukey_c, sigma_floor_px, tol_px, max_iter):
    """Tukey-biweight IRLS total least squares from weights ``w`` (modified in place): (nx, ny, d, rms_px);
    ``w > 0`` marks the inliers on return."""
    n_pts = x.size
    buf = np.empty(n_pts)
    r = np.empty(n_pts)
    w_new = np.empty(n_pts)
    nx, ny, d = _tls(x, y, w, buf)
    for _ in range(max_iter):
        m = 0
        for i in range(n_pts):
            r[i] = nx * x[i] + ny * y[i] - d
            if w[i] > 0:
                buf[m] = r[i]
                m += 1
        med = _median(buf[:m])
        for i in range(m):
            buf[i] = abs(buf[i] - med)
        s = max(1.4826 * _median(buf[:m]), sigma_floor_px)
        nz = 0
        for i in range(n_pts):
            u = r[i] / (tukey_c * s)
            if abs(u) < 1:
                t = 1 - u * u
                w_new[i] = t * t
                nz += w_new[i] != 0.0
            else:
                w_new[i] = 0.0
        if _sum(w_new) < 2 or nz < 2:
            break
        nx2, ny2, d2 = _tls(x, y, w_new, buf)
        if nx2 * nx + ny2 * ny < 0:
            nx2, ny2, d2 = -nx2, -ny2, -d2
        done = abs(d2 - d) < tol_px and math.sqrt((nx2 - nx) ** 2 + (ny2 - ny) ** 2) < tol_px * 1e-3
        nx, ny, d = nx2, ny2, d2
        w[:] = w_new
        if done:
            break
    m = 0
    for i in range(n_pts):
        if w[i] > 0:
            ri = nx * x[i] + ny * y[i] - d
            buf[m] = ri * ri
            m += 1
    rms = math.sqrt(pairwise_sum(buf, np.int64(0), np.int64(m)) / m) if m else np.nan  # typed: as in _sum
    return nx, ny, d, rms


@njit(cache=True)
def robust_line(x, y, pairs, threshold_px, tukey_c, sigma_floor_px, tol_px, max_iter, w):
    """``size.fit_line_robust`` after its random draws: the candidate lines through the point ``pairs``
    (draws with i0 != i1; those of coincident points dropped), RANSAC's best, its inliers as the start
    weights (all points when fewer than 2), then ``irls_line``.  ``w`` (n,) receives the final weights;
    returns (nx, ny, d, rms_px).  Each operation as the numpy code did it (tests)."""
    n_pts = x.size
    m = pairs.shape[0]
    cnx = np.empty(m)
    cny = np.empty(m)
    cd = np.empty(m)
    c = 0
    for j in range(m):
        i0, i1 = pairs[j, 0], pairs[j, 1]
        ex, ey = x[i1] - x[i0], y[i1] - y[i0]
        norm = math.hypot(ex, ey)
        if norm > 0:
            a, b = -ey / norm, ex / norm
            cnx[c], cny[c], cd[c] = a, b, a * x[i0] + b * y[i0]
            c += 1
    inliers = 0
    if c > 0:
        k = ransac_best(x, y, cnx[:c], cny[:c], cd[:c], threshold_px)
        for i in range(n_pts):
            if abs(cnx[k] * x[i] + cny[k] * y[i] - cd[k]) < threshold_px:
                w[i] = 1.0
                inliers += 1
            else:
                w[i] = 0.0
    if inliers < 2:
        w[:] = 1.0
    return irls_line(x, y, w, tukey_c, sigma_floor_px, tol_px, max_iter)
