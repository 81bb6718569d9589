"""The exact per-point Cramér–Rao bound of the render tables, per method over its own footprint.

For each scored candidate p of a rendered target image and each method, the bound on the standard
deviation of any (locally) unbiased estimate of ρ = d(p) -- the quantity every per-point error
measures -- from exactly the pixels the method reads (its declared footprint,
``edgetruth.locate.footprints``), under the expected image the render has
(``edgetruth.evaluate.bound_psf``, docs/bound.md "On renders: the exact bound"):

- **PSF**: the camera's, from the image's JSON: Airy(λ, N) ⊗ Gaussian aberration σ(h) (σx, σy) ⊗
  defocus disk (the target's radius) ⊗ 4-dot OLPF, box-integrated over the pixel.  h is *the point's*
  field height; points are grouped into bins of σ(h) 4 % wide (the bin's centre σ is used: < 0.2 % on
  the bound), and the tables of equal optics are shared between images (the paired design renders
  one pose at every SNR level and target).
- **Edge**: the exact distorted outline of the JSON: the distance ρ and the normal direction φ at p
  from the nearest chord; a smooth outline's (circle, ellipse) local radius of curvature and normal
  from the circle through the polyline vertices two either side of the nearest (a polygon's sides as
  straight lines).
- **Levels** A (dark side) and B (contrast) per point: a least-squares fit of the noise-free DN
  (the EXR radiance through the sensor's gain: offset + K·η·photons·radiance) to A + B·M over the
  point's footprint pixels -- the local shading on both sides.
- **Noise**: EMVA 1288, K²(σd² + μe) + 1/12 DN², plus the fixed-pattern noise the JSON declares
  (DSNU, PRNU: per pixel independent, unknown to a method).  The renderer's Monte-Carlo noise is left
  out (measured at 0.07–0.38 of the temporal noise on edge pixels, tests/render/test_mc_noise.py):
  less noise, a smaller bound, so still a bound.
- **Unknowns** (ρ, φ, A, B, λ): position, normal, the two levels and the PSF's scale (patch_esf_fit is given
  the PSF's tables, ``esf_for_points``, and still fits its scale; a method told the scale, ``psf_sigma_px`` or
  patch_esf_fit's ``blur_known``, gets the bound with λ known).
"""
from __future__ import annotations

import math
from collections import OrderedDict

import numpy as np
from scipy.spatial import cKDTree

from edgetruth.render.optics import mtf


ANGLE_STEP_DEG = 1.0  # table bins of the normal's direction: < 4e-5 on the bound against 0.25 deg
FFT_LEN = 1 << 12  # 64 px period on the 1/64-px grid: < 6e-5 on the bound against 1 << 16 (512 px)
SIGMA_BIN_REL = 0.04  # field-height bins 4 % wide in the aberration sigma: < 0.2 % on the bound
_CACHE: OrderedDict = OrderedDict()
_CACHE_SIZE = 12


def optics_at(gt: dict, field_h: float):
    """``bound_psf.Optics`` of the image's camera at field height ``field_h`` (JSON keys only)."""
    from edgetruth.evaluate.bound_psf import Optics  # lazy: bound_psf loads numba
    cam = gt["camera"]
    psf = cam.get("optics", {}).get("psf", {})
    p = float(cam["pitch_um"])
    g = 1.0 + float(psf.get("aberration_sigma_growth", 0.0)) * field_h ** 2
    sx = float(psf.get("aberration_sigma_um", 0.0))
    sy = psf.get("aberration_sigma_y_um")
    sy = sx if sy is None else float(sy)
    r_def = float(gt.get("optics_at_target", {}).get("defocus_radius_px", gt.get("defocus_radius_px", 0.0)))
    cutoff = psf.get("diffraction_cutoff_cy_px")  # the renderer's own (an effective wavelength included)
    if cutoff is None:
        cutoff = mtf.diffraction_cutoff_cy_px(p, float(psf.get("diffraction_wavelength_nm", 0.0)),
                                              float(cam.get("f_number", 0.0)))
    cutoff = float(cutoff) if cutoff is not None and float(cutoff) > 0 else math.inf
    return Optics(cutoff, sx / p * g, sy / p * g, r_def, float(psf.get("olpf_split_um", 0.0)) / p)


