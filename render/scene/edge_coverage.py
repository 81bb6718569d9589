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
- **Evaluation**: on integer pixel centres (1/h an integer, as in every shipped table) all pixels'
  table grids are one global grid, so each node's outline is split once and each piece reduced to six
  moments; a pixel sums table coefficients times moments over the pieces within its kernel (the same
  exact integral, 2-9x cheaper than splitting per pixel: docs/optics.md).  Other pixel sets, or
  ``reference=True``, split per pixel.

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


@njit(cache=True, forceinline=True)
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


@njit(cache=True, forceinline=True)
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


@njit(cache=True)  # cheap beside the coverage: serial compiles in a fraction of the time
def _inside_kernel(poly, x, y, row, ptr, idx):
    """Even-odd crossings of the ray to +x from each point, over the chords of the point's row list."""
    n = poly.shape[0]
    out = np.zeros(x.shape[0], np.bool_)
    for p in range(x.shape[0]):
        inside = False
        for q in range(ptr[row[p]], ptr[row[p] + 1]):
            k = idx[q]
            k1 = k + 1 if k + 1 < n else 0
            ya, yb = poly[k, 1], poly[k1, 1]
            if (ya <= y[p]) != (yb <= y[p]):
                xc = poly[k, 0] + (y[p] - ya) * (poly[k1, 0] - poly[k, 0]) / (yb - ya)
                if xc > x[p]:
                    inside = not inside
        out[p] = inside
    return out


def _inside_polyline(poly: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Points (x, y) px inside the closed polyline ``poly`` (N, 2): even-odd crossings of the ray to
    +x, each chord half-open in y (a ray through a vertex counts it once).  Only the chords whose
    y-range meets a point's unit row [floor(y), floor(y) + 1) can cross its ray: each point tests those."""
    if not len(x):
        return np.zeros(0, bool)
    row0 = int(math.floor(y.min()))
    rows = np.floor(y).astype(np.int64) - row0
    n_rows = int(rows.max()) + 1
    ya, yb = poly[:, 1], np.roll(poly[:, 1], -1)
    r_lo = np.clip(np.floor(np.minimum(ya, yb)).astype(np.int64) - row0, 0, n_rows)
    r_hi = np.clip(np.floor(np.maximum(ya, yb)).astype(np.int64) - row0 + 1, 0, n_rows)
    ptr, idx = _row_lists(r_lo, r_hi, n_rows)
    return _inside_kernel(poly, x, y, rows, ptr, idx)


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
                   step_px: float | None = None, reference: bool = False) -> np.ndarray:
    """Lens-weighted coverage c ∈ [0, 1] of the target inside ``curve`` (an ``OutlineCurve``) for
    pixels centred at (``x_px``, ``y_px``) (OpenCV px): the share of each pixel's weighted rays that
    land inside.  ``n_r``, ``n_phi``: the aperture rule (default: from the defocus; pixels farther
    than the defocus radius + ``FAR_MARGIN_PX`` from the outline use ``FAR_RULE``).  ``reference``: the
    per-pixel segment split everywhere (the aligned evaluation's check; same values to rounding)."""
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
            out[idx] = sum(_coverage_with(camera, t, cam_pts, pin_px, c_depth, defocus_px, xs[idx], ys[idx], rule,
                                          reference) for t, rule in plan)
    return np.clip(out, 0.0, 1.0).reshape(shape)


