"""Throughput of the refinement stage (after Canny) on 1280 x 1024 synthetic images.

Figures: refined points per second per method (median of repeats, all
cores numba uses), and for the dynamic ERF fits the ratio against
``scipy.optimize.least_squares`` fitting the same profiles with the same
windows one by one (results compared on converged points).
"""
from __future__ import annotations

import os
import time
from functools import lru_cache

import numba
import numpy as np
from scipy.optimize import least_squares
from scipy.special import ndtr

from edgetruth import locate
from edgetruth.evaluate.method_order import resolve
from edgetruth.locate import erf_kernels as K
from edgetruth.locate.profiles import sample_profiles
from edgetruth.render.edge_truth import CircleEdge
from edgetruth.render.synthetic.scenarios import render_edge_image


BENCH_SHAPE = (1024, 1280)


def bench_image(shape=BENCH_SHAPE, tile: int = 128, seed: int = 0) -> np.ndarray:
    """A mosaic of 128-px tiles on one background, each with a blurred disc (dark or bright, every
    orientation of the edge), blur U(0.5, 2) px, contrast U(60, 180), noise 1 % of the contrast.
    The discs stay clear of the tile borders, so the mosaic has no seams."""
    rng = np.random.default_rng(seed)
    h, w = shape
    background = 100.0
    img = np.empty(shape)
    for r in range(0, h, tile):
        for c in range(0, w, tile):
            th, tw = min(tile, h - r), min(tile, w - c)
            bright_inside = bool(rng.integers(2))
            e = CircleEdge(tw / 2 + rng.uniform(-1, 1), th / 2 + rng.uniform(-1, 1), rng.uniform(20, 0.5 * min(th, tw) - 20),
                           bright_inside)
            B = rng.uniform(60, 180)
            A = background if bright_inside else background - B
            img[r:r + th, c:c + tw] = render_edge_image((th, tw), e, A, B, rng.uniform(0.5, 2.0), noise_sigma=0.01 * B, rng=rng)
    return img


def interleaved_times(img, cand, methods, repeats: int, options: dict | None = None) -> dict:
    """Wall times (s) of one refinement call per method, ``repeats`` rounds, every method once per round:
    a change of machine load hits all methods alike, so per-round ratios compare like with like."""
    run = {m: resolve(m, options) for m in methods}  # a label with options (pae2013:variant=floating) runs its method
    for m in methods:
        locate.refine(img, cand, run[m][0], **run[m][1])  # compile / warm caches
    times = {m: [] for m in methods}
    for _ in range(repeats):
        for m in methods:
            t0 = time.perf_counter()
            locate.refine(img, cand, run[m][0], **run[m][1])
            times[m].append(time.perf_counter() - t0)
    return times


def ratio_medians(times: dict, reference: str) -> dict:
    """Median over rounds of (reference time / method time): throughput relative to ``reference``."""
    ref = np.asarray(times[reference])
    return {m: float(np.median(ref / np.asarray(t))) for m, t in times.items()}


@lru_cache(maxsize=2)
def _bench_candidates(shape):
    img = bench_image(shape)
    return img, locate.candidates(img)


def batch_throughput(methods, options: dict | None = None, repeats: int = 7, shape=BENCH_SHAPE,
                     reference: str | None = None):
    """Points per second of each method's refinement over all candidates of the bench mosaic in one
    call (median of ``repeats`` interleaved rounds), with the study's per-method ``options``: the
    studies' time per point.  With ``reference``: also the median per-round ratio of each method's
    throughput to the reference's (robust to the machine's load changing between rounds)."""
    img, cand = _bench_candidates(tuple(shape))
    methods = list(methods)
    times = interleaved_times(img, cand, methods, repeats, options)
    rates = {m: len(cand) / float(np.median(t)) for m, t in times.items()}
    if reference is None:
        return rates
    return rates, (ratio_medians(times, reference) if reference in times else {})


REFERENCE = "erf4p_fixed11"
#: issue 20's throughput goal for edgetruth's own 2-D patch fit (points/s, all the cores numba uses)
PATCH_METHOD, PATCH_TARGET = "patch_psf_fit", 200_000
#: the curve-fit baselines that must keep up with the ERF kernels (>= 2/3 of REFERENCE's points/s)
CURVE_FITS = ("hagara_aef2011", "gaussian_fit2014", "arctan_fit2016", "sigmoid_logistic_fit2023", "ser_cis")
MIN_RATIO = 2.0 / 3.0


def scipy_reference(profiles, windows, four_param: bool):
    """Fit each profile one by one with scipy (LM), same window and model as the kernel: mu per point."""
    t = np.arange(K.PROFILE_LEN) - K.PROFILE_HALF
    mus = np.empty(len(profiles))
    for i, (prof, w) in enumerate(zip(profiles, windows)):
        half = (int(w) - 1) // 2
        tt = t[K.PROFILE_HALF - half:K.PROFILE_HALF + half + 1]
        y = prof[K.PROFILE_HALF - half:K.PROFILE_HALF + half + 1]
        A, B = y.min(), y.max() - y.min()
        g = np.clip(np.diff(y), 0, None)
        mu0 = float(np.sum(g * (tt[:-1] + 0.5)) / max(g.sum(), 1e-300))
        if four_param:
            res = least_squares(lambda p: p[0] + p[1] * ndtr((tt - p[2]) / p[3]) - y, [A, B, mu0, 1.0], method="lm")
            mus[i] = res.x[2]
        else:
            res = least_squares(lambda p: A + B * ndtr((tt - p[0]) / p[1]) - y, [mu0, 1.0], method="lm")
            mus[i] = res.x[0]
    return mus


