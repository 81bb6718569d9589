"""The per-point bound under the camera's PSF (evaluate/bound_psf.py, docs/bound.md "On renders").

- A Gaussian PSF: the expected image is the closed form of evaluate/crb.py, and so is the bound
  (straight edges: to 1e-6; circles: the disk under the PSF vs crb's distance profile, 2 %).
- A camera's PSF (Airy f/4 at 550 nm on 4.8 um pixels, Gaussian aberration, a defocus disk, OLPF):
  the bound equals the one from a numerical Fisher information -- central differences of the
  expected image computed independently (the PSF's ESF by direct quadrature of the sine integral of
  its OTF, averaged over each pixel by 8 x 8 Gauss-Legendre).
- Monte Carlo: the maximum-likelihood fit of that exact model on a footprint (EMVA-type
  signal-dependent noise) comes within [0.9, 1.10] of its bound on straight and curved edges.
"""
import numpy as np
import pytest
from scipy.optimize import least_squares

from edgetruth import locate
from edgetruth.evaluate import bound_psf as BP
from edgetruth.evaluate import crb
from edgetruth.render.edge_truth import CircleEdge, StraightEdge
from tests.support.edge_scenes import SHAPE_64, near_candidates, render

CAMERA_PSF = BP.Optics(cutoff_cy_px=4.8 / (0.55 * 4.0), sigma_x_px=0.35, sigma_y_px=0.35, defocus_px=0.8,
                       olpf_px=0.3)
A, B = 40.0, 120.0


def _cands(edge, step=7):
    img = render(SHAPE_64, edge, 1.0, 0.0)
    cand = near_candidates(img, edge)
    return cand.subset(np.arange(0, len(cand), step))


@pytest.mark.parametrize("angle", [0.0, 0.4, 2.1])
def test_gaussian_psf_gives_the_closed_form_bound(angle):
    edge = StraightEdge(32.3, 31.7, angle)
    cand = _cands(edge)
    geo = crb.edge_geometry(edge, cand.x, cand.y)
    masks = {m: locate.METHODS[m].footprint_masks(cand) for m in ("patch_psf_fit", "erf4p_fixed11", "canny_devernay")}
    ref = crb.footprint_bounds(geo, A, B, 1.0, 1.0, masks, noise_var=2.4 ** 2)
    got = BP.footprint_bounds(BP.Optics(sigma_x_px=1.0, sigma_y_px=1.0), geo, A, B, masks, noise_var=2.4 ** 2)
    for m in masks:
        np.testing.assert_allclose(got[m], ref[m], rtol=1e-6)


def test_gaussian_psf_circle_is_close_to_the_distance_profile_bound():
    edge = CircleEdge(32.2, 31.9, 15.0, True)
    cand = _cands(edge, 11)
    geo = crb.edge_geometry(edge, cand.x, cand.y)
    masks = {"patch_psf_fit": locate.METHODS["patch_psf_fit"].footprint_masks(cand)}
    ref = crb.footprint_bounds(geo, A, B, 1.0, 1.0, masks, noise_var=2.4 ** 2)["patch_psf_fit"]
    got = BP.footprint_bounds(BP.Optics(sigma_x_px=1.0, sigma_y_px=1.0), geo, A, B, masks,
                              noise_var=2.4 ** 2)["patch_psf_fit"]
    np.testing.assert_allclose(got, ref, rtol=0.02)


def _independent_means(optics, rho, phi, offsets, scale=1.0):
    """Pixel means of a straight edge under ``optics``: the PSF's ESF along the normal by direct
    quadrature of 1/2 + (1/pi) int_0^inf OTF(nu n) sin(2 pi nu x) / nu dnu, averaged over each pixel
    by 8 x 8 Gauss-Legendre nodes."""
    c, s = np.cos(phi), np.sin(phi)
    g, w = np.polynomial.legendre.leggauss(8)
    gx, gy = np.meshgrid(0.5 * g, 0.5 * g)
    ww = np.outer(0.5 * w, 0.5 * w).ravel()
    x = offsets[:, 0:1] + gx.ravel()[None]
    y = offsets[:, 1:2] + gy.ravel()[None]
    d = (x * c + y * s + rho).ravel()
    nu = (np.arange(4000) + 0.5) * (4.0 / 4000)  # the OTF is 0 beyond the diffraction cutoff (2.18)
    T = optics.otf(nu * c, nu * s, scale)
    esf = 0.5 + (T[None, :] * np.sin(2 * np.pi * np.outer(d, nu)) / nu[None, :]).sum(axis=1) * (4.0 / 4000) / np.pi
    return (esf.reshape(x.shape) * ww[None]).sum(axis=1)


def test_camera_psf_bound_matches_a_numerical_fisher_information():
    edge = StraightEdge(32.3, 31.7, 0.5)
    cand = _cands(edge, 9)
    geo = crb.edge_geometry(edge, cand.x, cand.y)
    masks = locate.METHODS["erf4p_fixed11"].footprint_masks(cand)
    var_fn = BP.emva_variance(0.5, 6.0)
    got = BP.footprint_bounds(CAMERA_PSF, geo, A, B, {"m": masks}, variance_fn=var_fn)["m"]
    for i in range(0, len(cand), 3):
        off = BP.offsets_of(masks[i])
        rho, phi = geo["rho"][i], geo["phi"][i]
        m0 = _independent_means(CAMERA_PSF, rho, phi, off)
        h = 1e-3
        cols = [B * (_independent_means(CAMERA_PSF, rho + h, phi, off) - _independent_means(CAMERA_PSF, rho - h, phi, off)) / (2 * h),
                B * (_independent_means(CAMERA_PSF, rho, phi + h, off) - _independent_means(CAMERA_PSF, rho, phi - h, off)) / (2 * h),
                np.ones_like(m0), m0,
                B * (_independent_means(CAMERA_PSF, rho, phi, off, 1 + h) - _independent_means(CAMERA_PSF, rho, phi, off, 1 - h)) / (2 * h)]
        J = np.stack(cols, axis=1)
        F = J.T @ (J / var_fn(A + B * m0)[:, None])
        ref = crb.bound_from_fisher(F[None])[0]
        assert got[i] == pytest.approx(ref, rel=2e-3)