def _coverage_with(camera, tab: KernelTables, cam_pts, pin_px, c_depth, defocus_px, xn, yn, nodes,
                   reference: bool = False) -> np.ndarray:
    """The coverage of pixels (xn, yn) with the aperture rule ``nodes`` (ux, uy, w on the unit disk);
    ``reference``: split each segment per pixel (``_segment_integral``) even where the grids align."""
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
    area2 = float(np.sum(pin_px[:, 0] * np.roll(pin_px[:, 1], -1) - np.roll(pin_px[:, 0], -1) * pin_px[:, 1]))
    lo, lam = level_mix(tab, camera, xn, yn)
    orient = 1.0 if area2 > 0 else -1.0
    grid = None if reference else _aligned_grid(xn, yn, tab)
    if grid is None:
        ptr, idx = _row_lists(r_lo, r_hi, n_rows)
        return _coverage_kernel(xn, yn, rows, lo, lam, node_pts, w, ptr, idx, orient, tab.density, tab.row_cum,
                                tab.row_mass, tab.mass_cum, tab.half_width_px, tab.step_px)
    pi, pj, x_org, y_org = grid
    h = tab.step_px
    counts = _piece_counts(node_pts, x_org, y_org, h).reshape(node_pts.shape[0], -1)
    # chunks of CHUNK_SEGMENTS consecutive segments: their boxes per node, their rows (padded as above)
    n_pts = len(pin_px)
    first = np.arange(0, n_pts, CHUNK_SEGMENTS)
    end = np.minimum(first + CHUNK_SEGMENTS, n_pts)
    verts = np.minimum(first[:, None] + np.arange(CHUNK_SEGMENTS + 1)[None, :], end[:, None]) % n_pts
    seg = np.ascontiguousarray(np.column_stack([first, end, end % n_pts]).astype(np.int64))
    cy = pin_px[verts, 1]
    c_lo = np.clip(np.floor(cy.min(1) - pad).astype(np.int64) - row0, 0, n_rows)
    c_hi = np.clip(np.ceil(cy.max(1) + pad).astype(np.int64) - row0 + 1, 0, n_rows)
    c_ptr, c_idx = _row_lists(c_lo, c_hi, n_rows)
    coef = _g_coef(tab)
    # the nodes in batches of at most MAX_PIECES pieces (memory: 64 bytes a piece); c is linear in them
    per_node = counts.sum(axis=1)
    batch = np.cumsum(per_node) // MAX_PIECES
    out = np.zeros(len(xn))
    for b in np.unique(batch):
        sel = np.flatnonzero(batch == b)
        pts = np.ascontiguousarray(node_pts[sel])
        pieces = np.zeros(pts.shape[0] * pts.shape[1] + 1, np.int64)
        pieces[1:] = np.cumsum(counts[sel].ravel())
        cell_i, cell_j = np.empty(pieces[-1], np.int64), np.empty(pieces[-1], np.int64)
        mom = np.empty((pieces[-1], 6))
        _piece_moments(pts, x_org, y_org, h, pieces, cell_i, cell_j, mom)
        cpts = pts[:, verts, :]  # (nodes, chunks, C + 1, 2)
        box = np.ascontiguousarray(np.stack([cpts[..., 0].min(2), cpts[..., 0].max(2), cpts[..., 1].min(2),
                                             cpts[..., 1].max(2)], axis=2))
        out += _coverage_kernel_aligned(xn, yn, pi, pj, rows, lo, lam, pts, np.ascontiguousarray(w[:, sel]), c_ptr,
                                        c_idx, box, seg, orient, coef, tab.row_mass, tab.mass_cum, tab.half_width_px,
                                        h, pieces, cell_i, cell_j, mom)
    return out


#: the aligned evaluation's pieces held at once (~64 bytes each): more aperture nodes go in batches
MAX_PIECES = 4_000_000
#: the aligned evaluation takes the outline in chunks of this many segments: a chunk clear of a pixel's
#: kernel costs one test (and, right of it, two mass look-ups) per node instead of one per segment
CHUNK_SEGMENTS = 16


def _row_lists(r_lo: np.ndarray, r_hi: np.ndarray, n_rows: int) -> tuple[np.ndarray, np.ndarray]:
    """CSR lists (ptr, items) of the items meeting each row: item k spans rows [r_lo[k], r_hi[k])."""
    counts = np.maximum(r_hi - r_lo, 0)
    item = np.repeat(np.arange(len(r_lo)), counts)
    rr = np.repeat(r_lo, counts) + (np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts))
    order = np.argsort(rr, kind="stable")
    ptr = np.zeros(n_rows + 1, np.int64)
    ptr[1:] = np.cumsum(np.bincount(rr, minlength=n_rows))
    return ptr, item[order].astype(np.int64)


