"""Canny–Zernike2020 (locate/methods/canny_zernike2020.py): Ghosal-Mehrotra Zernike step, as a specification.

Known behaviour: the operator's model is an *unblurred* straight step inside the
mask's disk (radius N/2 = 3.5 px).  On such an edge it is nearly exact; on a
blurred edge it is exact only when the edge passes through the mask centre --
blur spreads the step symmetrically, so Z20 / Z11' underestimates |l| and the
point is pulled toward the candidate pixel.  At blur 1 px that bias dominates
the error budget (a few tenths of the offset).
"""
from functools import partial

import numpy as np

from edgetruth.locate.methods.canny_zernike2020 import zernike_masks
from tests.support.edge_scenes import (SHAPE_64 as SHAPE, make_edge, noise_displacement, refine_near_edge, render,
                                       run_method, stats)


def test_masks_integrate_the_zernike_polynomials_over_the_disk():
    mx, my, m20 = zernike_masks(7)
    # symmetry: M11x odd in columns, M11y its transpose, M20 fully symmetric
    assert np.allclose(mx, -mx[:, ::-1], atol=1e-12) and np.allclose(my, mx.T, atol=1e-12)
    assert np.allclose(m20, m20.T, atol=1e-12) and np.allclose(m20, m20[::-1], atol=1e-12)
    # V20 and V11 integrate to 0 over the disk; the corner pixels lie outside the disk
    assert abs(m20.sum()) < 1e-6 and abs(mx.sum()) < 1e-12
    assert mx[0, 0] == 0.0 and m20[0, 0] == 0.0
    # the moment of u over the disk part u > a (columns right of the centre, a = 0.5/3.5)
    # is integral_a^1 2u sqrt(1-u^2) du = (2/3)(1 - a^2)^(3/2)
    a = 0.5 / 3.5
    assert abs(mx[:, 4:].sum() - 2.0 / 3.0 * (1 - a * a) ** 1.5) < 5e-7  # midpoint rule near u = 1: O(h^1.5)


def _unblurred_offsets(seeds):
    """(l, true edge offset from the candidate along the Zernike normal) on unblurred straight steps."""
    ls, ds = [], []
    for s in seeds:
        edge = make_edge("line", s)
        cand, pts = refine_near_edge(render(SHAPE, edge, 0.0), edge, "canny_zernike2020")
        c, sn = edge.normal
        ls.append(pts.l)
        ds.append(-edge.signed_distance(cand.x, cand.y) / (pts.nx * c + pts.ny * sn))
    return np.concatenate(ls), np.concatenate(ds)


def test_scale_factor_is_half_the_mask_size():
    """On unblurred steps (the operator's own model) the least-squares factor k in
    offset = k l is 3.63 px: N/2 = 3.5 (the convention used), not (N-1)/2 = 3 or N = 7.
    The 4 % excess comes from digitisation (the masks treat each pixel's mean as
    constant over the pixel).  Asserted: 3.3 < k < 3.8."""
    l, d = _unblurred_offsets(range(10))
    k = float((l * d).sum() / (l * l).sum())
    assert 3.3 < k < 3.8, k


def test_unblurred_straight_edges_are_nearly_exact():
    """Measured RMSE 0.013 px on unblurred steps.  Asserted < 0.025."""
    e, conv = run_method("canny_zernike2020", "line", range(10), blur=0.0)
    assert conv == 1.0 and stats(e)[1] < 0.025


def test_ideal_straight_edges():
    """Noise-free straight edges, blur 1 px.  Measured |mean| = 0.0002, RMSE = 0.104:
    the blur bias described above.  Asserted: RMSE in [0.07, 0.12] (the bias is real and
    must not vanish or grow), |mean| < 0.01, and the errors point back toward the
    candidate pixel: least-squares estimate/truth factor 0.72 (measured), asserted in (0.5, 0.9)."""
    e, conv = run_method("canny_zernike2020", "line", range(12))
    mean, rmse = stats(e)
    assert conv == 1.0
    assert 0.07 < rmse < 0.12, rmse
    assert mean < 0.01, mean
    # shrink toward the candidate: estimate = k' * truth offset with k' < 1
    d_true, d_est = [], []
    for s in range(12):
        edge = make_edge("line", s)
        cand, pts = refine_near_edge(render(SHAPE, edge, 1.0), edge, "canny_zernike2020")
        d_true.append(-edge.signed_distance(cand.x, cand.y))
        d_est.append(pts.offset * (pts.nx * edge.normal[0] + pts.ny * edge.normal[1]))
    d_true, d_est = np.concatenate(d_true), np.concatenate(d_est)
    shrink = float((d_true * d_est).sum() / (d_true * d_true).sum())
    assert 0.5 < shrink < 0.9, shrink


def test_ideal_circles():
    """Circles, radius 12-20 px, blur 1: blur bias plus the curvature of the edge inside
    the 7-px disk.  Measured |mean| = 0.006, RMSE = 0.130.  Asserted RMSE < 0.16, |mean| < 0.02."""
    e, conv = run_method("canny_zernike2020", "circle", range(6))
    mean, rmse = stats(e)
    assert conv == 1.0
    assert rmse < 0.16, rmse
    assert mean < 0.02, mean


# Per-point displacement caused by noise alone: the noisy image refined on the
# noise-free image's candidates (the operator reads the image, not cand.smoothed).
# Every point is scored, converged or not.
_noise_displacement = partial(noise_displacement, "canny_zernike2020")


def test_error_grows_with_noise():
    """The 7x7 moments average 37 pixels, so noise moves the point little compared with
    the blur bias: measured RMSE 0.104 -> 0.109 at sigma_n/B = 0.02.  The noise-only
    displacement on fixed candidates (0.0152 px at 0.01, 0.0304 px at 0.02) is linear in sigma_n (the moments
    are linear in the image, l = Z20/Z11' is smooth).  Asserted: RMSE grows, displacement
    ratio 2 +- 10 %."""
    seeds = range(16)
    r0 = stats(run_method("canny_zernike2020", "line", seeds)[0])[1]
    r2 = stats(run_method("canny_zernike2020", "line", seeds, noise_rel=0.02)[0])[1]
    assert r2 > r0, (r0, r2)
    d1 = _noise_displacement(0.01, seeds)
    d2 = _noise_displacement(0.02, seeds)
    assert 0.01 < d2 < 0.06, d2
    assert 1.8 < d2 / d1 < 2.2, (d1, d2)
