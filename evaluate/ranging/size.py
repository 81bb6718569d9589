"""Target image size from refined edge points: robust side lines (squares), robust circle fit (circles).

Square (seed §4.4.2): the edge points are split into the four sides by their
outward normal (the dominant 4-fold orientation gives the split, so a rolled
square works too); each side gets a robust line fit - RANSAC on point pairs for
the inlier set, then iteratively re-weighted total least squares with Tukey's
biweight (scale from the MAD, so gross outliers get zero weight); points within
``corner_trim_px`` of a corner (where the profile crosses two sides) are dropped
and the lines refitted.  The image size is the distance between opposite side
lines: ``width_px`` (left/right, the seed's l, used with fx) is the mean of the
distances from the two corners of one side to the opposite line (both ways),
i.e. the width at mid-height; ``height_px`` (top/bottom, used with fy) likewise.

Circle: algebraic Taubin fit (Chernov's formulation) as the start, then a
geometric fit (Levenberg–Marquardt on orthogonal distances, ``scipy``'s
``least_squares`` with a soft-L1 loss), points beyond 3 robust sigmas removed,
refitted; the size is the diameter 2r.  Points are first scaled by
``aspect = fx / fy`` in y, so the diameter is in fx pixels.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from edgetruth.errors import InputError
from edgetruth.evaluate.ranging import line_kernels as lk


MIN_SIDE_POINTS = 5
MIN_CIRCLE_POINTS = 8
SIGMA_FLOOR_PX = 0.01


# --- lines ------------------------------------------------------------------------
@dataclass
class Line:
    """The line n·p = d (unit normal n), fitted to points; ``inliers`` marks the points used."""

    n: np.ndarray
    d: float
    inliers: np.ndarray
    rms_px: float

    def distance(self, x, y) -> np.ndarray:
        """Signed distance of points to the line."""
        return self.n[0] * np.asarray(x) + self.n[1] * np.asarray(y) - self.d


#: IRLS stops when the line moves less than this (px); far below the edge errors it measures (>= 1e-3 px)
IRLS_TOL_PX = 1e-7


def _median(v: np.ndarray) -> float:
    """``np.median`` of a 1-D array, bit for bit, without its generic machinery (the robust line fits
    call it ~60,000 times per quick run)."""
    n = v.size
    if n == 0:
        return float("nan")
    k = n // 2
    if n % 2:
        return float(np.partition(v, k)[k])
    p = np.partition(v, (k - 1, k))
    return float(np.mean(p[k - 1:k + 1]))


def _mad_sigma(r) -> float:
    return max(1.4826 * _median(np.abs(r - _median(r))), SIGMA_FLOOR_PX)


def fit_line_robust(x, y, ransac_threshold_px: float = 1.0, iterations: int = 200, seed: int = 0,
                    tukey_c: float = 4.685) -> Line:
    """Robust line through (x, y): RANSAC inliers, then Tukey-biweight IRLS total least squares (scale
    1.4826 MAD, at least ``SIGMA_FLOOR_PX``; to ``IRLS_TOL_PX``, at most 30 steps).  Past the random draws
    it is one numba kernel (``edgetruth.evaluate.ranging.line_kernels.robust_line``), bit for bit the numpy
    code it replaced."""
    x = np.ascontiguousarray(x, np.float64)
    y = np.ascontiguousarray(y, np.float64)
    n_pts = x.size
    if n_pts < 2:
        raise InputError(f"line fit: need at least 2 points, got {n_pts}")
    w = np.empty(n_pts)
    nx, ny, d, rms = lk.robust_line(x, y, ransac_pairs(seed, n_pts, iterations), float(ransac_threshold_px),
                                    float(tukey_c), SIGMA_FLOOR_PX, IRLS_TOL_PX, 30, w)
    return Line(np.array([nx, ny]), float(d), w > 0, float(rms))


@functools.lru_cache(maxsize=4096)
def ransac_pairs(seed: int, n_pts: int, iterations: int) -> np.ndarray:
    """RANSAC's point pairs (m, 2) for ``n_pts`` points: ``iterations`` draws of ``Generator(PCG64(seed))``
    without the pairs of one point twice; none for 3 points or fewer (no RANSAC).  They depend on nothing
    else, so they are drawn once per (seed, n_pts) and kept read-only: the quick run fits ~40,000 lines."""
    if n_pts <= 3:
        i = np.zeros((0, 2), np.int64)
    else:
        i = np.random.Generator(np.random.PCG64(seed)).integers(0, n_pts, size=(iterations, 2))
        i = np.ascontiguousarray(i[i[:, 0] != i[:, 1]], np.int64)
    i.flags.writeable = False
    return i


def intersect(a: Line, b: Line) -> np.ndarray:
    m = np.array([a.n, b.n])
    return np.linalg.solve(m, np.array([a.d, b.d]))


def _line_gap(side_a: Line, corners_a: np.ndarray, side_b: Line, corners_b: np.ndarray) -> float:
    """Mean distance between two opposite sides: corners of each to the other's line."""
    return float(np.mean(np.abs(np.concatenate([side_b.distance(corners_a[:, 0], corners_a[:, 1]),
                                                 side_a.distance(corners_b[:, 0], corners_b[:, 1])]))))


