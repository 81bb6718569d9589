"""The optical edge: where the renderer's camera model puts a target's edge, beside the geometric one.

The geometric outline (``edgetruth.render.scene.outline``) is where a scene edge projects.  The image of
that edge is its step convolved with the camera's kernel, and a symmetric kernel leaves it in place.
The thin lens of ``edgetruth.render.optics.lens_sensor`` is not symmetric off axis when the edge is out of
focus: each ray carries the weight (1 + ρ²)/(1 + |a/f + b|²)² (natural vignetting; a the aperture
point, f the focal length, ρ = R/f, b the ray's sensor point in normalised coordinates), so the
weight tilts across the aperture and the defocus disk's weighted centroid moves.

Derivation (docs/optics.md, "The optical edge").  A ray from aperture point a (metres) through
sensor point x_s reaches, at depth z, the scene point whose undistorted normalised image is
x_und(x_s) + a c, c = 1/z − 1/z_f (z_f the focus distance).  In distorted pixels that point lies at
x_s + D a, D = f_x c J, J the Jacobian of the distortion (distorted over undistorted normalised
coordinates).  Across a locally straight edge with outward unit normal n (dark target inside, bright
board outside), the normalised edge-spread function at x_s, s = (x_s − u_0)·n, is the share of the
weighted rays that land outside: P(Y < s) with Y = −n·D a + G, G the (symmetric) pixel box ⊗ PSF.
So the image edge lies, along n, at

- **centroid** (the mean of the line-spread function, what an area / light-deficit estimate
  measures): Δ_c = −n·D E_w[a];
- **50 % level** (median of Y): Δ_50, which a symmetric disk's tilt puts at 4/3 Δ_c before the
  symmetric part G pulls it back towards Δ_c.

To first order in a/f, E_w[a] = (R²/4) ∇ln w = −R² b / (f (1 + |b|²)), so
Δ_c ≈ f_x c (R²/f) n·J b / (1 + |b|²): outward when the edge is nearer than focus (c > 0) and off
axis along its normal; inward beyond focus; zero in focus and on the axis.  Exact moments come
from a quadrature of the weight over the aperture disk (``aperture_mean``).

The pixel's own falloff multiplies both sides of the edge alike and does not move a level defined
against the local plateaus; the PSF's field dependence is per receiving pixel (the kernel of pixel p
is centred on p) and does not move the edge either.  Left out: motion blur (symmetric for a uniform
motion), the disk's distortion beyond the local Jacobian, the weight's dependence on the PSF offset
of the sensor point (< 1e-4 px).
"""
from __future__ import annotations

import functools
import math

import numpy as np

OPTICAL_LEVELS = ("centroid", "median")


def _disk_nodes(rho: float, n_r: int = 24, n_phi: int = 48):
    """Polar Gauss–Legendre nodes of the disk |a| <= rho: (ax, ay, area weights), sum = π rho²."""
    gr, wr = np.polynomial.legendre.leggauss(n_r)
    r = 0.5 * rho * (gr + 1.0)
    phi = 2.0 * np.pi * (np.arange(n_phi) + 0.5) / n_phi  # periodic: the midpoint rule is spectral
    ax = (r[:, None] * np.cos(phi)[None, :]).ravel()
    ay = (r[:, None] * np.sin(phi)[None, :]).ravel()
    w = (0.5 * rho * wr[:, None] * r[:, None] * np.full(n_phi, 2.0 * np.pi / n_phi)[None, :]).ravel()
    return ax, ay, w


def lens_weight(ax, ay, bx, by, rho: float):
    """The sensor plugin's per-ray weight: (1 + ρ²) / (1 + |a + b|²)², a and b in units of f."""
    return (1.0 + rho * rho) / (1.0 + (ax + bx) ** 2 + (ay + by) ** 2) ** 2


def aperture_mean(rho: float, bx, by, n_r: int = 24, n_phi: int = 48) -> np.ndarray:
    """Weighted mean aperture point (units of f), (N, 2), of the thin lens's ray weights at sensor
    points b = (bx, by) (normalised, distorted): numeric quadrature over the disk of radius rho."""
    bx, by = np.atleast_1d(np.asarray(bx, float)), np.atleast_1d(np.asarray(by, float))
    if rho <= 0:
        return np.zeros((bx.size, 2))
    ax, ay, w = _disk_nodes(rho, n_r, n_phi)
    ww = w[None, :] * lens_weight(ax[None, :], ay[None, :], bx[:, None], by[:, None], rho)
    s = ww.sum(1)
    return np.column_stack([(ww * ax).sum(1) / s, (ww * ay).sum(1) / s])


