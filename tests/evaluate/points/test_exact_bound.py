"""The exact per-point bound of the render tables (evaluate/points/bound.py, docs/bound.md).

- On an analytic image (an exact pixel-integrated Gaussian-blurred edge, EMVA noise model, levels
  fitted from the noise-free image as on a render), the bound of every footprint equals a direct
  Fisher computation: crb's closed-form pixel means with forward differences (straight edges:
  within 1e-3), and for a circle the PSF model's own means by central differences
  (``bound_psf.jacobian``, an independent code path from the batched chain-rule kernel; within 1e-3)
  and crb's distance-profile circle (within 2 %, the two circle models' difference).
- Monte Carlo: the weighted least-squares fit of the exact model (ρ, φ, A, B; the camera's PSF known:
  Airy f/4, aberration, defocus disk, OLPF) on the patch_psf_fit footprint of a rendered-like edge
  (expected image from finer tables than the bound's, EMVA noise) comes within [0.90, 1.10] of the
  bound, on a straight edge and a circle.
"""
import numpy as np
import pytest

from edgetruth import locate
from edgetruth.evaluate import bound_psf as BP
from edgetruth.evaluate import crb
from edgetruth.evaluate.points import bound as PB
from edgetruth.render.edge_truth import CircleEdge, OutlineEdge, StraightEdge
from tests.support.edge_scenes import SHAPE_64, near_candidates, render

K_GAIN, DARK_E, QE, PPR = 0.5, 6.0, 0.5, 1000.0
METHODS = ("patch_psf_fit", "erf4p_fixed11", "canny_devernay", "canny_zernike2020")


def _gt(shape, sigma_px=1.0, cutoff_nm=0.0, defocus_px=0.0, olpf_px=0.0, pitch_um=4.8, growth=0.0):
    h, w = SHAPE_64
    return {"camera": {"pitch_um": pitch_um, "f_number": 4.0, "width_px": w, "height_px": h, "cx_px": (w - 1) / 2,
                       "cy_px": (h - 1) / 2,
                       "optics": {"psf": {"diffraction_wavelength_nm": cutoff_nm,
                                          "aberration_sigma_um": sigma_px * pitch_um,
                                          "aberration_sigma_growth": growth, "olpf_split_um": olpf_px * pitch_um}}},
            "optics_at_target": {"defocus_radius_px": defocus_px},
            "sensor": {"qe": QE, "gain_dn_per_e": K_GAIN, "dark_noise_e": DARK_E, "dark_offset_dn": 0.0},
            "photons_per_radiance": PPR, "target": {"shape": shape}}


def _outline(edge) -> OutlineEdge:
    """A closed polyline whose boundary near the image is ``edge`` (> 0 outside = the bright side)."""
    if isinstance(edge, CircleEdge):
        assert not edge.bright_inside
        t = np.linspace(0, 2 * np.pi, 2000, endpoint=False)
        poly = np.column_stack([edge.cx + edge.radius_px * np.cos(t), edge.cy + edge.radius_px * np.sin(t)])
        return OutlineEdge(poly, "circle")
    c, s = np.cos(edge.angle_rad), np.sin(edge.angle_rad)
    u = np.arange(-300, 300.01, 0.5)
    line = np.column_stack([edge.x0 - u * s, edge.y0 + u * c])
    far = line[[-1, 0]] - 600 * np.array([c, s])  # close the polygon on the dark side
    return OutlineEdge(np.vstack([line, far]), "square")


def _points(edge, step=5):
    img = render(SHAPE_64, edge, 1.0, 0.0)
    cand = near_candidates(img, edge)
    inner = (cand.x > 10) & (cand.x < 53) & (cand.y > 10) & (cand.y < 53)
    return cand.subset(np.nonzero(inner)[0][::step])


@pytest.mark.parametrize("angle", [0.0, 0.5, 2.3])
def test_line_bound_equals_a_direct_fisher_computation(angle):
    edge = StraightEdge(32.3, 31.7, angle)
    cand = _points(edge)
    dn = render(SHAPE_64, edge, 1.0, 0.0)  # A 40 DN, B 120 DN, exact pixel integral of Phi(d / 1 px)
    masks = {m: locate.METHODS[m].footprint_masks(cand) for m in METHODS}
    got = PB.point_bounds(_gt("square"), dn / (K_GAIN * QE * PPR), _outline(edge), cand.x, cand.y, masks)
    geo = crb.edge_geometry(edge, cand.x, cand.y)
    ref = crb.footprint_bounds(geo, 40.0, 120.0, 1.0, 1.0, masks, variance_fn=BP.emva_variance(K_GAIN, DARK_E))
    for m in METHODS:
        assert np.all(np.isfinite(got[m]))
        np.testing.assert_allclose(got[m], ref[m], rtol=1e-3, err_msg=m)


def _fd_fisher_bound(optics, geo, A, B, mask, var_fn):
    """sqrt((F^-1)_rho,rho) from bound_psf.jacobian (central differences of the PSF model's means)."""
    off = BP.offsets_of(mask)
    J, M = BP.jacobian(optics, geo, A, B, off, True, BP.EdgeSpread(optics, 1.0, 1 << 14, 0.25))
    w = 1.0 / var_fn(A + B * M)
    F = np.einsum("np,npk,npl->nkl", w, J, J)
    return crb.bound_from_fisher(F)


