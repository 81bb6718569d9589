"""Which detected quad is which square of the model: a homography grown from one square.

Hypotheses: the seed quad (a detected quad near the middle of all of them) is model square
``m``, with its corners in one of the 4 cyclic rolls, in the model's corner direction or
mirrored -- 8 per model square.  All of them are first scored at once (batched least-squares
homographies): the seed square's homography, refitted on the squares next to ``m`` that it
matches, then the matches it gives over the whole model; only the best-scoring hypotheses
are grown.  Growing: the homography maps the model's
squares into the image, squares within a growing radius of the seed (in steps of the
model's nearest-neighbour spacing) that land within ``MATCH_FRACTION`` of their size of a
detected quad's centre are matched (mutual nearest), and the homography is refitted on
every matched corner; it stops when the radius covers the model and the matches no longer
change.  The best hypothesis matches the most squares.

**Rule for symmetric boards.**  A board such as Zhang's (8 x 8 equal squares) matches
equally well under its symmetries (rotations by 90 degrees, and mirrors).  Among the
hypotheses that match the most squares with (to 5 % + 0.05 px) the smallest corner
residual, the study keeps one that does not mirror the model (the model's corner order maps
to clockwise on screen, as Zhang's does: model +x to the right, +y down the image) and whose
model +x axis, at the board's centre, points closest to the image's +x axis: the model's axes
are read like the image's (+x right, +y down) up to a rotation of less than 45 degrees.  Zhang's
model then numbers the squares as his ``dataN.txt`` do: square 0 (largest y) at the bottom left of
each photo, rows of 8 from left to right, going up.  The calibration does not depend on the rule: a symmetry
maps the model's corners onto themselves, i.e. it only changes the board's pose.

The result is refined with all squares: a least-squares homography on every matched corner; a
quad with a corner more than ``OUTLIER_FRACTION`` of its size from it is not the whole square
(cut by the image's border, merged with a smudge) and is dropped, and the homography refitted.

**The board's outer squares must be in view** on every side: a grid of equal squares seen only
in part looks the same shifted by a square, and no rule can tell which squares are seen.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from edgetruth.evaluate.board.model import BoardModel

#: A projected model square matches a quad when their centres are closer than this share of its size.
MATCH_FRACTION = 0.35
#: A matched quad with a corner farther than this share of its size from the final homography is dropped.
OUTLIER_FRACTION = 0.2
#: Seeds tried (quads nearest the middle) before giving up on a better hypothesis.
MAX_SEEDS = 3


@dataclass
class Correspondence:
    """corners: (S, 4, 2) the detected quad of each model square, its corners in the model's order
    (NaN where the square was not found); found: (S,) bool; homography: 3x3, model -> image;
    residual_px: RMS of the matched quad corners about the homography; mirrored: the rule's choice."""

    corners: np.ndarray
    found: np.ndarray
    homography: np.ndarray
    residual_px: float
    mirrored: bool
    rotation_deg: float

    @property
    def missing(self) -> list[int]:
        return [int(i) for i in np.flatnonzero(~self.found)]