_COEF: dict = {}


def _g_coef(tab: KernelTables) -> np.ndarray:
    """``g_coefficients`` of ``tab``, kept per table (the tables themselves are cached per camera)."""
    hit = _COEF.get(id(tab))
    if hit is None or hit[0] is not tab:
        if len(_COEF) > 32:
            _COEF.clear()
        hit = _COEF[id(tab)] = (tab, g_coefficients(tab))
    return hit[1]


def _aligned_grid(xn, yn, tab: KernelTables):
    """(pi, pj, x_org, y_org) when every pixel's table grid lies on one global grid x_org + k h,
    y_org + k h (pixel offsets whole multiples of the step h), pixel p's table column 0 being global
    column pi[p]; None otherwise."""
    h, r = tab.step_px, tab.half_width_px
    x_org, y_org = float(xn.min()) - r, float(yn.min()) - r
    fi, fj = (xn - r - x_org) / h, (yn - r - y_org) / h
    pi, pj = np.rint(fi), np.rint(fj)
    if np.max(np.abs(fi - pi), initial=0.0) > 1e-9 or np.max(np.abs(fj - pj), initial=0.0) > 1e-9:
        return None
    return pi.astype(np.int64), pj.astype(np.int64), x_org, y_org


# --- the aligned evaluation: one split of the outline per node, shared by every pixel ----------------
#
# When the pixels' offsets are whole multiples of the table step (integer pixel centres, 1/h an integer:
# every shipped PSF table has h = 1/4, the box alone h = 1), the table's grid lines of every pixel are
# the same lines of one global grid.  Each node's outline is then split at those lines once, each piece
# reduced to six moments of (u, v), its position in its global cell; a pixel's ∮ G dy becomes a sum
# over the pieces within its kernel of six table coefficients times the moments -- the same exact
# piecewise-polynomial integral as ``_segment_integral``, without re-splitting and sorting per pixel.


def g_coefficients(tab: KernelTables) -> np.ndarray:
    """(n-1, n, L, 6): G of level L on table cell (row j, column i) as c·(1, v, u, uv, u², u²v), u, v ∈
    [0, 1] the position in the cell; column n-1 is everything right of the table (G = the rows' mass,
    blended).  A cell's levels lie side by side: a pixel mixes two neighbours."""
    d, rc, m, h = tab.density, tab.row_cum, tab.row_mass, tab.step_px
    n_lev, n = d.shape[0], d.shape[1]
    c = np.zeros((n_lev, n - 1, n, 6))
    a0, a1, b0, b1 = d[:, :-1, :-1], d[:, :-1, 1:], d[:, 1:, :-1], d[:, 1:, 1:]
    c[:, :, :-1, 0] = rc[:, :-1, :-1]
    c[:, :, :-1, 1] = rc[:, 1:, :-1] - rc[:, :-1, :-1]
    c[:, :, :-1, 2] = h * a0
    c[:, :, :-1, 3] = h * (b0 - a0)
    c[:, :, :-1, 4] = 0.5 * h * (a1 - a0)
    c[:, :, :-1, 5] = 0.5 * h * ((b1 - b0) - (a1 - a0))
    c[:, :, -1, 0] = m[:, :-1]
    c[:, :, -1, 1] = m[:, 1:] - m[:, :-1]
    return np.ascontiguousarray(c.transpose(1, 2, 0, 3))


@njit(cache=True)  # cheap beside the coverage: serial compiles in a fraction of the time
def _piece_counts(node_pts, x_org, y_org, h):
    """Pieces per (node, segment): the segment split at the global grid lines x_org + k h, y_org + k h
    (0 for a horizontal segment: it adds nothing to ∮ G dy)."""
    n_nodes, n_pts = node_pts.shape[0], node_pts.shape[1]
    out = np.zeros(n_nodes * n_pts, np.int64)
    for a in range(n_nodes):
        for k in range(n_pts):
            k1 = k + 1 if k + 1 < n_pts else 0
            y0, y1 = node_pts[a, k, 1], node_pts[a, k1, 1]
            if y0 == y1:
                continue
            x0, x1 = node_pts[a, k, 0], node_pts[a, k1, 0]
            m = 1
            for g0, g1 in (((x0 - x_org) / h, (x1 - x_org) / h), ((y0 - y_org) / h, (y1 - y_org) / h)):
                if g1 != g0:
                    m += max(0, int(math.floor(max(g0, g1))) - int(math.ceil(min(g0, g1))) + 1)
            out[a * n_pts + k] = m
    return out