def field_heights(gt: dict, x, y) -> np.ndarray:
    """Normalised field height of image points (as ``render.optics.field_height``, from the JSON)."""
    cam = gt["camera"]
    half = math.hypot(float(cam["width_px"]) / 2.0, float(cam["height_px"]) / 2.0)
    return np.hypot(np.asarray(x, float) - float(cam["cx_px"]), np.asarray(y, float) - float(cam["cy_px"])) / half


def spread_for(optics):
    """The ``EdgeSpread`` of ``optics`` (tables kept for the next images with the same optics)."""
    from edgetruth.evaluate.bound_psf import EdgeSpread  # lazy: bound_psf loads numba

    key = tuple(round(float(v), 9) for v in (optics.cutoff_cy_px if math.isfinite(optics.cutoff_cy_px) else -1,
                                              optics.sigma_x_px, optics.sigma_y_px, optics.defocus_px,
                                              optics.olpf_px))
    sp = _CACHE.get(key)
    if sp is None:
        sp = EdgeSpread(optics, 1.0, FFT_LEN, ANGLE_STEP_DEG)
        _CACHE[key] = sp
        while len(_CACHE) > _CACHE_SIZE:
            _CACHE.popitem(last=False)
    else:
        _CACHE.move_to_end(key)
    return sp


def field_bins(gt: dict, x, y) -> tuple[list, np.ndarray]:
    """(``EdgeSpread`` per field-height bin, (N,) bin index) of image points (x, y) in full-image pixel
    coordinates: bins of the aberration σ(h) 4 % wide (``SIGMA_BIN_REL``), each with the optics at its
    centre.  One rule for the bound (``point_bounds``) and the locator patch_esf_fit (``esf_for_points``)."""
    h = field_heights(gt, x, y)
    growth = float(gt["camera"].get("optics", {}).get("psf", {}).get("aberration_sigma_growth", 0.0))
    key = np.round(np.log1p(growth * h * h) / SIGMA_BIN_REL).astype(np.int64)
    keys, bin_of = np.unique(key, return_inverse=True)
    spreads = []
    for kb in keys:
        hb = math.sqrt(max(math.expm1(kb * SIGMA_BIN_REL), 0.0) / growth) if growth else 0.0
        spreads.append(spread_for(optics_at(gt, hb)))
    return spreads, bin_of.reshape(-1).astype(np.int64)


def esf_for_points(gt: dict, x, y) -> tuple[list, np.ndarray]:
    """The camera's edge-spread tables for the locator patch_esf_fit at image points (x, y), full-image
    pixel coordinates: (list of ``locate.esf_tables.EsfTables``, one per field-height bin, every angle
    row built; (N,) bin index per point) -- its ``esf`` and ``bin_index`` options, binned as the bound."""
    spreads, bin_of = field_bins(gt, x, y)
    return [sp.tables() for sp in spreads], bin_of


