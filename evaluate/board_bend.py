"""Does the board bend?  Zhang's calibration refitted with a bend per view, against the flat board.

Zhang's method assumes a flat board.  A printed sheet that curls leaves each view a residual that no pose or
lens term absorbs (``residual_field`` sees it as a smooth field per view).  This check names the cause: it
refits the calibration (K, the distortion terms the flat fit estimated, and every pose) with the board's
height in each view a polynomial of its board coordinates, z = s · Σ c_k m_k(x̂, ŷ), where x̂ = (x − x̄)/s,
ŷ = (y − ȳ)/s over the view's corners (s their largest distance from the centre along an axis), and the
monomials m_k are of degree 2 (x̂², x̂ŷ, ŷ²: a sheet curled into a cylinder, a dome or a saddle) or 2 and 3
(``ORDERS``).  Constant and linear heights are a pose, so they are left out.  Started from the flat solution,
Levenberg-Marquardt (``block_lm``: per-view blocks, linear in the views) refits both models with one projection
(OpenCV's pinhole and 5-term Brown-Conrady model, ``render.optics.distortion``), so they differ in the bend
alone.

Reported per model: both RMS (px, over 2-D residuals as OpenCV's), the share of the flat residual energy the
bend takes, the F test of the nested models (the bend's q = terms × views extra parameters), its effect size
``bend_excess`` = (share − chance) / (1 − chance), where chance = q / (the flat fit's residual degrees of
freedom) is the share noise alone gives, each view's depth (the fitted height's peak-to-valley over its
corners, mm), its coefficients c_k · s (mm: each monomial's height at x̂ or ŷ = ±1) with standard errors
(residual variance × (JᵀJ)⁻¹), and the bent calibration's intrinsics.  The F test and the errors assume
independent residuals of one variance.  On analytic views both are calibrated (tests); on the rendered OpenCV
twin (a flat board, line corners) the F test gives F = 0.72 and 0.91 (p = 0.90 and 0.72).  Where the bend
leaves structure behind (the photos' cubic share exceeds the quadratic one), the errors are too small.

A bend per view can also stand in for lens terms the calibration leaves out: the same twin calibrated with
k1, k2 only (it is rendered through the photos' lens, p1 = 0.001) reads as bent (32 %, F = 15.6), and reads
flat again with k1, k2, p1, p2 (3 %, p = 0.54).  The check is about the board only under a lens model that
fits; ``reading`` says so when the model is not the full one.

A third model shares one quadratic shape among all views (``common``: a rigid board that is warped, 3 terms in all,
normalised over the board's distinct corners): fewer parameters, so a warp that is the same in every view is found
with errors of a few micrometres where the per-view fit's are tens.

Measured (docs/board.md): OpenCV's photos (54 line corners, 5-term model): a quadratic bend takes 30 % of the
residual energy (RMS 0.155 → 0.130 px, F = 13.9, p ≈ 10⁻⁷²), 0.3-1.0 mm deep, the sheet curled the same way in
all 13 photos (ŷ² coefficient +0.24 to +0.76 mm, 1.6-6.7 standard errors); the cubic one 45 % (0.115 px).  Their
flat twin: 1 % and 5 % (chance), ≤ 0.04 mm.  Zhang's own corners: 2 % against 1 %, mostly noise.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation
from scipy.stats import f as f_dist

from edgetruth.evaluate import block_lm
from edgetruth.render.optics.distortion import distort_normalized
from edgetruth.render.scene.bend import height_terms


#: bend models: name -> the degrees of the monomials in the board's height
ORDERS = {"quadratic": (2,), "cubic": (2, 3)}
#: the common bend: one quadratic shape shared by every view (a rigid board that is warped), 3 terms in all
COMMON = (2,)
#: the share of what chance leaves (``bend_excess``) from which a significant bend is called one
BEND_EXCESS = 0.1
#: fewest corners a view needs to take part: its 2 n residuals against 6 pose and 7 cubic terms, twice over
MIN_CORNERS = 13
_POSE = 6


def _n_terms(degrees) -> int:
    return sum(d + 1 for d in degrees)


def monomials(board_xy: np.ndarray, degrees=(2,)) -> tuple[np.ndarray, float]:
    """(n, k) the height terms x̂^i ŷ^j (i + j in ``degrees``, x̂ first) of a view's board coordinates (n, 2),
    and the scale s (board units) that makes them dimensionless: z = s · terms @ c."""
    p = np.asarray(board_xy, float)
    c = p.mean(0)
    s = float(max(np.abs(p - c).max(), 1e-12))
    return height_terms((p - c) / s, degrees), s  # the renderer's terms: a rendered curl reads back as given


def project(points: np.ndarray, view: np.ndarray, poses: np.ndarray, K4, dist5) -> np.ndarray:
    """(n, 2) pixel positions of board points (n, 3) seen in views ``view`` (n,) with ``poses`` (V, 6: rvec,
    tvec), K4 = (fx, fy, cx, cy) and OpenCV's dist5 = (k1, k2, p1, p2, k3) (``cv2.projectPoints``)."""
    R = Rotation.from_rotvec(poses[:, :3]).as_matrix()[view]
    X = np.einsum("nij,nj->ni", R, points) + poses[view, 3:6]
    xd, yd = distort_normalized(X[:, 0] / X[:, 2], X[:, 1] / X[:, 2], dist5)
    fx, fy, cx, cy = K4
    return np.stack([fx * xd + cx, fy * yd + cy], axis=1)


