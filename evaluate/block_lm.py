"""Levenberg-Marquardt for a calibration's structure: shared parameters (the lens) and one independent block per
view (its pose, its board's bend), every residual row belonging to one view.

The normal equations are solved by the Schur complement on the shared parameters, as bundle adjustment does,
so time and memory grow linearly with the number of views (a dense solver's Jacobian of 200 views of 100
corners at 13 parameters a view is 0.8 GB; here it is the per-view blocks).  The Jacobian is taken by central
differences, one column of the shared parameters at a time and one block column for all views at once (a
view's rows depend on its own block only), so it costs 2 × (shared + block size) residual evaluations whatever
the number of views.  Damping is Marquardt's (λ times the normal matrix's diagonal).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares


#: central-difference step, relative to max(|parameter|, STEP_FLOOR)
STEP = 1e-6
STEP_FLOOR = 1e-2
MAX_ITERATIONS = 200


@dataclass
class Fit:
    """The solution: ``shared`` (ns,), ``blocks`` (V, nb), ``residual`` (m,), and ``block_var`` (V, nb): each
    block parameter's variance per unit residual variance, the diagonal of (JᵀJ)⁻¹ (NaN where held fixed)."""

    shared: np.ndarray
    blocks: np.ndarray
    residual: np.ndarray
    block_var: np.ndarray
    iterations: int
    #: (ns,) each shared parameter's variance per unit residual variance (NaN where held fixed)
    shared_var: np.ndarray | None = None


def _jacobian(residual, shared, blocks, fs, fb, row_block):
    cols_s = []
    for i in np.flatnonzero(fs):
        h = STEP * max(abs(shared[i]), STEP_FLOOR)
        up, down = shared.copy(), shared.copy()
        up[i] += h
        down[i] -= h
        cols_s.append((residual(up, blocks) - residual(down, blocks)) / (2 * h))
    cols_b = []
    for j in np.flatnonzero(fb):
        h = STEP * np.maximum(np.abs(blocks[:, j]), STEP_FLOOR)
        up, down = blocks.copy(), blocks.copy()
        up[:, j] += h
        down[:, j] -= h
        cols_b.append((residual(shared, up) - residual(shared, down)) / (2 * h[row_block]))
    m = len(row_block)
    return (np.stack(cols_s, 1) if cols_s else np.zeros((m, 0))), np.stack(cols_b, 1)


def _normal(Js, Jb, r, starts):
    """The normal equations' parts: U (ns, ns), W (V, ns, nb), Vb (V, nb, nb), gradients gs (ns,), gb (V, nb)."""
    U = Js.T @ Js
    W = np.add.reduceat(Js[:, :, None] * Jb[:, None, :], starts, axis=0)
    Vb = np.add.reduceat(Jb[:, :, None] * Jb[:, None, :], starts, axis=0)
    gb = np.add.reduceat(Jb * r[:, None], starts, axis=0)
    return U, W, Vb, Js.T @ r, gb


def _damped(M, lam):
    """M + λ diag(M) (batched), with a floor on the diagonal so a parameter without effect stays solvable."""
    d = np.diagonal(M, axis1=-2, axis2=-1)
    floor = 1e-12 * max(float(np.max(d, initial=0.0)), 1e-300)
    return M + (lam * np.maximum(d, floor) + (d <= floor) * floor)[..., None] * np.eye(M.shape[-1])


def _step(U, W, Vb, gs, gb, lam):
    """Solve (A + λ diag A) δ = −g by the Schur complement on the shared parameters."""
    Vinv = np.linalg.inv(_damped(Vb, lam))
    Y = W @ Vinv  # (V, ns, nb)
    S = _damped(U, lam) - np.einsum("vij,vkj->ik", Y, W)
    ds = np.linalg.solve(S, -gs + np.einsum("vij,vj->i", Y, gb)) if len(gs) else np.zeros(0)
    db = -np.einsum("vij,vj->vi", Vinv, gb + np.einsum("vij,i->vj", W, ds))
    return ds, db