@pytest.mark.slow
def test_circle_bound_equals_a_direct_fisher_computation():
    edge = CircleEdge(31.6, 32.2, 17.0, False)
    cand = _points(edge, 7)
    gt = _gt("circle")
    optics = PB.optics_at(gt, 0.0)
    dn = _expected_dn(edge, optics, 40.0, 120.0)  # the disk under the (Gaussian) PSF, box-integrated
    masks = {m: locate.METHODS[m].footprint_masks(cand) for m in METHODS}
    got = PB.point_bounds(gt, dn / (K_GAIN * QE * PPR), _outline(edge), cand.x, cand.y, masks)
    geo = crb.edge_geometry(edge, cand.x, cand.y)
    var_fn = BP.emva_variance(K_GAIN, DARK_E)
    ref = crb.footprint_bounds(geo, 40.0, 120.0, 1.0, 1.0, masks, variance_fn=var_fn)
    for m in METHODS:
        np.testing.assert_allclose(got[m], ref[m], rtol=0.03, err_msg=m)  # disk under the PSF vs distance profile
        for i in range(len(cand)):
            g1 = {k: v[i:i + 1] for k, v in geo.items()}
            fd = _fd_fisher_bound(optics, g1, 40.0, 120.0, masks[m][i], var_fn)[0]
            assert got[m][i] == pytest.approx(fd, rel=1e-3), (m, i)


def _expected_dn(edge, optics, A, B):
    """The rendered-like noise-free image: every pixel's mean under ``optics`` from finer tables
    (0.25 deg, 256 px period) than the bound's."""
    h, w = SHAPE_64
    yy, xx = np.mgrid[0:h, 0:w]
    geo = crb.edge_geometry(edge, xx.ravel().astype(float), yy.ravel().astype(float))
    M = BP.unit_means(BP.EdgeSpread(optics, 1.0, 1 << 14, 0.25), geo, np.zeros((1, 2)))[:, 0]
    return (A + B * M).reshape(h, w)


@pytest.mark.parametrize("edge", [StraightEdge(32.3, 31.7, 0.7), CircleEdge(32.2, 31.9, 18.0, False)],
                         ids=["line", "circle"])
def test_weighted_fit_of_the_exact_model_attains_the_bound(edge):
    gt = _gt("circle" if isinstance(edge, CircleEdge) else "square", sigma_px=0.35, cutoff_nm=550.0,
             defocus_px=0.8, olpf_px=0.3)
    optics = PB.optics_at(gt, 0.0)
    assert optics.cutoff_cy_px == pytest.approx(4.8 / (0.55 * 4.0))
    A, B = 40.0, 120.0
    dn = _expected_dn(edge, optics, A, B)
    cand = _points(edge, 4)
    mask = locate.METHODS["patch_psf_fit"].footprint_masks(cand)
    bound = PB.point_bounds(gt, dn / (K_GAIN * QE * PPR), _outline(edge), cand.x, cand.y, {"m": mask},
                            blur_known={"m"})["m"]
    # draws: every (point, repeat) fitted at once by weighted Gauss-Newton on (rho, phi, A, B)
    reps = 60
    n = len(cand)
    off = BP.offsets_of(mask.any(axis=0))
    ix = (cand.x.astype(int)[:, None] + off[None, :, 0].astype(int))
    iy = (cand.y.astype(int)[:, None] + off[None, :, 1].astype(int))
    use = mask.reshape(n, -1)[:, np.nonzero(mask.any(axis=0).ravel())[0]]
    mean = dn[iy, ix]
    sd = np.sqrt(BP.emva_variance(K_GAIN, DARK_E)(mean))
    rng = np.random.default_rng(7)
    y = np.repeat(mean, reps, 0) + np.repeat(sd, reps, 0) * rng.standard_normal((n * reps, mean.shape[1]))
    wts = np.repeat(np.where(use, 1.0 / sd ** 2, 0.0), reps, 0)
    geo = {k: np.repeat(v, reps) for k, v in crb.edge_geometry(edge, cand.x, cand.y).items()}
    true_rho = geo["rho"].copy()
    p = np.column_stack([geo["rho"], geo["phi"], np.full(n * reps, A), np.full(n * reps, B)])
    spread = BP.EdgeSpread(optics, 1.0, 1 << 14, 0.25)
    uu = np.repeat(use, reps, 0)
    for _ in range(8):
        g = dict(geo, rho=p[:, 0].copy(), phi=p[:, 1].copy())
        M, Jr, Jp, _ = BP.means_and_derivatives(spread, g, off, uu)
        r = y - (p[:, 2:3] + p[:, 3:4] * M)
        J = np.stack([p[:, 3:4] * Jr, p[:, 3:4] * Jp, np.ones_like(M), M], axis=-1)
        H = np.einsum("np,npk,npl->nkl", wts, J, J)
        gvec = np.einsum("np,npk,np->nk", wts, J, r)
        p += np.linalg.solve(H, gvec[..., None])[..., 0]
    err = p[:, 0] - true_rho
    ratio = np.sqrt(np.mean(err ** 2)) / np.sqrt(np.mean(np.repeat(bound, reps) ** 2))
    assert abs(np.mean(err)) < 3 * np.sqrt(np.mean(err ** 2) / err.size) + 1e-4  # unbiased
    print(f"RMSE / bound = {ratio:.3f} ({err.size} fits)")
    assert 0.90 <= ratio <= 1.10, ratio