# --- squares ------------------------------------------------------------------------
SIDES = ("right", "bottom", "left", "top")  # outward normal angle 0, +90, 180, 270 deg (image y down)


@dataclass
class SquareFit:
    width_px: float  # left/right distance (seed's l, with fx)
    height_px: float  # top/bottom distance (with fy)
    width_seed_px: float  # mean x of right points - mean x of left points (the seed's formula verbatim)
    lines: dict  # side -> Line
    corners: np.ndarray  # (4, 2): top-left, top-right, bottom-right, bottom-left
    side_of_point: np.ndarray  # (N,) side index into SIDES, -1 if dropped
    used: np.ndarray  # (N,) bool: inlier of its side's final fit
    n_points: int

    def to_dict(self) -> dict:
        return {"width_px": self.width_px, "height_px": self.height_px, "width_seed_px": self.width_seed_px,
                "n_points": self.n_points, "n_used": int(self.used.sum()),
                "side_rms_px": {s: self.lines[s].rms_px for s in SIDES}, "corners_px": self.corners.tolist()}


def outward_normals(x, y, nx, ny) -> tuple[np.ndarray, np.ndarray]:
    """Normals flipped to point away from the point cloud's centroid."""
    cx, cy = np.mean(x), np.mean(y)
    s = np.sign(nx * (x - cx) + ny * (y - cy))
    s[s == 0] = 1.0
    return nx * s, ny * s


def assign_sides(x, y, nx, ny) -> np.ndarray:
    """Side index (0 right, 1 bottom, 2 left, 3 top) of each point from its outward normal."""
    ox, oy = outward_normals(x, y, nx, ny)
    th = np.arctan2(oy, ox)
    z = np.exp(4j * th).sum()
    th0 = np.angle(z) / 4.0  # dominant orientation modulo 90 deg, in (-45, 45]
    return np.mod(np.round((th - th0) / (np.pi / 2)).astype(int), 4)


def fit_square(x, y, nx, ny, corner_trim_px: float = 6.0, seed: int = 0) -> SquareFit:
    """Robust side lines and the square's width/height in pixels (see module docstring)."""
    x = np.asarray(x, np.float64)
    y = np.asarray(y, np.float64)
    side = assign_sides(x, y, np.asarray(nx, float), np.asarray(ny, float))
    lines: dict = {}
    for k, name in enumerate(SIDES):
        sel = side == k
        if sel.sum() < MIN_SIDE_POINTS:
            raise InputError(f"square fit: only {int(sel.sum())} edge points on the {name} side "
                             f"(need {MIN_SIDE_POINTS}); is the target a square and fully in view?")
        lines[name] = fit_line_robust(x[sel], y[sel], seed=seed + k)
    used = np.zeros(x.size, bool)
    keep_side = side.copy()
    for _ in range(2):  # corners from the lines, trim points near them, refit
        corners = np.array([intersect(lines["left"], lines["top"]), intersect(lines["top"], lines["right"]),
                            intersect(lines["right"], lines["bottom"]), intersect(lines["bottom"], lines["left"])])
        near = np.min(np.hypot(x[:, None] - corners[None, :, 0], y[:, None] - corners[None, :, 1]), axis=1)
        keep_side = np.where(near > corner_trim_px, side, -1)
        for k, name in enumerate(SIDES):
            sel = np.flatnonzero(keep_side == k)
            if sel.size < MIN_SIDE_POINTS:
                raise InputError(f"square fit: {sel.size} points left on the {name} side after trimming "
                                 f"{corner_trim_px} px at the corners; the target is too small in the image")
            ln = fit_line_robust(x[sel], y[sel], seed=seed + k)
            lines[name] = ln
            used[sel] = ln.inliers
    corners = np.array([intersect(lines["left"], lines["top"]), intersect(lines["top"], lines["right"]),
                        intersect(lines["right"], lines["bottom"]), intersect(lines["bottom"], lines["left"])])
    tl, tr, br, bl = corners
    width = _line_gap(lines["left"], np.array([tl, bl]), lines["right"], np.array([tr, br]))
    height = _line_gap(lines["top"], np.array([tl, tr]), lines["bottom"], np.array([bl, br]))
    r_sel = (keep_side == 0) & used
    l_sel = (keep_side == 2) & used
    width_seed = float(x[r_sel].mean() - x[l_sel].mean())
    used &= keep_side >= 0
    return SquareFit(width, height, width_seed, lines, corners, keep_side, used, int(x.size))