def outline_geometry(truth, x, y) -> dict:
    """``crb.edge_geometry`` of the JSON's outline (``render.edge_truth.OutlineEdge``) at pixel centres:
    ρ, the normal φ towards the bright board (> 0 side) from the nearest chord, and for a smooth outline
    (no corners: a circle, an ellipse) the local radius of curvature and the normal at the point from the
    circle through the vertices two either side of the nearest."""
    poly = np.asarray(truth.polyline_px, float)
    q = np.column_stack([np.ravel(x), np.ravel(y)]).astype(float)
    n, nv = len(q), len(poly)
    rho = truth.signed_distance(q[:, 0], q[:, 1]) if n else np.zeros(0)
    _, i = cKDTree(poly).query(q) if n else (None, np.zeros(0, np.int64))
    best = np.full(n, np.inf)
    tang = np.zeros((n, 2))
    for j0 in (i - 2, i - 1, i, i + 1):
        a, b = poly[j0 % nv], poly[(j0 + 1) % nv]
        d = b - a
        u = np.clip(((q - a) * d).sum(1) / np.maximum((d * d).sum(1), 1e-300), 0.0, 1.0)
        dist = np.linalg.norm(q - (a + u[:, None] * d), axis=1)
        take = dist < best
        best[take] = dist[take]
        tang[take] = d[take]
    tang /= np.maximum(np.linalg.norm(tang, axis=1, keepdims=True), 1e-300)
    nrm = np.column_stack([tang[:, 1], -tang[:, 0]])
    # orient towards the bright side: a step along the normal increases the signed distance
    probe = truth.signed_distance(q[:, 0] + 0.25 * nrm[:, 0], q[:, 1] + 0.25 * nrm[:, 1]) if n else rho
    nrm *= np.where(probe >= rho, 1.0, -1.0)[:, None]
    out = {"kind": np.zeros(n, np.int64), "rho": np.asarray(rho, float), "phi": np.arctan2(nrm[:, 1], nrm[:, 0]),
           "radius": np.zeros(n), "sgn": np.ones(n)}
    # a smooth outline (circle, ellipse: no corners) bends; a polygon's sides are straight
    smooth = getattr(truth, "corners_px", None) is None and getattr(truth, "shape", "") != "square"
    if smooth and n:
        p0, p1, p2 = poly[(i - 2) % nv], poly[i % nv], poly[(i + 2) % nv]
        a, b, c = np.linalg.norm(p1 - p0, axis=1), np.linalg.norm(p2 - p1, axis=1), np.linalg.norm(p2 - p0, axis=1)
        cross = (p1 - p0)[:, 0] * (p2 - p0)[:, 1] - (p1 - p0)[:, 1] * (p2 - p0)[:, 0]
        radius = a * b * c / np.maximum(2.0 * np.abs(cross), 1e-300)
        # the centre of curvature lies on the dark side (target inside) or the bright side
        centre_dir = (p0 + p2) / 2.0 - p1  # towards the centre of curvature
        bright_inside = (centre_dir * nrm).sum(1) > 0
        ok = np.isfinite(radius) & (radius < 1e6)
        # the normal at p itself: along the line from the circumcentre (exact on a circle; the nearest
        # chord's normal is off by half the chord's turn)
        e1, e2 = p0 - p1, p2 - p1
        den = 2.0 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
        den = np.where(np.abs(den) > 1e-300, den, np.nan)
        n1, n2 = (e1 * e1).sum(1), (e2 * e2).sum(1)
        cc = p1 + np.column_stack([(e2[:, 1] * n1 - e1[:, 1] * n2) / den, (e1[:, 0] * n2 - e2[:, 0] * n1) / den])
        v = q - cc
        v *= np.where((v * nrm).sum(1) >= 0, 1.0, -1.0)[:, None]
        ok &= np.all(np.isfinite(v), axis=1)
        phi_c = np.arctan2(v[:, 1], v[:, 0])
        out["phi"] = np.where(ok, phi_c, out["phi"])
        out["kind"] = np.where(ok, 1, 0).astype(np.int64)
        out["radius"] = np.where(ok, radius, 0.0)
        out["sgn"] = np.where(bright_inside, 1.0, -1.0)
    return out


def sensor_variance(gt: dict):
    """The pixel variance (DN²) as a function of its mean DN: EMVA 1288 temporal noise, plus DSNU and
    PRNU where the JSON's sensor declares them."""
    s = gt["sensor"]
    K = float(s["gain_dn_per_e"])
    sd = float(s.get("dark_noise_e", 0.0))
    off = float(s.get("dark_offset_dn", gt.get("image", {}).get("black_level_dn", 0.0)))
    dsnu = float(s.get("dsnu_e", 0.0))
    prnu = float(s.get("prnu_pct", 0.0)) / 100.0

    def fn(mean_dn):
        mu_e = np.maximum(np.asarray(mean_dn, float) - off, 0.0) / K
        return K * K * (sd * sd + mu_e + dsnu * dsnu + (prnu * mu_e) ** 2) + 1.0 / 12.0
    return fn


def noise_free_dn(gt: dict, radiance: np.ndarray) -> np.ndarray:
    """The expected DN of every pixel: black level + K·η·(photons per radiance)·radiance."""
    s = gt["sensor"]
    rad = np.asarray(radiance, float)
    rad = rad if rad.ndim == 2 else rad.mean(axis=2)
    off = float(s.get("dark_offset_dn", gt.get("image", {}).get("black_level_dn", 0.0)))
    return off + float(s["gain_dn_per_e"]) * float(s["qe"]) * float(gt["photons_per_radiance"]) * rad