def aperture_mean_first_order(rho: float, bx, by) -> np.ndarray:
    """E_w[a] to first order in a/f: (ρ²/4) ∇ ln w(0) = −ρ² b / (1 + |b|²) (units of f)."""
    bx, by = np.atleast_1d(np.asarray(bx, float)), np.atleast_1d(np.asarray(by, float))
    k = -rho * rho / (1.0 + bx * bx + by * by)
    return np.column_stack([k * bx, k * by])


def _distortion_jacobian(camera, x_und, y_und, eps: float = 1e-6) -> np.ndarray:
    """(N, 2, 2) Jacobian of distorted pixels over undistorted normalised coordinates, f_x J."""
    def proj(x, y):
        return camera.project(np.column_stack([x, y, np.ones_like(x)]), distorted=True)
    jx = (proj(x_und + eps, y_und) - proj(x_und - eps, y_und)) / (2 * eps)
    jy = (proj(x_und, y_und + eps) - proj(x_und, y_und - eps)) / (2 * eps)
    return np.stack([jx, jy], axis=2)  # [:, :, 0] = d(px)/dx_und


def outward_normals(ring_px: np.ndarray, tangents_px: np.ndarray) -> np.ndarray:
    """Unit normals pointing out of the region the closed polygon ``ring_px`` encloses, at points
    whose tangents (in the ring's direction of travel) are ``tangents_px``."""
    p = np.asarray(ring_px, float)
    t = np.asarray(tangents_px, float)
    t = t / np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-300)
    area2 = np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1])
    orient = 1.0 if area2 > 0 else -1.0
    return orient * np.column_stack([t[:, 1], -t[:, 0]])