def project(h: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Apply homography ``h`` to (..., 2) points."""
    p = np.asarray(pts, np.float64)
    q = p @ h[:, :2].T + h[:, 2]
    return q[..., :2] / q[..., 2:3]


def homographies(src: np.ndarray, dst: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Batched least-squares homographies (normalised DLT): (K, n, 2) ``src`` -> ``dst``, points where ``w``
    (K, n) is True; (K, 3, 3), NaN where fewer than 4 points."""
    w = np.asarray(w, bool)
    cnt = w.sum(axis=1)
    wf = w[..., None].astype(float)

    def norm(p):
        c = (p * wf).sum(1) / np.maximum(cnt, 1)[:, None]
        r = (np.linalg.norm(p - c[:, None], axis=2) * w).sum(1) / np.maximum(cnt, 1)
        s = np.sqrt(2.0) / np.where(r > 0, r, 1.0)
        t = np.zeros((len(p), 3, 3))
        t[:, 0, 0] = t[:, 1, 1] = s
        t[:, 0, 2], t[:, 1, 2], t[:, 2, 2] = -s * c[:, 0], -s * c[:, 1], 1.0
        return (p - c[:, None]) * s[:, None, None], t

    (ps, ts), (pd, td) = norm(np.asarray(src, float)), norm(np.asarray(dst, float))
    x, y, u, v = ps[..., 0], ps[..., 1], pd[..., 0], pd[..., 1]
    z, o = np.zeros_like(x), np.ones_like(x)
    r1 = np.stack([-x, -y, -o, z, z, z, u * x, u * y, u], axis=2)
    r2 = np.stack([z, z, z, -x, -y, -o, v * x, v * y, v], axis=2)
    a = np.concatenate([r1, r2], axis=1) * np.concatenate([wf, wf], axis=1)
    if a.shape[1] < 9:  # 4 points: pad with zero rows so that the null vector is among the 9 returned
        a = np.concatenate([a, np.zeros((len(a), 9 - a.shape[1], 9))], axis=1)
    hn = np.linalg.svd(a, full_matrices=False)[2][:, -1].reshape(-1, 3, 3)
    h = np.linalg.inv(td) @ hn @ ts
    with np.errstate(invalid="ignore", divide="ignore"):
        h = h / h[:, 2:3, 2:3]
    h[cnt < 4] = np.nan
    return h


def _fit(model_pts: np.ndarray, image_pts: np.ndarray) -> np.ndarray | None:
    h, _ = cv2.findHomography(model_pts.reshape(-1, 1, 2), image_pts.reshape(-1, 1, 2), 0)
    return h if h is not None and np.all(np.isfinite(h)) else None


def _best_roll(quads: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Each quad's corners rolled (cyclically) to lie closest to the corresponding target corners."""
    rolls = np.stack([np.roll(quads, -r, axis=1) for r in range(4)])  # (4, N, 4, 2)
    cost = np.linalg.norm(rolls - target[None], axis=3).sum(axis=2)  # (4, N)
    k = np.argmin(cost, axis=0)
    return rolls[k, np.arange(len(k))]


def _grow(model: BoardModel, mc: np.ndarray, quads: np.ndarray, seed_quad: np.ndarray, m: int,
          spacing: float, max_iter: int = 60):
    """Grow one hypothesis: model square m <-> seed quad (corners ``mc``, the model's corners as ordered
    by the hypothesis).  Returns (homography, matched quad index per model square or -1, residual_px)."""
    h = cv2.getPerspectiveTransform(mc.astype(np.float32), seed_quad.astype(np.float32)).astype(np.float64)
    centres_m = model.centres
    q_centres = quads.mean(axis=1)
    dist_m = np.linalg.norm(centres_m - centres_m[m], axis=1)
    corners_m = model.corners
    match = np.full(len(model), -1)
    radius = 1.5 * spacing
    for _ in range(max_iter):
        pc = project(h, corners_m)  # (S, 4, 2)
        if not np.all(np.isfinite(pc)):
            return None, match, np.inf
        size = _size(pc)
        d = np.linalg.norm(pc.mean(axis=1)[:, None] - q_centres[None], axis=2)  # (S, Q)
        j = np.argmin(d, axis=1)
        mutual = np.argmin(d, axis=0)[j] == np.arange(len(model))
        ok = (d[np.arange(len(model)), j] < MATCH_FRACTION * size) & mutual & (dist_m <= radius)
        new = np.where(ok, j, -1)
        if ok.sum() < 1:
            return None, new, np.inf
        rolled = _best_roll(quads[j[ok]], pc[ok])
        src, dst = corners_m[ok].reshape(-1, 2), rolled.reshape(-1, 2)
        h_new = _fit(src, dst) if ok.sum() >= 2 else h
        if h_new is None:
            return None, new, np.inf
        done = np.array_equal(new, match) and radius >= dist_m.max()
        match, h = new, h_new
        if done:
            break
        radius += spacing
    ok = match >= 0
    pc = project(h, corners_m[ok])
    rolled = _best_roll(quads[match[ok]], pc)
    res = float(np.sqrt(np.mean(np.sum((rolled - pc) ** 2, axis=2))))
    return h, match, res


def _size(pc: np.ndarray) -> np.ndarray:
    """Square root of the area of (..., 4, 2) quads."""
    return np.sqrt(np.abs(0.5 * (pc[..., 0] * np.roll(pc[..., 1], -1, -1)
                                 - np.roll(pc[..., 0], -1, -1) * pc[..., 1]).sum(-1)))


def _matches(h: np.ndarray, model: BoardModel, quads: np.ndarray, squares: np.ndarray, allowed: np.ndarray):
    """For K homographies (K, 3, 3) and, per homography, model squares ``squares`` (K, m) of which ``allowed``
    (K, m): (matched (K, m) bool, quad index (K, m), projected corners (K, m, 4, 2)).  A square matches the quad
    nearest its projected centre when closer than ``MATCH_FRACTION`` of its projected size and the two are
    each other's nearest among the allowed squares."""
    corners = model.corners[squares]  # (K, m, 4, 2)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        q = np.einsum("kij,kmcj->kmci", h[:, :, :2], corners) + h[:, None, None, :, 2]
        pc = q[..., :2] / q[..., 2:3]
        centre = pc.mean(axis=2)
        qc = quads.mean(axis=1)
        d2 = (centre[..., 0:1] - qc[:, 0]) ** 2 + (centre[..., 1:2] - qc[:, 1]) ** 2  # (K, m, Q)
    d2 = np.where(np.isfinite(d2) & allowed[..., None], d2, np.inf)
    j = np.argmin(d2, axis=2)
    s_idx = np.arange(j.shape[1])[None]
    mutual = np.take_along_axis(np.argmin(d2, axis=1), j, axis=1) == s_idx
    dj = np.take_along_axis(d2, j[..., None], axis=2)[..., 0]
    with np.errstate(invalid="ignore"):
        ok = (dj < (MATCH_FRACTION * _size(pc)) ** 2) & mutual & allowed
    return ok, j, pc


def _refit(model: BoardModel, h: np.ndarray, quads: np.ndarray, squares: np.ndarray, ok: np.ndarray,
           j: np.ndarray, pc: np.ndarray) -> np.ndarray:
    """Each homography refitted on its matched squares' corners (quads rolled to the projections)."""
    q = quads[j]  # (K, m, 4, 2)
    rolls = np.stack([np.roll(q, -r, axis=2) for r in range(4)])  # (4, K, m, 4, 2)
    cost = np.sqrt(((rolls - pc[None]) ** 2).sum(axis=4)).sum(axis=3)
    best = np.argmin(np.nan_to_num(cost, nan=np.inf), axis=0)
    q = np.take_along_axis(rolls, best[None, ..., None, None], axis=0)[0]
    k = len(h)
    h2 = homographies(model.corners[squares].reshape(k, -1, 2), q.reshape(k, -1, 2), np.repeat(ok, 4, axis=1))
    return np.where(np.isfinite(h2).all(axis=(1, 2))[:, None, None], h2, h)


def _look(model: BoardModel, h0: np.ndarray, quads: np.ndarray, m_idx: np.ndarray, spacing: float) -> np.ndarray:
    """How promising each start is (K,): the homography of the seed square alone, refitted on the model
    squares within 1.5 spacings of the start's square that it matches; then, for the starts that match the
    most of those, the count of matches over the whole model (others: -1)."""
    c = model.centres
    dist = np.linalg.norm(c[m_idx][:, None] - c[None], axis=2)  # (K, S)
    width = int((dist <= 1.5 * spacing).sum(axis=1).max())
    squares = np.argsort(dist, axis=1, kind="stable")[:, :width]
    allowed = np.take_along_axis(dist, squares, axis=1) <= 1.5 * spacing
    ok, j, pc = _matches(h0, model, quads, squares, allowed)
    n_near = ok.sum(axis=1)
    top = np.flatnonzero(n_near == n_near.max())
    h1 = _refit(model, h0[top], quads, squares[top], ok[top], j[top], pc[top])
    every = np.broadcast_to(np.arange(len(model)), (len(top), len(model)))
    ok2, _, _ = _matches(h1, model, quads, every, np.ones(every.shape, bool))
    score = np.full(len(h0), -1)
    score[top] = ok2.sum(axis=1)
    return score


def rotation_deg(h: np.ndarray, model: BoardModel) -> float:
    """Angle (deg) of the image direction of model +x at the board's centre, from image +x."""
    c = model.centres.mean(axis=0)
    scale = float(np.ptp(model.corners[..., 0])) or 1.0
    a, b = project(h, np.array([c, c + [1e-3 * scale, 0.0]]))
    v = b - a
    return float(np.degrees(np.arctan2(v[1], v[0])))


def match_squares(model: BoardModel, quads: np.ndarray) -> Correspondence | None:
    """The model's squares among the detected ``quads`` (clockwise on screen); None when fewer than 4 match."""
    quads = np.asarray(quads, np.float64)
    if len(quads) < 4:
        return None
    c = model.centres
    dm = np.linalg.norm(c[:, None] - c[None], axis=2)
    np.fill_diagonal(dm, np.inf)
    spacing = float(np.median(dm.min(axis=1)))
    # the model's corner direction as seen on screen when not mirrored: Zhang's (+x right, +y down) is clockwise
    model_cw = np.sign(np.sum(model.corners[0, :, 0] * np.roll(model.corners[0, :, 1], -1)
                              - np.roll(model.corners[0, :, 0], -1) * model.corners[0, :, 1])) > 0
    qc = quads.mean(axis=1)
    order = np.argsort(np.linalg.norm(qc - np.median(qc, axis=0), axis=1))
    hyps = []
    for seed in order[:MAX_SEEDS]:
        # every (model square, mirror, roll); a first look at the seed's neighbours keeps the promising ones
        starts = []
        for m in range(len(model)):
            for mirrored in (False, True):
                base = model.corners[m] if model_cw != mirrored else model.corners[m][::-1]
                for r in range(4):
                    starts.append((m, mirrored, np.roll(base, -r, axis=0)))
        m_idx = np.array([m for m, _, _ in starts])
        seed_q = np.broadcast_to(quads[seed], (len(starts), 4, 2))
        h0 = homographies(np.array([mc for _, _, mc in starts]), seed_q, np.ones((len(starts), 4), bool))
        score = _look(model, h0, quads, m_idx, spacing)  # the seed's neighbours, then the whole model
        keep = np.flatnonzero(score == score.max()) if score.max() > 0 else np.arange(len(starts))
        for k in keep:
            m, mirrored, mc = starts[k]
            h, match, res = _grow(model, mc, quads, quads[seed], m, spacing)
            if h is not None:
                hyps.append(((match >= 0).sum(), res, mirrored, h, match))
        if hyps and max(x[0] for x in hyps) >= 0.5 * len(model):
            break
    if not hyps:
        return None
    best = max(x[0] for x in hyps)
    if best < 4:
        return None
    tied = [x for x in hyps if x[0] == best]
    floor = min(x[1] for x in tied)
    tied = [x for x in tied if x[1] <= 1.05 * floor + 0.05]
    pick = min(tied, key=lambda x: (x[2], abs(rotation_deg(x[3], model))))
    _, _, mirrored, h, match = pick
    # refine with all squares; a quad whose corners stray from the homography by more than
    # OUTLIER_FRACTION of its size is not the whole square (cut by the border, merged with a smudge): drop it
    found = match >= 0
    for _ in range(3):
        pc = project(h, model.corners[found])
        rolled = _best_roll(quads[match[found]], pc)
        h = _fit(model.corners[found].reshape(-1, 2), rolled.reshape(-1, 2))
        pc = project(h, model.corners[found])
        rolled = _best_roll(quads[match[found]], pc)
        stray = np.linalg.norm(rolled - pc, axis=2).max(axis=1) > OUTLIER_FRACTION * _size(pc)
        if not stray.any() or found.sum() - stray.sum() < 4:
            break
        found[np.flatnonzero(found)[stray]] = False
    corners = np.full(model.corners.shape, np.nan)
    corners[found] = rolled
    res = float(np.sqrt(np.mean(np.sum((rolled - pc) ** 2, axis=2))))
    return Correspondence(corners, found, h, res, bool(mirrored), rotation_deg(h, model))
