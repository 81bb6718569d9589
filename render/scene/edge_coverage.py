"""The exact lens-weighted coverage of a target's outline per pixel: the analytic edge band.

Near a target's outline a pixel averages two smoothly shaded regions, the board (outside) and the
target (inside).  With the renderer's camera model (``edgetruth.render.optics.lens_sensor``) a pixel p's
value is E[w L] over its rays: sensor point c_p + z with z ~ K_p (the tabulated pixel box ⊗ PSF of
``edgetruth.render.optics.psf``, bilinear on a vertex grid, the field levels mixed linearly as Mitsuba's
warp mixes them), aperture point a uniform on the lens disk, ray weight w = (1 + ρ²)/(1 + |a/f + b|²)².
When each region's radiance is constant over the kernel's footprint,

    value(p) = S_out(p) (1 − c(p)) + S_in(p) c(p),    c(p) = E[w χ] / E[w],

S_out / S_in the renders of the board alone and of the target's material alone (smooth: a few spp
converge them) and χ = 1 for rays that land inside the target.  ``pixel_coverage`` computes c
deterministically:

- **Aperture**: a polar Gauss–Legendre × periodic-midpoint rule on the lens disk, each node weighted
  by the plugin's ray weight at the pixel centre.  For aperture point A (metres) the sensor points
  whose rays pass through an outline point P are exactly distort(P_xy/P_z − (1/P_z − 1/z_f) A): the
  outline seen from each node is the outline's own points moved, with no linearisation (a tilted
  board's depth enters per point).
- **Kernel**: Green's theorem turns the area integral of K over the target into a contour integral,
  ∫∫_Ω K(x − c_p) dA = ∮_∂Ω G(x − c_p) dy with G(x, y) = ∫_{−∞}^x K(x', y) dx'.  For the bilinear table,
  G is piecewise polynomial (quadratic in x within a cell, linear in y within a row), so splitting
  each polyline segment of the outline at the table's grid lines and using 2-point Gauss–Legendre
  on each piece integrates it exactly.  Corners and curves need nothing special.

What is left out (docs/optics.md, "Edges without Monte-Carlo noise"): the polyline's chord error
(``CHORD_TOLERANCE_PX``), the ray weight's variation across the kernel footprint (it is taken at
the pixel centre; ~1e-3 per px at the image corner), the aperture rule's error, and -- in the
composite -- the shading's variation across the footprint (second order: a gradient of the shading
times the kernel's first moment on the covered side).
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from edgetruth.jit import njit, prange

CHORD_TOLERANCE_PX = 1e-4  # curves: polyline spacing keeps the chords within this of the curve


@dataclass(frozen=True)
class KernelTables:
    """The renderer's kernel K = box ⊗ PSF per field level, normalised to ∫K = 1 (px⁻²), on the
    vertex grid x_i = −R + i h (rows: y), with the row cumulatives that G needs."""

    density: np.ndarray  # (L, n, n) px⁻²
    row_cum: np.ndarray  # (L, n, n): ∫_{−R}^{x_i} of row j's piecewise-linear density
    row_mass: np.ndarray  # (L, n): ∫ over x of row j
    mass_cum: np.ndarray  # (L, n): ∫_{−R}^{y_j} of the row masses
    half_width_px: float
    step_px: float
    levels: np.ndarray  # field heights² of the levels


def kernel_tables(camera) -> KernelTables:
    """The tables for ``camera``: its PSF table, or the pixel box alone (a 2 x 2 table of ones on
    [−½, ½]²: the bilinear interpolant of a constant is the box itself)."""
    from edgetruth.render.optics.psf import psf_params

    return _kernel_tables(psf_params(camera))


@functools.lru_cache(maxsize=16)
def _kernel_tables(params) -> KernelTables:
    from edgetruth.render.optics.psf import psf_table

    table = psf_table(params)
    if table is None:
        d, h, r, levels = np.ones((1, 2, 2)), 1.0, 0.5, np.array([0.0])
    else:
        d = table.density.astype(np.float64)
        h, r, levels = float(table.step_px), float(table.half_width_px), np.asarray(table.field_heights_sq, float)
    mass = (0.5 * h * (d[:, :, 1:] + d[:, :, :-1])).sum(axis=2)
    total = (0.5 * h * (mass[:, 1:] + mass[:, :-1])).sum(axis=1)
    return _tables_from(d / total[:, None, None], h, r, levels)  # each level normalised, as Mitsuba's warp


def _tables_from(d: np.ndarray, h: float, r: float, levels: np.ndarray) -> KernelTables:
    """Row cumulatives of the bilinear density ``d`` (L, n, n) on [−r, r]² (no renormalisation)."""
    trap = 0.5 * h * (d[:, :, 1:] + d[:, :, :-1])  # (L, n, n-1) per-cell integrals along x
    row_cum = np.concatenate([np.zeros(d.shape[:2] + (1,)), np.cumsum(trap, axis=2)], axis=2)
    row_mass = row_cum[:, :, -1].copy()
    mass_cum = np.concatenate([np.zeros((d.shape[0], 1)),
                               np.cumsum(0.5 * h * (row_mass[:, 1:] + row_mass[:, :-1]), axis=1)], axis=1)
    return KernelTables(np.ascontiguousarray(d), row_cum, row_mass, mass_cum, r, h, levels)


#: the kernel's core reaches the pixel box + this many of its largest Gaussian σ (+ 0.5 px): beyond
#: it only the Airy tail is left, which a small aperture rule integrates
CORE_SIGMAS = 4.0


@functools.lru_cache(maxsize=16)
def split_tables(params) -> tuple[KernelTables, KernelTables] | None:
    """(core, tail) with K = K_core + K_tail exactly: the core is the table's vertices within the core
    box (its outer ring of vertices zeroed, on a cropped grid), the tail the rest on the full grid --
    both bilinear on the same vertices, so both integrate exactly.  None when the table is small."""
    full = _kernel_tables(params)
    h, r, n = full.step_px, full.half_width_px, full.density.shape[1]
    core_r = math.sqrt(0.5) + CORE_SIGMAS * params.sigma_max_px * (1.0 + max(params.sigma_growth, 0.0)) + 0.5
    m = int(math.ceil(core_r / h)) + 1  # vertices -m..m, the ring at ±m zeroed
    c = (n - 1) // 2
    if m >= c - 2:
        return None
    core = full.density[:, c - m:c + m + 1, c - m:c + m + 1].copy()
    core[:, [0, -1], :] = 0.0
    core[:, :, [0, -1]] = 0.0
    tail = full.density.copy()
    tail[:, c - m:c + m + 1, c - m:c + m + 1] -= core
    return _tables_from(core, h, m * h, full.levels), _tables_from(tail, h, r, full.levels)


def level_mix(tables: KernelTables, camera, x_px, y_px) -> tuple[np.ndarray, np.ndarray]:
    """Per pixel: the lower field level and the weight of the next (the plugin's q = h², clipped)."""
    lv = tables.levels
    if len(lv) == 1:
        return np.zeros(np.size(x_px), np.int64), np.zeros(np.size(x_px))
    cx, cy = camera.principal_point_px
    q = np.minimum(((np.ravel(x_px) - cx) ** 2 + (np.ravel(y_px) - cy) ** 2) / camera.half_diagonal_px ** 2, 1.0)
    lo = np.clip(np.searchsorted(lv, q, side="right") - 1, 0, len(lv) - 2)
    return lo.astype(np.int64), (q - lv[lo]) / (lv[lo + 1] - lv[lo])


def aperture_nodes(defocus_px: float, n_r: int | None = None, n_phi: int | None = None, smooth: bool = True):
    """Nodes of the unit disk (ux, uy, area weights summing to 1) for a defocus disk of radius
    ``defocus_px``: polar Gauss–Legendre in r² (n_r) × periodic midpoint (n_phi); one node in focus,
    more as the disk grows against the kernel's core.  ``smooth``: the kernel has a PSF (its ESF is
    smooth; measured against a 32 x 128 rule: 7e-6 at 2.2 px (4 x 16 nodes), 3e-5 at 0.56 px (3 x 12)); the pixel box
    alone has kinks and gets more nodes."""
    if defocus_px <= 1e-6 and n_r is None:  # in focus (a flush target's 10 um stand-off: ~1e-8 px)
        return np.zeros(1), np.zeros(1), np.ones(1)
    if n_r is None:
        n_r = 1 if defocus_px < 0.05 else math.ceil((1.5 + defocus_px) if smooth else (2.0 + 8.0 * defocus_px))
        n_r = int(min(16, n_r))
    n_phi = n_phi or max(4, 4 * n_r)
    g, wg = np.polynomial.legendre.leggauss(n_r)
    r = np.sqrt(0.5 * (g + 1.0))  # Gauss–Legendre in r² (the area): exact for polynomials in r²
    phi = 2.0 * np.pi * (np.arange(n_phi) + 0.5) / n_phi
    ux = (r[:, None] * np.cos(phi)[None, :]).ravel()
    uy = (r[:, None] * np.sin(phi)[None, :]).ravel()
    w = np.repeat(0.5 * wg, n_phi) / n_phi
    return ux, uy, w / w.sum()


#: the far rule: 4 nodes on the ring r = 1/√2 integrate every polynomial of degree <= 3 over the disk
#: exactly; pixels this far from the outline see only the kernel's smooth Airy tail
FAR_RULE = (np.sqrt(0.5) * np.cos(np.pi / 4 + np.pi / 2 * np.arange(4)),
            np.sqrt(0.5) * np.sin(np.pi / 4 + np.pi / 2 * np.arange(4)), np.full(4, 0.25))
FAR_MARGIN_PX = 4.0  # beyond the defocus radius + this, the far rule
#: the kernel's tail (``split_tables``) on pixels near the outline: 2 rings x 8
TAIL_RULE = aperture_nodes(1.0, n_r=2, n_phi=8)


@njit(cache=True, inline="always")
def _g_value(dens, row_cum, row_mass, lev, xi, eta, r, h, n):
    """G(xi, eta) = ∫_{−∞}^{xi} K(x, eta) dx for level ``lev``."""
    if eta <= -r or eta >= r or xi <= -r:
        return 0.0
    gy = (eta + r) / h
    j = min(int(gy), n - 2)
    v = gy - j
    if xi >= r:
        return (1.0 - v) * row_mass[lev, j] + v * row_mass[lev, j + 1]
    gx = (xi + r) / h
    i = min(int(gx), n - 2)
    u = gx - i
    a0, a1 = dens[lev, j, i], dens[lev, j, i + 1]
    b0, b1 = dens[lev, j + 1, i], dens[lev, j + 1, i + 1]
    cj = row_cum[lev, j, i] + h * u * (a0 + 0.5 * u * (a1 - a0))
    cj1 = row_cum[lev, j + 1, i] + h * u * (b0 + 0.5 * u * (b1 - b0))
    return (1.0 - v) * cj + v * cj1


@njit(cache=True, inline="always")
def _mass_below(row_mass, mass_cum, lev, eta, r, h, n):
    """∫_{−∞}^{eta} of the row masses (the kernel's mass below eta)."""
    if eta <= -r:
        return 0.0
    if eta >= r:
        return mass_cum[lev, n - 1]
    gy = (eta + r) / h
    j = min(int(gy), n - 2)
    v = gy - j
    m0, m1 = row_mass[lev, j], row_mass[lev, j + 1]
    return mass_cum[lev, j] + h * v * (m0 + 0.5 * v * (m1 - m0))


@njit(cache=True)
def _segment_integral(dens, row_cum, row_mass, mass_cum, lev, lam, x0, y0, x1, y1, r, h, n, buf):
    """∫ G dy along the segment (x0, y0) -> (x1, y1) (kernel coordinates), exactly, for the kernel
    (1 − lam) K_lev + lam K_{lev+1}."""
    if (y0 <= -r and y1 <= -r) or (y0 >= r and y1 >= r) or (x0 <= -r and x1 <= -r) or y0 == y1:
        return 0.0
    if x0 >= r and x1 >= r:  # right of the kernel: G is the row mass, whose integral is tabulated
        s = _mass_below(row_mass, mass_cum, lev, y1, r, h, n) - _mass_below(row_mass, mass_cum, lev, y0, r, h, n)
        if lam != 0.0:
            s1 = (_mass_below(row_mass, mass_cum, lev + 1, y1, r, h, n)
                  - _mass_below(row_mass, mass_cum, lev + 1, y0, r, h, n))
            s = (1.0 - lam) * s + lam * s1
        return s
    m = 0
    buf[m] = 0.0
    m += 1
    for axis in range(2):  # parameters where the segment crosses a grid line
        a0, a1 = (x0, x1) if axis == 0 else (y0, y1)
        if a1 != a0:
            lo, hi = max(min(a0, a1), -r), min(max(a0, a1), r)
            if hi > lo:
                k0 = int(math.ceil((lo + r) / h))
                k1 = int(math.floor((hi + r) / h))
                for k in range(k0, k1 + 1):
                    t = (-r + k * h - a0) / (a1 - a0)
                    if 0.0 < t < 1.0:
                        buf[m] = t
                        m += 1
    buf[m] = 1.0
    m += 1
    for a in range(1, m):  # insertion sort: a few dozen entries
        t = buf[a]
        b = a - 1
        while b >= 0 and buf[b] > t:
            buf[b + 1] = buf[b]
            b -= 1
        buf[b + 1] = t
    dx, dy = x1 - x0, y1 - y0
    g = 0.5 / math.sqrt(3.0)
    s = 0.0
    s1 = 0.0
    for a in range(m - 1):
        ta, tb = buf[a], buf[a + 1]
        if tb - ta <= 0.0:
            continue
        tm, length = 0.5 * (ta + tb), (tb - ta)
        t1, t2 = tm - g * length, tm + g * length
        xa, ya, xb, yb = x0 + t1 * dx, y0 + t1 * dy, x0 + t2 * dx, y0 + t2 * dy
        s += 0.5 * length * (_g_value(dens, row_cum, row_mass, lev, xa, ya, r, h, n)
                             + _g_value(dens, row_cum, row_mass, lev, xb, yb, r, h, n))
        if lam != 0.0:
            s1 += 0.5 * length * (_g_value(dens, row_cum, row_mass, lev + 1, xa, ya, r, h, n)
                                  + _g_value(dens, row_cum, row_mass, lev + 1, xb, yb, r, h, n))
    return ((1.0 - lam) * s + lam * s1) * dy


@njit(cache=True, parallel=True)
def _coverage_kernel(px, py, row, lo, lam, node_pts, node_w, seg_ptr, seg_idx, orient, dens, row_cum, row_mass,
                     mass_cum, r, h):
    """c per pixel: Σ_nodes w ∮ G dy over the node's outline.  The candidate segments of a pixel are
    those of its row's list (all segments whose y-range, padded, meets the kernel's rows): right of
    the kernel a segment still adds ∫ M dy, so distant ones on the same rows count too."""
    n = dens.shape[1]
    n_pix = px.shape[0]
    n_nodes, n_pts = node_pts.shape[0], node_pts.shape[1]
    out = np.zeros(n_pix)
    for p in prange(n_pix):
        buf = np.empty(2 * n + 8)
        acc = 0.0
        rw = row[p]
        for a in range(n_nodes):
            sa = 0.0
            for q in range(seg_ptr[rw], seg_ptr[rw + 1]):
                k = seg_idx[q]
                k1 = k + 1 if k + 1 < n_pts else 0
                x0, y0 = node_pts[a, k, 0] - px[p], node_pts[a, k, 1] - py[p]
                x1, y1 = node_pts[a, k1, 0] - px[p], node_pts[a, k1, 1] - py[p]
                sa += _segment_integral(dens, row_cum, row_mass, mass_cum, lo[p], lam[p], x0, y0, x1, y1, r, h, n,
                                        buf)
            acc += node_w[p, a] * sa
        out[p] = orient * acc
    return out


@njit(cache=True, parallel=True)
def _inside_polyline(poly, x, y):
    """Points (x, y) px inside the closed polyline ``poly`` (N, 2): even-odd crossings of the ray to
    +x, each chord half-open in y (a ray through a vertex counts it once)."""
    n = poly.shape[0]
    out = np.zeros(x.shape[0], np.bool_)
    for p in prange(x.shape[0]):
        inside = False
        for k in range(n):
            k1 = k + 1 if k + 1 < n else 0
            ya, yb = poly[k, 1], poly[k1, 1]
            if (ya <= y[p]) != (yb <= y[p]):
                xc = poly[k, 0] + (y[p] - ya) * (poly[k1, 0] - poly[k, 0]) / (yb - ya)
                if xc > x[p]:
                    inside = not inside
        out[p] = inside
    return out


def outline_curve(camera, pose, target: str, size_m: float):
    """The exact outline (``OutlineCurve``) of target ``target`` (T1..T4) at ``pose``."""
    from edgetruth.render.scene.outline import OutlineCurve
    from edgetruth.render.scene.targets import TARGETS

    return OutlineCurve(camera, pose, TARGETS[target]["shape"], float(size_m))


def outline_points(curve, step_px: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(camera-frame points (N, 3) m, distorted pinhole pixels (N, 2)) of a dense closed polyline on
    the curve: corners kept, circles spaced so the chords stay within ``CHORD_TOLERANCE_PX``."""
    if step_px is None:
        step_px = 2.0
        if curve.shape not in ("square", "polygon"):
            ring = curve.points(np.linspace(0.0, 1.0, 64, endpoint=False))
            r_px = 0.5 * float(np.min(np.ptp(ring, axis=0)))
            step_px = min(2.0, 0.8 * math.sqrt(8.0 * CHORD_TOLERANCE_PX * max(r_px, 1.0)))
    t = curve.parameters(step_px)
    cam = curve.pose.to_camera(curve.local(t))
    return cam, curve.camera.project(cam, distorted=True)


def pixel_coverage(camera, curve, x_px, y_px, n_r: int | None = None, n_phi: int | None = None,
                   step_px: float | None = None) -> np.ndarray:
    """Lens-weighted coverage c ∈ [0, 1] of the target inside ``curve`` (an ``OutlineCurve``) for
    pixels centred at (``x_px``, ``y_px``) (OpenCV px): the share of each pixel's weighted rays that
    land inside.  ``n_r``, ``n_phi``: the aperture rule (default: from the defocus; pixels farther
    than the defocus radius + ``FAR_MARGIN_PX`` from the outline use ``FAR_RULE``)."""
    from edgetruth.render.edge_truth import closed_polyline_signed_distance

    if camera.moving:
        raise ValueError("pixel_coverage: a moving camera's outline sweeps; use the path-traced band")
    shape = np.shape(x_px)
    xs, ys = np.ravel(np.asarray(x_px, float)), np.ravel(np.asarray(y_px, float))
    tab = kernel_tables(camera)
    cam_pts, pin_px = outline_points(curve, step_px)
    r_m, zf = camera.aperture_radius_m, camera.focus_distance_m
    c_depth = 1.0 / cam_pts[:, 2] - 1.0 / zf
    defocus_px = float(np.max(np.abs(c_depth))) * camera.fx_px * r_m if r_m > 0 else 0.0
    reach = tab.half_width_px * math.sqrt(2.0) + defocus_px * 1.01 + 1e-6
    # |d| only: its sign comes from the nearest chord, which is ambiguous off a corner (both chords
    # nearest at the shared vertex; on the extension of a side that chord's cross product is ~0 and
    # says "inside" for points just across its line).  Outside the kernel's reach, c is the exact
    # point-in-polygon test of the pixel centre.
    d = np.abs(closed_polyline_signed_distance(pin_px, xs, ys))
    out = _inside_polyline(np.ascontiguousarray(pin_px, dtype=np.float64), xs, ys).astype(float)
    near = d <= reach + 0.5
    nodes = aperture_nodes(defocus_px, n_r, n_phi, smooth=tab.half_width_px > 0.5)
    # (pixels, [(table, aperture rule), ...]): the coverage is linear in the kernel
    parts = [(near, [(tab, nodes)])]
    if len(nodes[0]) > len(FAR_RULE[0]) and n_r is None:
        from edgetruth.render.optics.psf import psf_params

        far = near & (d > defocus_px + FAR_MARGIN_PX)
        split = split_tables(psf_params(camera))
        parts = [(near & ~far, [(tab, nodes)] if split is None else [(split[0], nodes), (split[1], TAIL_RULE)]),
                 (far, [(tab, FAR_RULE)])]
    for mask, plan in parts:
        idx = np.flatnonzero(mask)
        if len(idx):
            out[idx] = sum(_coverage_with(camera, t, cam_pts, pin_px, c_depth, defocus_px, xs[idx], ys[idx], rule)
                           for t, rule in plan)
    return np.clip(out, 0.0, 1.0).reshape(shape)


def _coverage_with(camera, tab: KernelTables, cam_pts, pin_px, c_depth, defocus_px, xn, yn, nodes) -> np.ndarray:
    """The coverage of pixels (xn, yn) with the aperture rule ``nodes`` (ux, uy, w on the unit disk)."""
    ux, uy, uw = nodes
    r_m, f_m = camera.aperture_radius_m, camera.focal_length_m
    # the outline seen from each aperture node A: distort(P_xy / P_z − c A), exactly
    z = cam_pts[:, 2]
    xu, yu = cam_pts[:, 0] / z, cam_pts[:, 1] / z
    nx = xu[None, :] - c_depth[None, :] * (ux * r_m)[:, None]
    ny = yu[None, :] - c_depth[None, :] * (uy * r_m)[:, None]
    proj = camera.project(np.column_stack([nx.ravel(), ny.ravel(), np.ones(nx.size)]), distorted=True)
    node_pts = np.ascontiguousarray(proj.reshape(len(ux), len(xu), 2))
    # per pixel: the plugin's ray weight at the pixel centre times the node's area weight
    cx, cy = camera.principal_point_px
    if camera.natural_vignetting and r_m > 0:
        from edgetruth.render.optics.optical_edge import lens_weight

        rho = r_m / f_m
        bx, by = (xn - cx) / camera.fx_px, (yn - cy) / camera.fy_px
        w = uw[None, :] * lens_weight(ux[None, :] * rho, uy[None, :] * rho, bx[:, None], by[:, None], rho)
    else:
        w = np.broadcast_to(uw[None, :], (len(xn), len(uw)))
    w = np.ascontiguousarray(w / w.sum(axis=1, keepdims=True))
    # per pixel row: the segments (of any node: padded by the defocus) that meet the kernel's rows
    row0 = int(math.floor(yn.min()))
    rows = np.floor(yn).astype(np.int64) - row0
    n_rows = int(rows.max()) + 1
    y_a, y_b = pin_px[:, 1], np.roll(pin_px[:, 1], -1)
    pad = tab.half_width_px + defocus_px * 1.01 + 1.0
    r_lo = np.clip(np.floor(np.minimum(y_a, y_b) - pad).astype(np.int64) - row0, 0, n_rows)
    r_hi = np.clip(np.ceil(np.maximum(y_a, y_b) + pad).astype(np.int64) - row0 + 1, 0, n_rows)
    counts = np.maximum(r_hi - r_lo, 0)
    seg = np.repeat(np.arange(len(pin_px)), counts)
    rr = np.repeat(r_lo, counts) + (np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts))
    order = np.argsort(rr, kind="stable")
    idx = seg[order].astype(np.int64)
    ptr = np.zeros(n_rows + 1, np.int64)
    ptr[1:] = np.cumsum(np.bincount(rr, minlength=n_rows))
    area2 = float(np.sum(pin_px[:, 0] * np.roll(pin_px[:, 1], -1) - np.roll(pin_px[:, 0], -1) * pin_px[:, 1]))
    lo, lam = level_mix(tab, camera, xn, yn)
    return _coverage_kernel(xn, yn, rows, lo, lam, node_pts, w, ptr, idx, 1.0 if area2 > 0 else -1.0,
                            tab.density, tab.row_cum, tab.row_mass, tab.mass_cum, tab.half_width_px, tab.step_px)