# --- circles ------------------------------------------------------------------------
@dataclass
class CircleFit:
    cx: float
    cy: float
    r: float
    used: np.ndarray
    rms_px: float
    n_points: int
    algebraic: tuple = field(default=(np.nan, np.nan, np.nan))

    @property
    def diameter_px(self) -> float:
        return 2.0 * self.r

    def to_dict(self) -> dict:
        return {"diameter_px": self.diameter_px, "centre_px": [self.cx, self.cy], "radius_px": self.r,
                "rms_px": self.rms_px, "n_points": self.n_points, "n_used": int(self.used.sum()),
                "taubin_start": list(self.algebraic)}


def circle_taubin(x, y) -> tuple[float, float, float]:
    """Taubin's algebraic circle fit (Chernov's Newton formulation): (cx, cy, r)."""
    x = np.asarray(x, np.float64)
    y = np.asarray(y, np.float64)
    mx, my = x.mean(), y.mean()
    u, v = x - mx, y - my
    z = u * u + v * v
    muu, mvv, muv = (u * u).mean(), (v * v).mean(), (u * v).mean()
    muz, mvz, mzz = (u * z).mean(), (v * z).mean(), (z * z).mean()
    mz = muu + mvv
    cov_xy = muu * mvv - muv * muv
    var_z = mzz - mz * mz
    a3 = 4 * mz
    a2 = -3 * mz * mz - mzz
    a1 = var_z * mz + 4 * cov_xy * mz - muz * muz - mvz * mvz
    a0 = muz * (muz * mvv - mvz * muv) + mvz * (mvz * muu - muz * muv) - var_z * cov_xy
    a22, a33 = a2 + a2, a3 * 3
    xn = 0.0
    yn = a0
    for _ in range(99):
        dy = a1 + xn * (a22 + xn * a33)
        xnew = xn - yn / dy
        if xnew == xn or not np.isfinite(xnew):
            break
        ynew = a0 + xnew * (a1 + xnew * (a2 + xnew * a3))
        if abs(ynew) >= abs(yn):
            break
        xn, yn = xnew, ynew
    det = xn * xn - xn * mz + cov_xy
    ccx = (muz * (mvv - xn) - mvz * muv) / det / 2
    ccy = (mvz * (muu - xn) - muz * muv) / det / 2
    return float(ccx + mx), float(ccy + my), float(np.sqrt(ccx * ccx + ccy * ccy + mz))


def _geometric(x, y, start, scale):
    def res(p):
        return np.hypot(x - p[0], y - p[1]) - p[2]

    sol = least_squares(res, np.asarray(start, float), method="trf", loss="soft_l1", f_scale=scale,
                        x_scale="jac", xtol=1e-12, ftol=1e-12, gtol=1e-12)
    return sol.x


def fit_circle(x, y, aspect: float = 1.0, cy_px: float = 0.0) -> CircleFit:
    """Robust circle fit: Taubin start, geometric LM (soft-L1), 3-sigma rejection, refit.

    ``aspect`` = fx / fy scales y about ``cy_px`` so the result is in fx pixels.
    """
    x = np.asarray(x, np.float64)
    y0 = np.asarray(y, np.float64)
    y = cy_px + (y0 - cy_px) * aspect
    if x.size < MIN_CIRCLE_POINTS:
        raise InputError(f"circle fit: {x.size} edge points (need {MIN_CIRCLE_POINTS})")
    start = circle_taubin(x, y)
    p = _geometric(x, y, start, 0.5)
    used = np.ones(x.size, bool)
    for _ in range(3):
        r = np.hypot(x - p[0], y - p[1]) - p[2]
        s = _mad_sigma(r[used])
        new = np.abs(r) <= 3.0 * s
        if new.sum() < MIN_CIRCLE_POINTS:
            break
        p = _geometric(x[new], y[new], p, s)
        if np.array_equal(new, used):
            used = new
            break
        used = new
    r = np.hypot(x - p[0], y - p[1]) - p[2]
    return CircleFit(float(p[0]), float(cy_px + (p[1] - cy_px) / aspect), float(p[2]), used,
                     float(np.sqrt(np.mean(r[used] ** 2))), int(x.size), start)


def distance_from_size(f_px: float, size_m: float, size_px: float) -> float:
    """Pinhole ranging Z = f * S / l (metres)."""
    return float(f_px * size_m / size_px) if size_px > 0 else float("nan")