ESF_METHOD, ESF_SIGMA_PX = "patch_esf_fit", 1.25  # the mosaic's blur is U(0.5, 2) px: its middle for the tables


def esf_line(img, cand, repeats: int) -> str:
    """patch_esf_fit needs a camera's edge-spread tables, which a mosaic has not: it runs here with the tables of
    a Gaussian PSF of the mosaic's middle blur (its discs' blur spans 0.4-1.6x that, so some points leave the
    fitted scale's range), unweighted, after a warm-up; median of ``repeats`` calls."""
    from edgetruth.evaluate import bound_psf as BP  # lazy: bound_psf loads numba

    tab = BP.EdgeSpread(BP.Optics(sigma_x_px=ESF_SIGMA_PX, sigma_y_px=ESF_SIGMA_PX), 1.0, 1 << 12).tables()
    pts = locate.refine(img, cand, ESF_METHOD, esf=tab)
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        locate.refine(img, cand, ESF_METHOD, esf=tab)
        ts.append(time.perf_counter() - t0)
    n = len(cand)
    r = n / float(np.median(ts))
    return (f"{ESF_METHOD} (Gaussian sigma {ESF_SIGMA_PX} px tables, unweighted): {r:,.0f} points/s "
            f"({np.mean(pts.converged):.0%} converged), against the goal {PATCH_TARGET:,} "
            f"({'met' if r >= PATCH_TARGET else f'{PATCH_TARGET / r:.1f}x short'})")


def run_bench(repeats: int = 7, scipy_points: int = 400, methods=None) -> list[str]:
    img, cand = _bench_candidates(BENCH_SHAPE)
    n = len(cand)
    methods = locate.registry.camera_free() if methods is None else list(methods)  # a mosaic has no camera
    times = interleaved_times(img, cand, methods, repeats)
    ratios = ratio_medians(times, REFERENCE) if REFERENCE in times else {}
    lines = [f"refinement throughput, {BENCH_SHAPE[1]}x{BENCH_SHAPE[0]} mosaic, {n} candidates, "
             f"numba threads={numba.get_num_threads()} (cpus={os.cpu_count()}), median of {repeats} interleaved rounds"]
    lines.append(f"{'method':28s} {'points/s':>12s} {'us/point':>9s} {'/' + REFERENCE:>15s}")
    rates = {}
    for m in methods:
        dt = float(np.median(times[m]))
        rates[m] = n / dt
        r = f"{ratios[m]:15.2f}" if m in ratios else ""
        lines.append(f"{m:28s} {n / dt:12,.0f} {1e6 * dt / n:9.2f} {r}")
    if PATCH_METHOD in rates:
        r = rates[PATCH_METHOD]
        lines.append(f"{PATCH_METHOD}: {r:,.0f} points/s on {numba.get_num_threads()} numba threads against the goal "
                     f"{PATCH_TARGET:,} ({'met' if r >= PATCH_TARGET else f'{PATCH_TARGET / r:.1f}x short'}; "
                     f"{r / numba.get_num_threads():,.0f} per thread)")
    if ESF_METHOD in locate.METHODS and (ESF_METHOD in methods or len(methods) > 1):
        lines.append(esf_line(img, cand, repeats))
    fits = [m for m in CURVE_FITS if m in ratios]
    if fits:
        ok = all(ratios[m] >= MIN_RATIO for m in fits)
        lines.append(f"curve-fit baselines vs {REFERENCE} (median per-round ratio, target >= {MIN_RATIO:.2f}): "
                     + ", ".join(f"{m} {ratios[m]:.2f}" for m in fits) + (" -- all keep up" if ok else " -- BELOW TARGET"))
    for m, four in (("dynamic_erf_2p", False), ("dynamic_erf_4p", True)):
        if m not in rates:
            continue
        pts = locate.refine(img, cand, m)
        profiles = sample_profiles(img, cand)
        sel = np.linspace(0, n - 1, min(scipy_points, n)).astype(int)
        t0 = time.perf_counter()
        mus = scipy_reference(profiles[sel], pts.window[sel], four)
        per_pt = (time.perf_counter() - t0) / sel.size
        conv = pts.converged[sel]
        diff = np.abs(mus[conv] - pts.offset[sel][conv])
        lines.append(f"{m}: scipy least_squares one by one {1e3 * per_pt:.3f} ms/point; kernel is "
                     f"{per_pt * rates[m]:,.0f}x faster; max |d mu| on {conv.sum()} converged points = {diff.max():.2e} px "
                     f"({'agree' if diff.max() <= 1e-3 else 'DISAGREE'} within 1e-3 px)")
    return lines