def point_bounds(gt: dict, radiance: np.ndarray, truth, x, y, masks: dict, blur_known=()) -> dict:
    """label -> (N,) exact per-point bound (px) at candidate pixel centres (x, y) (full-image integer
    coordinates) for each method's footprint ``masks[label]`` ((N, SIZE, SIZE) bool); labels in
    ``blur_known`` get the bound with the PSF's scale known.  NaN where the levels cannot be fitted
    (no contrast), the sensor block is missing, or the output is not the raw monochrome signal (a CFA,
    JPEG or processed output: its noise is not the EMVA model's)."""
    from edgetruth.evaluate.bound_psf import (bounds_from_derivatives,  # lazy: bound_psf loads numba
                                              means_and_derivatives, offsets_of)

    x = np.asarray(x, float)
    y = np.asarray(y, float)
    n = x.size
    out = {m: np.full(n, np.nan) for m in masks}
    if not n or not masks or "sensor" not in gt or radiance is None:
        return out
    sensor = gt["sensor"]
    if str(sensor.get("output", "raw")) != "raw" or str(sensor.get("cfa", "none")) != "none":
        return out  # demosaicked, compressed or processed output: the EMVA model of a raw pixel does not hold
    # methods sharing a footprint (and the blur's status) share one Fisher computation
    groups: dict = {}
    for m, mk in masks.items():
        mk = np.ascontiguousarray(mk, bool)
        groups.setdefault((m in blur_known, np.packbits(mk).tobytes()), (mk, []))[1].append(m)
    union = np.stack([mk for mk, _ in groups.values()]).any(axis=(0, 1))
    off = offsets_of(union)
    ui = np.nonzero(union.ravel())[0]
    dn = noise_free_dn(gt, radiance)
    H, W = dn.shape
    ix = x.astype(np.int64)[:, None] + off[None, :, 0].astype(np.int64)
    iy = y.astype(np.int64)[:, None] + off[None, :, 1].astype(np.int64)
    inside = (ix >= 0) & (ix < W) & (iy >= 0) & (iy < H)
    vals = dn[np.clip(iy, 0, H - 1), np.clip(ix, 0, W - 1)]
    on = {k: mk.reshape(n, -1)[:, ui] & inside for k, (mk, _) in groups.items()}
    use = np.stack(list(on.values())).any(axis=0)
    geo = outline_geometry(truth, x, y)
    var_fn = sensor_variance(gt)
    spreads, bin_of = field_bins(gt, x, y)
    for kb, spread in enumerate(spreads):
        sel = np.nonzero(bin_of == kb)[0]
        derivs = means_and_derivatives(spread, {k: v[sel] for k, v in geo.items()}, off, use[sel])
        A, B = _levels(derivs[0], vals[sel], use[sel])
        ok = np.isfinite(A) & np.isfinite(B) & (np.abs(B) > 0)
        if not ok.any():
            continue
        idx = sel[ok]
        derivs = tuple(np.ascontiguousarray(v[ok]) for v in derivs)
        for known in (False, True):
            keys = [k for k in groups if k[0] == known]
            if not keys:
                continue
            b = bounds_from_derivatives(derivs, A[ok], B[ok], np.stack([on[k][idx] for k in keys]),
                                        variance_fn=var_fn, blur_unknown=not known)
            for k, bk in zip(keys, b):
                for m in groups[k][1]:
                    out[m][idx] = bk
    return out


def _levels(M: np.ndarray, vals: np.ndarray, use: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per row: least squares vals ≈ A + B·M over the ``use`` pixels (NaN without spread in M)."""
    w = use.astype(float)
    s0 = w.sum(1)
    s1 = (w * M).sum(1)
    s2 = (w * M * M).sum(1)
    t0 = (w * vals).sum(1)
    t1 = (w * M * vals).sum(1)
    det = s0 * s2 - s1 * s1
    good = det > 1e-6 * np.maximum(s0 * s0, 1.0)
    det = np.where(good, det, np.nan)
    B = (s0 * t1 - s1 * t0) / det
    A = (t0 - B * s1) / np.where(s0 > 0, s0, np.nan)
    return A, B