def bend_check(board_xy: list[np.ndarray], image_xy: list[np.ndarray], K: np.ndarray, dist: np.ndarray,
               rvecs: list, tvecs: list, free_dist=(True,) * 5, unit_m: float = 1.0,
               solver=block_lm.solve) -> dict:
    """The flat calibration's per-view board coordinates (n, 2; board units, ``unit_m`` metres each), measured
    corners (n, 2; px), K, dist (5), poses and which of (k1, k2, p1, p2, k3) it estimated (the others stay at
    ``dist``) -> {model name: the module docstring's numbers} (``{}`` with too few corners to fit).  Only views
    with ``MIN_CORNERS`` corners take part (both fits, so they stay nested; ``views`` and ``points`` say how many):
    a view of a few corners would fit its own bend exactly.  ``solver``: ``block_lm.solve``, or its dense
    reference ``block_lm.solve_dense``."""
    xy = [np.asarray(b, float).reshape(-1, 2) for b in board_xy]
    use = [v for v, b in enumerate(xy) if len(b) >= MIN_CORNERS]
    if not use:
        return {}
    xy = [xy[v] for v in use]
    img = np.concatenate([np.asarray(image_xy[v], float).reshape(-1, 2) for v in use])
    rvecs, tvecs = [np.ravel(rvecs[v]) for v in use], [np.ravel(tvecs[v]) for v in use]
    n_views = len(xy)
    view = np.concatenate([np.full(len(b), v) for v, b in enumerate(xy)])
    if 2 * len(view) <= 9 + (_POSE + max(_n_terms(d) for d in ORDERS.values())) * n_views:
        return {}
    K = np.asarray(K, float)
    base = np.r_[K[0, 0], K[1, 1], K[0, 2], K[1, 2], np.pad(np.ravel(dist), (0, 5))[:5]]
    poses = np.concatenate([np.ravel(rvecs).reshape(n_views, 3), np.ravel(tvecs).reshape(n_views, 3)], axis=1)
    lens_free = np.r_[np.ones(4, bool), np.asarray(free_dist, bool)]
    out = {name: _fit_order(degrees, xy, view, img, base, poses, lens_free, unit_m, solver)
           for name, degrees in ORDERS.items()}
    out["common"] = _fit_common(COMMON, xy, view, img, base, poses, lens_free, unit_m, solver)
    return out


def _nested_stats(r0, r1, n_flat: int, q: int, n_points: int) -> dict:
    """The F test of a flat fit (residual r0, ``n_flat`` free parameters) against one with ``q`` bend terms more."""
    rss0, rss1 = float(r0 @ r0), float(r1 @ r1)
    dof0, dof1 = 2 * n_points - n_flat, 2 * n_points - n_flat - q
    share, chance = 1.0 - rss1 / rss0, q / dof0
    F = ((rss0 - rss1) / q) / (rss1 / dof1) if rss1 > 0 else float("inf")
    return {"rms_flat_px": float(np.sqrt(2 * rss0 / len(r0))), "rms_bent_px": float(np.sqrt(2 * rss1 / len(r1))),
            "bend_share": share, "bend_share_chance": chance, "bend_excess": (share - chance) / (1.0 - chance),
            "f_statistic": float(F), "p_value": float(f_dist.sf(F, q, dof1)), "extra_parameters": q,
            "residual_dof": dof1}


def _view_rms(r, view, n_views) -> list[float]:
    sq = np.sum(r.reshape(-1, 2) ** 2, axis=1)
    return np.sqrt(np.bincount(view, sq, n_views) / np.bincount(view, minlength=n_views)).tolist()


def _intrinsics(lens) -> dict:
    return {"fx_px": float(lens[0]), "fy_px": float(lens[1]), "cx_px": float(lens[2]), "cy_px": float(lens[3]),
            "dist_coeffs_opencv": np.asarray(lens[4:9], float).tolist()}