@njit(cache=True)  # cheap beside the coverage: serial compiles in a fraction of the time
def _piece_moments(node_pts, x_org, y_org, h, ptr, cell_i, cell_j, mom):
    """Fill each piece's global cell (``cell_i``, ``cell_j``) and its moments ∫ (1, v, u, uv, u², u²v) dy
    (2-point Gauss–Legendre: exact, the integrand is a cubic in the segment's parameter)."""
    n_nodes, n_pts = node_pts.shape[0], node_pts.shape[1]
    g = 0.5 / math.sqrt(3.0)
    for a in range(n_nodes):
        buf = np.empty(64)
        for k in range(n_pts):
            q0, q1 = ptr[a * n_pts + k], ptr[a * n_pts + k + 1]
            if q1 == q0:
                continue
            k1 = k + 1 if k + 1 < n_pts else 0
            x0, y0 = node_pts[a, k, 0], node_pts[a, k, 1]
            dx, dy = node_pts[a, k1, 0] - x0, node_pts[a, k1, 1] - y0
            if q1 - q0 + 1 > buf.shape[0]:
                buf = np.empty(2 * (q1 - q0 + 1))
            m = 0
            buf[m] = 0.0
            m += 1
            for axis in range(2):  # the crossings, with the same arithmetic as ``_piece_counts``
                g0 = (x0 - x_org) / h if axis == 0 else (y0 - y_org) / h
                g1 = (node_pts[a, k1, 0] - x_org) / h if axis == 0 else (node_pts[a, k1, 1] - y_org) / h
                if g1 != g0:
                    for kk in range(int(math.ceil(min(g0, g1))), int(math.floor(max(g0, g1))) + 1):
                        t = (kk - g0) / (g1 - g0)
                        if 0.0 < t < 1.0 and m < q1 - q0:
                            buf[m] = t
                            m += 1
            buf[m] = 1.0
            m += 1
            for b in range(1, m):  # insertion sort: the two axes' crossings, each list already sorted
                t = buf[b]
                c = b - 1
                while c >= 0 and buf[c] > t:
                    buf[c + 1] = buf[c]
                    c -= 1
                buf[c + 1] = t
            q = q0
            for b in range(m - 1):
                ta, tb = buf[b], buf[b + 1]
                tm, ln = 0.5 * (ta + tb), tb - ta
                gi = math.floor((x0 + tm * dx - x_org) / h)
                gj = math.floor((y0 + tm * dy - y_org) / h)
                s = 0.5 * ln * dy
                m1 = mv = mu = muv = muu = muuv = 0.0
                if ln > 0.0:
                    for t in (tm - g * ln, tm + g * ln):
                        u = (x0 + t * dx - x_org) / h - gi
                        v = (y0 + t * dy - y_org) / h - gj
                        m1 += 1.0
                        mv += v
                        mu += u
                        muv += u * v
                        muu += u * u
                        muuv += u * u * v
                cell_i[q], cell_j[q] = gi, gj
                mom[q, 0], mom[q, 1], mom[q, 2] = s * m1, s * mv, s * mu
                mom[q, 3], mom[q, 4], mom[q, 5] = s * muv, s * muu, s * muuv
                q += 1
            while q < q1:  # fewer pieces than counted (a crossing at t = 0 or 1): empty ones
                cell_i[q], cell_j[q] = 0, -1
                mom[q, :] = 0.0
                q += 1
    return 0