def _symmetric_spread(camera, x_px, y_px, normal) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per point: the pixel box's two widths along the normal (|n_x|, |n_y|) and the PSF's Gaussian σ
    (aberration σ(h), Airy core ≈ 0.42 λN, 4-dot OLPF as its variance), in px."""
    from edgetruth.render.optics.prediction import field_height
    from edgetruth.render.optics.psf import psf_params

    p = psf_params(camera)
    h = field_height(camera, x_px, y_px)
    s_ab = p.sigma_px * (1.0 + p.sigma_growth * h ** 2)
    s_airy = 0.42 / p.cutoff_cy_px if math.isfinite(p.cutoff_cy_px) and p.cutoff_cy_px > 0 else 0.0
    var = s_ab ** 2 + s_airy ** 2 + 0.25 * p.olpf_px ** 2
    return np.abs(normal[:, 0]), np.abs(normal[:, 1]), np.sqrt(var)


@functools.lru_cache(maxsize=4)
def _gauss_legendre(n: int):
    """``np.polynomial.legendre.leggauss(n)``, read-only, computed once per n (an eigenvalue problem:
    ~10 % of a ``_median_offsets`` call)."""
    nodes, weights = np.polynomial.legendre.leggauss(n)
    nodes.flags.writeable = weights.flags.writeable = False
    return nodes, weights


def _median_offsets(rho, b, m, box_x, box_y, sigma, f_m, n_grid: int = 801, n_chord: int = 24) -> np.ndarray:
    """Median of Y = −m·a + G per point: m (N, 2) px per metre of aperture, a the weighted disk of
    radius rho·f (the weight in units of f), G = box(box_x) ⊗ box(box_y) ⊗ N(0, σ²), along one axis.

    Per point: the density of Y on its own grid of ``n_grid`` samples over its support (the chord
    integrals of the weight by ``n_chord``-point Gauss–Legendre), convolved as ``np.convolve(...,
    "same")`` with the two odd box kernels and the sampled Gaussian, and the 50 % level of its
    cumulative sum.  All points at once (whole arrays, no loop over points): the boxes by cumulative
    sums, the Gaussians by one batched FFT -- the numbers of a loop over points with ``np.convolve``
    to ~1e-13 px (rounding)."""
    from scipy import fft

    b = np.asarray(b, float).reshape(-1, 2)
    m = np.asarray(m, float).reshape(-1, 2)
    out = np.zeros(len(b))
    mm = np.hypot(m[:, 0], m[:, 1])
    live = np.flatnonzero(~(mm * rho * f_m < 1e-9))  # in focus (or no aperture): offset 0
    if not live.size:
        return out
    nl = live.size
    mm, b = mm[live], b[live]
    u = m[live] / mm[:, None]
    box_x, box_y = np.asarray(box_x, float)[live], np.asarray(box_y, float)[live]
    sigma = np.asarray(sigma, float)[live]
    scale = mm * rho * f_m  # Y_lens half-range (px)
    half = scale + 0.5 * (box_x + box_y) + 6.0 * sigma + 0.05
    y = np.linspace(-half, half, n_grid, axis=1)  # (nl, n_grid), row i = np.linspace(-half[i], half[i], n_grid)
    dy = y[:, 1] - y[:, 0]
    # density of a'·u (units of f) at t = −y / (mm f): the weight's integral along the disk's chord at t,
    # only where there is a chord (|t| < ρ; 0 elsewhere) -- in focus that is one sample.  In the frame
    # (u, u⊥), a + b = (t + u·b, s + u⊥·b): the weight is (1 + ρ²) / (1 + X² + (s + V)²)²
    t = -y / (mm * f_m)[:, None]
    r, j = np.nonzero(np.abs(t) < rho)
    ti = t[r, j]
    c = np.sqrt(np.maximum(rho * rho - ti * ti, 0.0))  # the chord's half-length
    p1 = 1.0 + (ti + (u[:, 0] * b[:, 0] + u[:, 1] * b[:, 1])[r]) ** 2  # 1 + X²
    v = (u[:, 0] * b[:, 1] - u[:, 1] * b[:, 0])[r]  # V
    gl, wl = _gauss_legendre(n_chord)
    dens = np.zeros_like(y)
    chunk = 4096  # samples per block: its (chunk, n_chord) temporaries stay in cache
    for lo in range(0, r.size, chunk):
        sl = slice(lo, lo + chunk)
        q = np.multiply.outer(c[sl], gl)
        q += v[sl, None]
        np.square(q, out=q)
        q += p1[sl, None]
        np.square(q, out=q)
        np.reciprocal(q, out=q)
        dens[r[sl], j[sl]] = (1.0 + rho * rho) * c[sl] * (q @ wl)
    # the pixel boxes: np.convolve(dens, ones(k) / k, "same") with k = 2h + 1 odd (a centred kernel) is a
    # moving sum over the row padded with zeros: a difference of the padded row's cumulative sum
    for width in (box_x, box_y):
        h = np.rint(0.5 * width / dy).astype(np.intp)  # half to even, as round()
        rows = np.flatnonzero(h > 0)  # k = 1: unchanged
        if not rows.size:
            continue
        hr, hm = h[rows], int(h.max())
        lp = n_grid + 2 * hm + 1
        cs = np.zeros((rows.size, lp))
        cs[:, hm + 1:hm + 1 + n_grid] = dens[rows]
        np.cumsum(cs, axis=1, out=cs)
        at = (np.arange(rows.size) * lp + hm)[:, None] + np.arange(n_grid)[None, :]  # flat index of sample j
        cs = cs.ravel()
        dens[rows] = (cs[at + (hr + 1)[:, None]] - cs[at - hr[:, None]]) / (2 * hr + 1)[:, None]
    rows = np.flatnonzero(sigma > 0)
    if rows.size:
        # the Gaussian: np.convolve(dens, g / g.sum(), "same"), g sampled at d·dy, |d| <= a, on the row's own
        # grid.  The kernels differ in length: one batched circular convolution by FFT, long enough that
        # nothing wraps onto the grid (the rows' supports ± a and the grid fit in one period)
        a = (6 * sigma[rows] / dy[rows]).astype(np.intp) + 1
        am = int(a.max())
        d = np.arange(am + 1)
        g = np.exp(-0.5 * (d[None, :] * dy[rows, None] / sigma[rows, None]) ** 2)
        g[d[None, :] > a[:, None]] = 0.0
        g /= 2.0 * g.sum(1, keepdims=True) - g[:, :1]  # the sum over -a..a
        dr = dens[rows]
        nz = dr != 0
        first = np.argmax(nz, axis=1)
        last = n_grid - 1 - np.argmax(nz[:, ::-1], axis=1)
        span = int(np.max(np.maximum(n_grid - 1, last + a) - np.minimum(0, first - a) + 1))
        p = 2 * fft.next_fast_len((max(span, 2 * am + 1) + 1) // 2, real=True)  # even, > 2 am
        # the kernel is even: its spectrum is real, the DCT-I of its half d = 0..p/2
        half_k = np.zeros((rows.size, p // 2 + 1))
        half_k[:, :am + 1] = g
        spec = fft.rfft(dr, p, axis=1) * fft.dct(half_k, type=1, axis=1)
        dens[rows] = fft.irfft(spec, p, axis=1)[:, :n_grid]
    cdf = np.cumsum(dens, axis=1)
    total = cdf[:, -1:].copy()
    cdf -= 0.5 * dens
    cdf /= total
    # np.interp(0.5, cdf, y) per row: the cdf passes 0.5 once, between samples k and k + 1 (the FFT's
    # round-off keeps its tails within ~1e-16 of 0 and 1)
    k = np.clip(np.count_nonzero(cdf <= 0.5, axis=1) - 1, 0, n_grid - 2)
    i = np.arange(nl)
    x0, x1, y0, y1 = cdf[i, k], cdf[i, k + 1], y[i, k], y[i, k + 1]
    out[live] = (y1 - y0) / (x1 - x0) * (0.5 - x0) + y0
    return out


def optical_offsets(camera, points_cam_m: np.ndarray, points_px: np.ndarray, normals_px: np.ndarray,
                    levels=("centroid",), first_order: bool = False) -> dict:
    """Displacement (px) of the image edge from the geometric outline along ``normals_px`` (outward,
    towards the bright board) at outline points given in the camera frame (metres) and in distorted
    pixels: {"centroid": (N,), "median": (N,)} for the requested ``levels``."""
    pc = np.asarray(points_cam_m, float).reshape(-1, 3)
    px = np.asarray(points_px, float).reshape(-1, 2)
    nrm = np.asarray(normals_px, float).reshape(-1, 2)
    nrm = nrm / np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-300)
    n = len(pc)
    out = {}
    r_m, f_m, zf = camera.aperture_radius_m, camera.focal_length_m, camera.focus_distance_m
    if r_m <= 0 or n == 0:
        return {lv: np.zeros(n) for lv in levels}
    rho = r_m / f_m
    cx, cy = camera.principal_point_px
    bx, by = (px[:, 0] - cx) / camera.fx_px, (px[:, 1] - cy) / camera.fy_px  # the plugin's b: distorted sensor point
    c = 1.0 / pc[:, 2] - 1.0 / zf
    jac = _distortion_jacobian(camera, pc[:, 0] / pc[:, 2], pc[:, 1] / pc[:, 2])  # px per normalised unit
    d = jac * c[:, None, None]  # D: px per metre of aperture
    m = np.einsum("ni,nij->nj", nrm, d)  # n·D
    if "centroid" in levels:
        ea = (aperture_mean_first_order if first_order else aperture_mean)(rho, bx, by) * f_m  # metres
        out["centroid"] = -np.einsum("nj,nj->n", m, ea)
    if "median" in levels:
        box_x, box_y, sigma = _symmetric_spread(camera, px[:, 0], px[:, 1], nrm)
        out["median"] = _median_offsets(rho, np.column_stack([bx, by]), m, box_x, box_y, sigma, f_m)
    return out


def first_order_offset_px(fx_px: float, aperture_radius_m: float, focal_length_m: float, z_m: float,
                          focus_m: float, b_normal: float, b_sq: float = None) -> float:
    """The closed form for an undistorted lens: f_x (1/z − 1/z_f) (R²/f) (n·b) / (1 + |b|²)."""
    b_sq = b_normal ** 2 if b_sq is None else b_sq
    return fx_px * (1.0 / z_m - 1.0 / focus_m) * aperture_radius_m ** 2 / focal_length_m * b_normal / (1.0 + b_sq)


def curve_optical_offsets(curve, t: np.ndarray, levels=("centroid", "median")) -> dict:
    """Optical offsets (px, outward) at parameters ``t`` of an ``OutlineCurve`` (mid-exposure)."""
    t = np.asarray(t, float)
    pts = curve.points(t)
    h = 1e-6
    tang = curve.points(t + h) - pts  # forward difference: a square's corner takes the next side
    nrm = outward_normals(curve.points(np.linspace(0.0, 1.0, 64, endpoint=False)), tang)
    cam_pts = curve.pose.to_camera(curve.local(t))
    out = optical_offsets(curve.camera, cam_pts, pts, nrm, levels=[lv for lv in levels if lv != "median"])
    if "median" in levels:  # smooth along the curve: a 1-D quadrature at <= ~100 nodes, interpolated
        n = len(t)
        nodes = set(range(0, n, max(1, n // 96))) | {n - 1}
        if curve.shape in ("square", "polygon"):  # both ends of every side
            k = np.floor(curve._pieces() * np.mod(t, 1.0) + 1e-9).astype(int)
            jumps = np.flatnonzero(np.diff(k) != 0)
            nodes |= set(jumps.tolist()) | set((jumps + 1).tolist())
        idx = np.array(sorted(nodes))
        med = optical_offsets(curve.camera, cam_pts[idx], pts[idx], nrm[idx], levels=("median",))["median"]
        out["median"] = np.interp(np.arange(n), idx, med)
    return out


class OpticalOutline:
    """A target's outline and its optical edge (``outline.optical_edge`` of the JSON).

    ``signed_distance(x, y, level)``: px to the optical edge (the geometric distance minus the
    offset of the nearest outline point; the offset varies slowly along the outline), > 0 on the
    bright board; ``geometric_signed_distance`` to the outline itself; ``offset_at(x, y)``."""

    def __init__(self, edge, offsets: dict):
        self.edge = edge  # edgetruth.render.edge_truth.OutlineEdge
        self.offsets = {k: np.asarray(v, float) for k, v in offsets.items()}

    @classmethod
    def from_ground_truth(cls, gt: dict) -> "OpticalOutline":
        from edgetruth.render.edge_truth import OutlineEdge

        oe = gt["outline"]["optical_edge"]
        return cls(OutlineEdge.from_ground_truth(gt),
                   {"centroid": oe["offset_px"], "median": oe.get("offset_50_px", oe["offset_px"])})

    @property
    def polyline_px(self) -> np.ndarray:
        return self.edge.polyline_px

    def offset_at(self, x, y, level: str = "centroid") -> np.ndarray:
        return nearest_offsets(self.edge.polyline_px, self.offsets[level], x, y)

    def polyline(self, level: str = "centroid") -> np.ndarray:
        """The optical edge as a polyline: each outline point moved along its outward normal."""
        p = self.edge.polyline_px
        tang = np.roll(p, -1, axis=0) - np.roll(p, 1, axis=0)
        return p + outward_normals(p, tang) * self.offsets[level][:, None]

    def geometric_signed_distance(self, x, y) -> np.ndarray:
        return self.edge.signed_distance(x, y)

    def signed_distance(self, x, y, level: str = "centroid") -> np.ndarray:
        return self.edge.signed_distance(x, y) - self.offset_at(x, y, level)

    def corner_distance(self, x, y) -> np.ndarray:
        return self.edge.corner_distance(x, y)


#: The last few ``optical_edge_ground_truth`` blocks by (curve, t): every cell of a design slot shares the
#: pose, and the squares T1, T3 and T4 the outline, so 7 images of a slot need 2 quadratures, not 7 (the
#: 50 % level's quadrature is most of a quick image's time outside ``mi.render``).  A pure function of its
#: arguments: a cached block is the one it would compute, byte for byte.
_MEMO: dict = {}
_MEMO_SIZE = 8


def optical_edge_ground_truth(curve, t: np.ndarray) -> dict:
    """The JSON block ``outline.optical_edge``: per polyline point, the optical edge's offset."""
    t = np.asarray(t, float)
    try:
        key = (curve, t.shape, t.tobytes())
        hit = _MEMO.get(key)
    except TypeError:  # an unhashable curve: no memo
        key = hit = None
    if hit is None:
        hit = _optical_edge_block(curve, t)
        if key is not None and _MEMO_SIZE > 0:
            while len(_MEMO) >= _MEMO_SIZE:
                _MEMO.pop(next(iter(_MEMO)))
            _MEMO[key] = hit
    return {k: list(v) if isinstance(v, list) else v for k, v in hit.items()}  # the caller's own lists


def _optical_edge_block(curve, t: np.ndarray) -> dict:
    off = curve_optical_offsets(curve, t)
    return {"offset_px": [round(float(v), 7) for v in off["centroid"]],
            "offset_50_px": [round(float(v), 7) for v in off["median"]],
            "meaning": "per polyline point: displacement (px) of the image edge from the geometric outline "
                       "along the outward normal (> 0 towards the bright board) that the camera model predicts "
                       "-- offset_px: the centroid of the line-spread function (the thin lens's vignetting "
                       "weight tilts the defocus disk), offset_50_px: its 50 % level; "
                       "edgetruth.render.optics.optical_edge derives both (docs/optics.md)"}


def nearest_offsets(polyline_px: np.ndarray, offsets: np.ndarray, x, y) -> np.ndarray:
    """The offset of the polyline vertex nearest each point (the offset varies slowly along a side)."""
    from scipy.spatial import cKDTree

    q = np.column_stack([np.ravel(x), np.ravel(y)]).astype(float)
    if not len(q):
        return np.zeros(np.shape(x))
    _, i = cKDTree(np.asarray(polyline_px, float)).query(q)
    return np.asarray(offsets, float)[i].reshape(np.shape(x))
