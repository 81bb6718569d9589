"""Is a calibration's residual noise, or a smooth field per view?  (``edgetruth calibrate``'s board check.)

Zhang's calibration leaves each corner a reprojection residual.  Corner noise leaves residuals that do not
depend on one another.  A board that is not flat (a hand-held print that bends, differently in each photo) or
corners biased along the board leave a *smooth* field over each view's corners, which no pose or lens term
absorbs.  Two numbers tell them apart, per calibration:

- ``neighbour_correlation``: the cosine similarity of the residual vectors of corners one square apart on the
  board, over all such pairs of all views (≈ 0 for noise; a smooth field gives > 0);
- ``smooth_share``: the share of the residuals' energy that a quadratic field per view and per axis takes (in
  board coordinates: 1, x, y, x², xy, y²); noise alone gives ``smooth_share_chance`` = Σ 6 / Σ n (each view's
  6-term projection of n independent residuals keeps 6/n of their energy on average), and ``p_value`` is the
  share of ``PERMUTATIONS`` shuffles of the residuals among each view's corners whose share reaches it;
- ``smooth_excess`` = (share − chance) / (1 − chance): the part of what noise would leave unexplained that the
  field takes (the effect size; with many corners a tiny field is significant).  The reading calls the
  residuals smooth when p < 0.01 *and* the excess reaches ``SMOOTH_EXCESS`` (0.1).

A lens term the calibration leaves out makes a smooth field too: OpenCV's twin calibrated with k1, k2 only takes
81 % (its lens has p1 = 0.001), and 11 % with k1, k2, p1, p2 (``board_bend`` names which it is).

Measured (docs/board.md): OpenCV's left photos (54 line corners each): neighbour correlation 0.60, share 0.46
against 0.11 by chance (excess 0.40); their twin (a flat board rendered): −0.24, 0.11 (p = 0.26); Zhang's own
corners of his photos: 0.09, 0.04 against 0.02 (p <= 0.0005, excess 0.02: mostly noise).
"""
from __future__ import annotations

import numpy as np

#: shuffles for the permutation test of the smooth share
PERMUTATIONS = 2000
QUADRATIC_TERMS = 6
#: the excess share (module docstring) from which significant residuals are called smooth rather than mostly noise
SMOOTH_EXCESS = 0.1


def _design(board_xy: np.ndarray) -> np.ndarray:
    """(n, 6) quadratic terms of board coordinates scaled to about [-1, 1] (for conditioning)."""
    p = np.asarray(board_xy, float)
    c = p.mean(0)
    s = np.maximum(np.abs(p - c).max(0), 1e-12)
    x, y = ((p - c) / s).T
    return np.stack([np.ones_like(x), x, y, x * x, x * y, y * y], axis=1)


def residual_structure(board_xy: list[np.ndarray], residuals: list[np.ndarray], pitch: float,
                       seed: int = 0) -> dict:
    """``board_xy``: per view (n, 2) the corners' board coordinates; ``residuals``: per view (n, 2) measured minus
    projected (px); ``pitch``: the distance between neighbouring corners in board units.  Returns the module
    docstring's numbers (views with fewer than 12 corners are skipped)."""
    rng = np.random.default_rng(seed)
    fitted = total = dof = 0.0
    null = np.zeros(PERMUTATIONS)
    dot = norm_a = norm_b = 0.0
    n_points = n_views = 0
    for xy, r in zip(board_xy, residuals):
        xy, r = np.asarray(xy, float), np.asarray(r, float)
        ok = np.all(np.isfinite(r), axis=1) & np.all(np.isfinite(xy), axis=1)
        xy, r = xy[ok], r[ok]
        n = len(r)
        if n < 2 * QUADRATIC_TERMS:
            continue
        q, _ = np.linalg.qr(_design(xy))  # orthonormal basis of the quadratic fields over these corners
        fitted += float(np.sum((q.T @ r) ** 2))
        total += float(np.sum(r * r))
        dof += QUADRATIC_TERMS
        perm = np.stack([r[rng.permutation(n)] for _ in range(PERMUTATIONS)])  # (P, n, 2)
        null += np.sum(np.einsum("nk,pnj->pkj", q, perm) ** 2, axis=(1, 2))
        d = np.linalg.norm(xy[:, None, :] - xy[None, :, :], axis=2)
        i, j = np.nonzero(np.triu(np.abs(d - pitch) < 1e-6 * pitch, 1))
        dot += float(np.sum(r[i] * r[j]))
        norm_a += float(np.sum(r[i] ** 2))
        norm_b += float(np.sum(r[j] ** 2))
        n_points += n
        n_views += 1
    if not total > 0:
        return {}
    share = fitted / total
    chance = dof / n_points
    corr = float(dot / np.sqrt(norm_a * norm_b)) if norm_a * norm_b > 0 else float("nan")
    return {"neighbour_correlation": corr, "smooth_share": share, "smooth_share_chance": chance,
            "smooth_excess": (share - chance) / (1.0 - chance),
            "p_value": float((1 + np.sum(null / total >= share)) / (1 + PERMUTATIONS)),
            "views": n_views, "points": n_points, "permutations": PERMUTATIONS}


def reading(s: dict, alpha: float = 0.01) -> str:
    """One line on what the structure says."""
    if not s:
        return "residuals: too few corners per view to tell noise from a smooth field"
    floor = s["p_value"] <= 1.0 / (1 + s["permutations"]) + 1e-12  # no shuffle reached it
    head = (f"residuals: neighbour correlation {s['neighbour_correlation']:.2f}, a quadratic field per view takes "
            f"{100 * s['smooth_share']:.0f} % of their energy ({100 * s['smooth_share_chance']:.0f} % by chance, "
            f"p {'<=' if floor else '='} {s['p_value']:.2g})")
    if s["p_value"] < alpha and s["smooth_excess"] >= SMOOTH_EXCESS:
        return head + (": smooth per view, not noise (a board that is not flat, corners biased along it, or lens terms "
                       "the distortion model leaves out)")
    if s["p_value"] < alpha:
        return head + ": mostly noise, with a small smooth part"
    return head + ": no smooth field found"