@njit(cache=True, parallel=True)
def _coverage_kernel_aligned(px, py, pi, pj, row, lo, lam, node_pts, node_w, chunk_ptr, chunk_idx, chunk_box, chunk_seg,
                             orient, coef, row_mass, mass_cum, r, h, ptr, cell_i, cell_j, mom):
    """``_coverage_kernel`` on pre-split pieces: pixel p's table cell of global cell (I, J) is
    (I − pi[p], J − pj[p]).  The outline comes in chunks of consecutive segments (``chunk_seg``: first
    segment, end, end vertex; ``chunk_box``: per node x/y min/max); a chunk left of, above or below the
    kernel adds nothing, one right of it ∫ M dy, which telescopes to its end vertices."""
    n = row_mass.shape[1]
    n_pix = px.shape[0]
    n_nodes, n_pts = node_pts.shape[0], node_pts.shape[1]
    out = np.zeros(n_pix)
    for p in prange(n_pix):
        acc = 0.0
        rw, lv, lm = row[p], lo[p], lam[p]
        for a in range(n_nodes):
            s = 0.0
            for q in range(chunk_ptr[rw], chunk_ptr[rw + 1]):
                c = chunk_idx[q]
                if (chunk_box[a, c, 1] - px[p] <= -r or chunk_box[a, c, 2] - py[p] >= r
                        or chunk_box[a, c, 3] - py[p] <= -r):
                    continue
                if chunk_box[a, c, 0] - px[p] >= r:
                    s += _mass_span(row_mass, mass_cum, lv, lm, node_pts[a, chunk_seg[c, 0], 1] - py[p],
                                    node_pts[a, chunk_seg[c, 2], 1] - py[p], r, h, n)
                    continue
                for k in range(chunk_seg[c, 0], chunk_seg[c, 1]):
                    k1 = k + 1 if k + 1 < n_pts else 0
                    x0, y0 = node_pts[a, k, 0] - px[p], node_pts[a, k, 1] - py[p]
                    x1, y1 = node_pts[a, k1, 0] - px[p], node_pts[a, k1, 1] - py[p]
                    if (y0 <= -r and y1 <= -r) or (y0 >= r and y1 >= r) or (x0 <= -r and x1 <= -r) or y0 == y1:
                        continue
                    if x0 >= r and x1 >= r:
                        s += _mass_span(row_mass, mass_cum, lv, lm, y0, y1, r, h, n)
                    else:
                        base = a * n_pts + k
                        s += _pieces_sum(coef, lv, lm, pi[p], pj[p], cell_i, cell_j, mom, ptr[base], ptr[base + 1], n)
            acc += node_w[p, a] * s
        out[p] = orient * acc
    return out


@njit(cache=True)
def _mass_span(row_mass, mass_cum, lv, lm, y0, y1, r, h, n):
    """∫ M dy from y0 to y1 (kernel rows) for the kernel (1 − lm) K_lv + lm K_{lv+1}."""
    s = _mass_below(row_mass, mass_cum, lv, y1, r, h, n) - _mass_below(row_mass, mass_cum, lv, y0, r, h, n)
    if lm != 0.0:
        s1 = _mass_below(row_mass, mass_cum, lv + 1, y1, r, h, n) - _mass_below(row_mass, mass_cum, lv + 1, y0, r, h, n)
        s = (1.0 - lm) * s + lm * s1
    return s


@njit(cache=True)
def _pieces_sum(coef, lv, lm, pi, pj, cell_i, cell_j, mom, e0, e1, n):
    """Σ over pieces e0..e1 of their moments times the coefficients of their cell in the pixel's table
    (global cell (I, J) is table cell (I − pi, J − pj)), for the kernel (1 − lm) K_lv + lm K_{lv+1}."""
    sa = 0.0
    sb = 0.0
    for e in range(e0, e1):
        j = cell_j[e] - pj
        if j < 0 or j > n - 2:
            continue
        i = cell_i[e] - pi
        if i < 0:
            continue
        if i > n - 1:
            i = n - 1
        for m in range(6):
            sa += coef[j, i, lv, m] * mom[e, m]
        if lm != 0.0:
            for m in range(6):
                sb += coef[j, i, lv + 1, m] * mom[e, m]
    return (1.0 - lm) * sa + lm * sb
