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


#: the image field's polynomial degree in (x, y) (10 terms per axis at 3): a lens term beyond the model
IMAGE_FIELD_DEGREE = 3
#: shuffles for the image field's permutation test (each refits every held-out photo)
IMAGE_FIELD_PERMUTATIONS = 200


def _image_design(xy: np.ndarray, size, degree: int) -> np.ndarray:
    """(n, m) monomials x^i y^j, i + j <= ``degree``, of image positions scaled to [-1, 1] over the image."""
    w, h = size
    x = (np.asarray(xy, float)[:, 0] - 0.5 * (w - 1)) / (0.5 * w)
    y = (np.asarray(xy, float)[:, 1] - 0.5 * (h - 1)) / (0.5 * h)
    return np.stack([x ** i * y ** j for i in range(degree + 1) for j in range(degree + 1 - i)], axis=1)


def _held_out_share(views: list, size, degree: int) -> float:
    """The share of all views' residual energy that a field over the image, fitted to the *other* views' residuals
    at their image positions, predicts (1 − Σ|r − f|² / Σ|r|², pooled; ≤ 0 when it predicts nothing)."""
    design = [_image_design(xy, size, degree) for xy, _ in views]
    miss = total = 0.0
    for k, (_, r) in enumerate(views):
        a = np.vstack([d for i, d in enumerate(design) if i != k])
        b = np.vstack([v for i, (_, v) in enumerate(views) if i != k])
        coef, *_ = np.linalg.lstsq(a, b, rcond=None)
        miss += float(np.sum((r - design[k] @ coef) ** 2))
        total += float(np.sum(r * r))
    return 1.0 - miss / total if total > 0 else float("nan")


def image_field_transfer(image_xy: list, residuals: list, size, degree: int = IMAGE_FIELD_DEGREE,
                         seed: int = 0) -> dict:
    """Is a calibration's residual a field fixed in the image (a lens term the model lacks: the same at the same
    pixel in every photo), or does it move with each view (the board's shape, the print)?  Leave one photo out: a
    degree-``degree`` polynomial field over the image, fitted to the other photos' residuals at their image
    positions, predicts the held-out photo's; ``image_field_share`` is the share of the residual energy so
    predicted, pooled over the photos (noise and per-view fields predict nothing: ≤ 0).  ``p_value``: the share of
    ``IMAGE_FIELD_PERMUTATIONS`` shuffles of each photo's residuals among its own points whose share reaches it.
    ``image_xy``, ``residuals``: per photo (n, 2) px; ``size`` (w, h).  Empty with fewer than 3 photos."""
    views = []
    for xy, r in zip(image_xy, residuals):
        xy, r = np.asarray(xy, float).reshape(-1, 2), np.asarray(r, float).reshape(-1, 2)
        ok = np.all(np.isfinite(xy), axis=1) & np.all(np.isfinite(r), axis=1)
        if ok.sum() >= 4:
            views.append((xy[ok], r[ok]))
    terms = (degree + 1) * (degree + 2) // 2
    if len(views) < 3 or sum(len(v) for _, v in views) < 4 * terms:
        return {}
    share = _held_out_share(views, size, degree)
    rng = np.random.default_rng(seed)
    null = np.array([_held_out_share([(xy, r[rng.permutation(len(r))]) for xy, r in views], size, degree)
                     for _ in range(IMAGE_FIELD_PERMUTATIONS)])
    return {"image_field_share": share, "image_field_degree": degree, "image_field_terms": terms,
            "image_field_p_value": float((1 + np.sum(null >= share)) / (1 + IMAGE_FIELD_PERMUTATIONS)),
            "image_field_null_median": float(np.median(null)), "image_field_views": len(views),
            "image_field_points": int(sum(len(v) for _, v in views))}


#: the step (board units) of the numerical Jacobian of the projection in ``board_point_transfer``
JACOBIAN_STEP = 1e-4


def _board_offsets(board_xy: np.ndarray, residuals: np.ndarray, K, dist, rvec, tvec) -> tuple[np.ndarray, np.ndarray]:
    """(offsets (n, 2) on the board, jacobians (n, 2, 2) px per board unit): the board displacement of each point
    that moves its projection by its residual (the residual through the inverse of d(image)/d(board) at it)."""
    import cv2  # lazy: only the calibration paths call this, and they have cv2 loaded already

    xy = np.asarray(board_xy, float)
    h = JACOBIAN_STEP * max(float(np.ptp(xy)), 1e-9)
    pts = np.concatenate([np.c_[xy + d, np.zeros(len(xy))] for d in ((h, 0), (-h, 0), (0, h), (0, -h))])
    uv, _ = cv2.projectPoints(pts, np.asarray(rvec, float), np.asarray(tvec, float), K, np.asarray(dist, float))
    uv = uv.reshape(4, len(xy), 2)
    jac = np.stack([(uv[0] - uv[1]) / (2 * h), (uv[2] - uv[3]) / (2 * h)], axis=2)  # (n, 2 image, 2 board)
    return np.linalg.solve(jac, np.asarray(residuals, float)[..., None])[..., 0], jac