def _ml_ratio(edge, optics, n_fits, blur_unknown, seed, fft_len=1 << 12):
    """RMSE / bound of the ML fit of the exact model (rho, phi, A, B[, lambda]) on the patch_psf_fit
    footprint of a few candidates, over n_fits noisy draws each.

    ``fft_len`` (1/64-px grid, so 1 << 12 = a 64 px period around the +-16 px table) only sets which
    exact model is tested: the truth, every fitted model (one EdgeSpread per tried lambda) and the bound
    all use tables of this length, so the ratio compares like with like (measured: 1 << 14 and 1 << 12
    give ratios within 3e-5 of each other); the shorter FFT makes the per-lambda tables of the blur-unknown
    fit cheaper (the straight case ~1.6x faster).

    The truth comes from ``unit_means`` (a Python loop over the angle bins, tables built per bin); the
    fitted model from ``means_and_derivatives`` (the bound's batched numba kernel, tables built in
    bulk): the two agree to 2e-15 (asserted at each truth below to 1e-12), so the fit is the same
    (the model evaluation ~250x cheaper: the circle's footprint spans ~100 angle bins)."""
    cand = _cands(edge, 13)
    geo = crb.edge_geometry(edge, cand.x, cand.y)
    masks = locate.METHODS["patch_psf_fit"].footprint_masks(cand)
    var_fn = BP.emva_variance(0.25, 8.0)
    spread = BP.EdgeSpread(optics, 1.0, fft_len)
    bound = BP.footprint_bounds(optics, geo, A, B, {"m": masks}, variance_fn=var_fn, blur_unknown=blur_unknown,
                                spread=spread)["m"]
    rng = np.random.default_rng(seed)
    errs, bounds = [], []
    for i in range(len(cand)):
        off = BP.offsets_of(masks[i])
        g1 = {k: v[i:i + 1] for k, v in geo.items()}
        truth = BP.unit_means(spread, g1, off)[0]
        np.testing.assert_allclose(BP.means_and_derivatives(spread, g1, off)[0][0], truth, rtol=0, atol=1e-12)
        mean = A + B * truth
        sd = np.sqrt(var_fn(mean))
        cache = {}  # lambda -> EdgeSpread, the last few: each holds 17.7 MB of tables, and keeping every one
        # a fit tries (thousands) cost more in page faults than the fits themselves

        def unit(p):  # (M, dM/drho, dM/dphi, lambda dM/dlambda) at p = (rho, phi, A, B[, lambda])
            key = round(float(p[4]), 12) if blur_unknown else 1.0
            sp = cache.pop(key, None) or (BP.EdgeSpread(optics, key, fft_len) if blur_unknown else spread)
            cache[key] = sp  # the most recent last
            while len(cache) > 4:
                del cache[next(iter(cache))]
            g = dict(g1, rho=np.array([p[0]]), phi=np.array([p[1]]))
            return [a[0] for a in BP.means_and_derivatives(sp, g, off)]

        def jac(p):
            # the model's exact derivatives (the ones the bound is built from): scipy's differences would build a
            # new EdgeSpread for every lambda they try, ~90 % of the fit's time
            m, d_rho, d_phi, d_lam = unit(p)
            cols = [p[3] * d_rho, p[3] * d_phi, np.ones_like(m), m] + ([p[3] * d_lam / p[4]] if blur_unknown else [])
            return np.stack(cols, axis=1) / sd[:, None]

        for _ in range(n_fits):
            y = mean + sd * rng.standard_normal(mean.shape)
            p0 = [g1["rho"][0], g1["phi"][0], A, B] + ([1.0] if blur_unknown else [])
            fit = least_squares(lambda p: (p[2] + p[3] * unit(p)[0] - y) / sd, p0, jac=jac,
                                x_scale=[0.01, 0.01, 1, 1, 0.01][:len(p0)])
            errs.append(fit.x[0] - g1["rho"][0])
            bounds.append(bound[i])
    errs, bounds = np.array(errs), np.array(bounds)
    return float(np.sqrt(np.mean(errs ** 2)) / np.sqrt(np.mean(bounds ** 2))), errs.size


@pytest.mark.slow
def test_ml_fit_of_the_exact_model_attains_the_bound_straight():
    ratio, n = _ml_ratio(StraightEdge(32.3, 31.7, 0.7), CAMERA_PSF, 80, True, 1)
    assert 0.90 <= ratio <= 1.10, (ratio, n)


@pytest.mark.slow
def test_ml_fit_of_the_exact_model_attains_the_bound_circle():
    ratio, n = _ml_ratio(CircleEdge(32.2, 31.9, 18.0, False), CAMERA_PSF, 80, False, 2)
    assert 0.90 <= ratio <= 1.10, (ratio, n)