def _fit_common(degrees, xy, view, img, base, poses, lens_free, unit_m, solver) -> dict:
    """The flat fit against one bend shared by every view: its terms normalised over the board's distinct corners
    (their centre and largest extent along an axis, so a coefficient is the height there), fitted with the lens."""
    n_views, n_points, n_lens = len(xy), len(view), len(base)
    board = np.concatenate(xy)
    corners = np.unique(board, axis=0)
    centre = corners.mean(0)
    s = float(max(np.abs(corners - centre).max(), 1e-12))
    terms = height_terms((board - centre) / s, degrees) * s
    k = terms.shape[1]
    points = np.c_[board, np.zeros(n_points)]

    def residual(shared, per_view):
        pts = points.copy()
        pts[:, 2] = terms @ shared[n_lens:]
        return (project(pts, view, per_view, shared[:4], shared[4:9]) - img).ravel()

    rows, pose_free = np.repeat(view, 2), np.ones(_POSE, bool)
    flat = solver(residual, np.r_[base, np.zeros(k)], poses, rows, np.r_[lens_free, np.zeros(k, bool)], pose_free)
    bent = solver(residual, flat.shared, flat.blocks, rows, np.r_[lens_free, np.ones(k, bool)], pose_free)
    stats = _nested_stats(flat.residual, bent.residual, int(lens_free.sum()) + _POSE * n_views, k, n_points)
    coef = bent.shared[n_lens:]
    var = float(bent.residual @ bent.residual) / stats["residual_dof"] * bent.shared_var[n_lens:]
    to_mm = s * unit_m * 1e3
    return {"terms": k, "views": n_views, "points": n_points, **stats,
            "per_view_rms_bent_px": _view_rms(bent.residual, view, n_views),
            "depth_mm": float(np.ptp(height_terms((corners - centre) / s, degrees) @ coef) * to_mm),
            "scale_mm": to_mm, "coefficients_mm": (coef * to_mm).tolist(),
            "coefficients_se_mm": (np.sqrt(var) * to_mm).tolist(), "intrinsics_bent": _intrinsics(bent.shared)}


def _fit_order(degrees, xy, view, img, base, poses, lens_free, unit_m, solver) -> dict:
    """The flat and the bent fit of one bend model (``ORDERS``), and what ``bend_check`` reports of them."""
    n_views, n_points = len(xy), len(view)
    design = [monomials(b, degrees) for b in xy]
    terms = np.concatenate([m * s for m, s in design])  # z = terms @ c per corner, board units
    k = terms.shape[1]
    points = np.c_[np.concatenate(xy), np.zeros(n_points)]

    def residual(lens, per_view):
        pts = points.copy()
        pts[:, 2] = np.einsum("nk,nk->n", terms, per_view[view, _POSE:])
        return (project(pts, view, per_view[:, :_POSE], lens[:4], lens[4:9]) - img).ravel()

    rows = np.repeat(view, 2)  # a residual row per axis of each corner
    # the flat board refitted with this projection, then the bend freed from it
    flat = solver(residual, base, np.c_[poses, np.zeros((n_views, k))], rows, lens_free,
                  np.r_[np.ones(_POSE, bool), np.zeros(k, bool)])
    bent = solver(residual, flat.shared, flat.blocks, rows, lens_free, np.ones(_POSE + k, bool))
    r1 = bent.residual
    stats = _nested_stats(flat.residual, r1, int(lens_free.sum()) + _POSE * n_views, k * n_views, n_points)
    coef = bent.blocks[:, _POSE:]
    depth = [float(np.ptp(m @ c) * s * unit_m * 1e3) for (m, s), c in zip(design, coef)]
    # the residual variance times the diagonal of (J^T J)^-1
    var = float(r1 @ r1) / stats["residual_dof"] * bent.block_var[:, _POSE:]
    to_mm = np.array([s for _, s in design])[:, None] * unit_m * 1e3
    return {"terms_per_view": k, "views": n_views, "points": n_points, **stats,
            "per_view_rms_bent_px": _view_rms(r1, view, n_views),
            "depth_mm": depth, "depth_mm_median": float(np.median(depth)), "scale_mm": to_mm[:, 0].tolist(),
            "coefficients_mm": (coef * to_mm).tolist(), "coefficients_se_mm": (np.sqrt(var) * to_mm).tolist(),
            "intrinsics_bent": _intrinsics(bent.shared)}


def reading(b: dict, alpha: float = 0.01, full_lens: bool = True) -> str:
    """One line on what the bend check says; ``full_lens`` False: the calibration left lens terms out, and a bend
    per view can stand in for them (module docstring), which the line then says."""
    if not b:
        return "board bend: too few corners to fit a bend per view"
    q, c = b["quadratic"], b.get("cubic")
    head = (f"board bend: a quadratic bend per view ({q['depth_mm_median']:.2f} mm deep, median) takes "
            f"{100 * q['bend_share']:.0f} % of the residual energy ({100 * q['bend_share_chance']:.0f} % by chance; "
            f"RMS {q['rms_flat_px']:.3f} -> {q['rms_bent_px']:.3f} px, F = {q['f_statistic']:.1f}, "
            f"p = {q['p_value']:.2g})")
    if c:
        head += f", a cubic one {100 * c['bend_share']:.0f} % ({c['rms_bent_px']:.3f} px)"
    common = b.get("common")
    if common:
        head += (f", one quadratic common to every view {100 * common['bend_share']:.0f} % "
                 f"({common['depth_mm']:.2f} mm deep)")
    best = max((m for m in (q, c, common) if m), key=lambda m: m["bend_excess"])
    if best["p_value"] < alpha and best["bend_excess"] >= BEND_EXCESS:
        if not full_lens:
            return head + (": the board bends, or the lens has terms this distortion model leaves out "
                           "(check with the default 5-term model)")
        return head + ": the board bends"
    if best["p_value"] < alpha:
        return head + ": a slight bend, mostly noise"
    return head + ": no bend found"