def _point_share(keys: list, offsets: list, jacobians: list, residuals: list, n_keys: int) -> float:
    """Leave one view out: each point's board offset predicted by the mean of its offsets in the other views where
    it is seen (0 where none), carried to the image by the view's Jacobian; the share of the residual energy so
    predicted.  ``keys``: per view each point's index among the ``n_keys`` board points."""
    total = np.zeros((n_keys, 2))
    count = np.zeros(n_keys)
    for k, o in zip(keys, offsets):
        np.add.at(total, k, o)
        np.add.at(count, k, 1.0)
    miss = energy = 0.0
    for k, o, jac, r in zip(keys, offsets, jacobians, residuals):
        others = count[k] - 1.0
        pred = np.where(others[:, None] > 0, (total[k] - o) / np.maximum(others, 1.0)[:, None], 0.0)
        miss += float(np.sum((r - np.einsum("nij,nj->ni", jac, pred)) ** 2))
        energy += float(np.sum(r * r))
    return 1.0 - miss / energy if energy > 0 else float("nan")


def board_point_transfer(board_xy: list, residuals: list, K, dist, rvecs: list, tvecs: list, seed: int = 0) -> dict:
    """Is a calibration's residual each board point's own (the print: a point printed off its nominal place is off
    it in every photo), or not?  Each residual is carried to the board (``_board_offsets``: the displacement of the
    point that moves its image by it); leave one photo out, the mean of a point's offsets in the other photos
    predicts its residual in the held-out one.  ``print_share``: the share of the residual energy so predicted,
    pooled (≤ 0 for noise, a bend or a lens term that differ between photos); ``print_offset_rms``: the RMS over
    the points seen in 2 or more photos of their mean offset (board units); ``print_p_value``: the share of
    ``IMAGE_FIELD_PERMUTATIONS`` shuffles of each photo's residuals among its points whose share reaches it.  Empty
    with fewer than 3 photos."""
    xy = [np.asarray(b, float).reshape(-1, 2) for b in board_xy]
    res = [np.asarray(r, float).reshape(-1, 2) for r in residuals]
    if len(xy) < 3:
        return {}
    every = np.round(np.concatenate(xy), 9)
    _, inverse = np.unique(every, axis=0, return_inverse=True)
    inverse = np.ravel(inverse)
    bounds = np.cumsum([0] + [len(b) for b in xy])
    keys = [inverse[a:b] for a, b in zip(bounds[:-1], bounds[1:])]
    n_keys = int(inverse.max()) + 1
    jacs, offs = [], []
    for b, r, rv, tv in zip(xy, res, rvecs, tvecs):
        o, j = _board_offsets(b, r, K, dist, rv, tv)
        offs.append(o)
        jacs.append(j)
    share = _point_share(keys, offs, jacs, res, n_keys)
    rng = np.random.default_rng(seed)
    null = []
    for _ in range(IMAGE_FIELD_PERMUTATIONS):
        perm = [rng.permutation(len(r)) for r in res]
        shuffled = [r[p] for r, p in zip(res, perm)]
        null.append(_point_share(keys, [np.linalg.solve(j, r[..., None])[..., 0] for j, r in zip(jacs, shuffled)],
                                 jacs, shuffled, n_keys))
    total = np.zeros((n_keys, 2))
    count = np.zeros(n_keys)
    for k, o in zip(keys, offs):
        np.add.at(total, k, o)
        np.add.at(count, k, 1.0)
    seen = count >= 2
    mean_off = total[seen] / count[seen][:, None]
    return {"print_share": share, "print_p_value": float((1 + np.sum(np.asarray(null) >= share))
                                                          / (1 + IMAGE_FIELD_PERMUTATIONS)),
            "print_null_median": float(np.median(null)),
            "print_offset_rms": float(np.sqrt(np.mean(np.sum(mean_off ** 2, axis=1)))) if seen.any() else
            float("nan"), "print_points": int(seen.sum())}


def reading(s: dict, alpha: float = 0.01) -> str:
    """One line on what the structure says."""
    if not s:
        return "residuals: too few corners per view to tell noise from a smooth field"
    floor = s["p_value"] <= 1.0 / (1 + s["permutations"]) + 1e-12  # no shuffle reached it
    head = (f"residuals: neighbour correlation {s['neighbour_correlation']:.2f}, a quadratic field per view takes "
            f"{100 * s['smooth_share']:.0f} % of their energy ({100 * s['smooth_share_chance']:.0f} % by chance, "
            f"p {'<=' if floor else '='} {s['p_value']:.2g})")
    if s["p_value"] < alpha and s["smooth_excess"] >= SMOOTH_EXCESS:
        head += (": smooth per view, not noise (a board that is not flat, corners biased along it, or lens terms "
                 "the distortion model leaves out)")
    elif s["p_value"] < alpha:
        head += ": mostly noise, with a small smooth part"
    else:
        head += ": no smooth field found"
    return head + where_reading(s, alpha)


def where_reading(s: dict, alpha: float = 0.01) -> str:
    """``reading``'s tail: where the residual lives (``image_field_transfer``, ``board_point_transfer``), each photo
    held out; empty when they were not measured."""
    parts = []
    for key, words in (("print", "each board point's own offset (the print)"),
                       ("image_field", "a field fixed in the image (a lens term)")):
        if f"{key}_share" not in s:
            continue
        share, p = s[f"{key}_share"], s[f"{key}_p_value"]
        parts.append(f"{words} {100 * max(share, 0.0):.0f} %" + ("" if p < alpha and share > 0 else
                                                                   " (not significant)"))
    return ("; of a held-out photo's residual energy the other photos predict by " + ", by ".join(parts)
            if parts else "")