def solve(residual, shared0, blocks0, row_block, free_shared, free_block, rel_tol: float = 1e-12) -> Fit:
    """Minimise |residual(shared, blocks)|² from (shared0 (ns,), blocks0 (V, nb)) over the ``free_shared`` (ns,)
    and ``free_block`` (nb,; the same for every view) entries.  ``row_block`` (m,): the view of each residual row,
    non-decreasing, every view with rows.  Stops when an accepted step lowers the cost by less than ``rel_tol``
    of it, or no damping finds a lower cost."""
    shared, blocks = np.asarray(shared0, float).copy(), np.asarray(blocks0, float).copy()
    fs, fb = np.asarray(free_shared, bool), np.asarray(free_block, bool)
    row_block = np.asarray(row_block)
    starts = np.flatnonzero(np.r_[True, np.diff(row_block) != 0])
    if len(starts) != len(blocks) or np.any(np.diff(row_block) < 0):
        raise ValueError("row_block: rows must be grouped by view, in order, every view with rows")
    r = residual(shared, blocks)
    cost, lam, it = float(r @ r), 1e-3, 0
    for it in range(1, MAX_ITERATIONS + 1):
        parts = _normal(*_jacobian(residual, shared, blocks, fs, fb, row_block), r, starts)
        while True:
            ds, db = _step(*parts, lam)
            s_new, b_new = shared.copy(), blocks.copy()
            s_new[fs] += ds
            b_new[:, fb] += db
            r_new = residual(s_new, b_new)
            c_new = float(r_new @ r_new)
            if np.isfinite(c_new) and c_new < cost:
                gain, lam = cost - c_new, max(lam / 3.0, 1e-12)
                shared, blocks, r, cost = s_new, b_new, r_new, c_new
                break
            lam *= 4.0
            if lam > 1e12:
                gain = 0.0
                break
        if gain <= rel_tol * cost:
            break
    U, W, Vb, _, _ = _normal(*_jacobian(residual, shared, blocks, fs, fb, row_block), r, starts)
    Vinv = np.linalg.pinv(Vb)
    Y = W @ Vinv
    S = U - np.einsum("vij,vkj->ik", Y, W)
    var = np.einsum("vii->vi", Vinv + np.einsum("vij,ik,vkl->vjl", Y, np.linalg.pinv(S), Y))
    block_var = np.full(blocks.shape, np.nan)
    block_var[:, fb] = var
    shared_var = np.full(shared.shape, np.nan)
    shared_var[fs] = np.diag(np.linalg.pinv(S))  # the shared block of (J^T J)^-1 is the Schur complement's inverse
    return Fit(shared, blocks, r, block_var, it, shared_var)


def solve_dense(residual, shared0, blocks0, row_block, free_shared, free_block, rel_tol: float = 1e-12) -> Fit:
    """The reference for ``solve``: scipy's MINPACK Levenberg-Marquardt on all free parameters at once, with a
    dense forward-difference Jacobian (time and memory grow with the square of the views; tests and
    ``edgetruth bench --only calibrate`` compare the two)."""
    shared0, blocks0 = np.asarray(shared0, float), np.asarray(blocks0, float)
    fs, fb = np.asarray(free_shared, bool), np.asarray(free_block, bool)
    n_views = len(blocks0)

    def unpack(v):
        s, b = shared0.copy(), blocks0.copy()
        s[fs] = v[:fs.sum()]
        b[:, fb] = v[fs.sum():].reshape(n_views, -1)
        return s, b

    r = least_squares(lambda v: residual(*unpack(v)), np.r_[shared0[fs], blocks0[:, fb].ravel()], method="lm",
                      x_scale="jac", xtol=rel_tol, ftol=rel_tol, max_nfev=100 * MAX_ITERATIONS)
    shared, blocks = unpack(r.x)
    diag = np.diag(np.linalg.pinv(r.jac.T @ r.jac))
    block_var = np.full(blocks.shape, np.nan)
    block_var[:, fb] = diag[fs.sum():].reshape(n_views, -1)
    shared_var = np.full(shared.shape, np.nan)
    shared_var[fs] = diag[:fs.sum()]
    return Fit(shared, blocks, r.fun, block_var, int(r.nfev), shared_var)
