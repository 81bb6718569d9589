"""patch_esf_fit (locate/methods/patch_esf_fit.py): the patch fit with the camera's exact edge spread.

The camera: Airy f/4 at 550 nm on 4.8 um pixels, Gaussian aberration 0.35 px, defocus disk 0.8 px, OLPF
0.3 px (as tests/evaluate/test_bound_psf.py).  The images are its exact expected images, built with the
tables themselves (``bound_psf.means_and_derivatives`` at every pixel centre of a straight edge or a
circle), A = 40, B = 120 DN.

- Without noise the fit recovers the edge: a line to 1e-4 px (measured 2e-6; 1e-12 with the curvature
  off); a circle to the curvature estimate's accuracy (the arc's curvature comes from the candidates'
  gradient field: measured RMS 1.1e-3 / 1.5e-3 px, max 2.6e-3 / 2.8e-3 px at radius 18 / 14 px).
- With EMVA noise (K = 0.25 DN/e, sigma_d = 8 e, as the bound's Monte Carlo), candidates from the noisy
  image: RMSE / the exact per-point bound of its footprint within [0.90, 1.10], blur unknown and known,
  lines and circles; the bias within 3 standard errors (clustered per image: neighbouring points share
  pixels); RMSE / the reported ``se`` within [0.9, 1.1].  Measured with 100 images per case: 0.998 / 0.984
  (line, blur free / known), 1.007 / 1.001 (circle); 24 here (~2-4 s each).
- Without the camera's tables it refuses, one line.
"""
import numpy as np
import pytest

from edgetruth import locate
from edgetruth.errors import InputError
from edgetruth.evaluate import bound_psf as BP
from edgetruth.evaluate import crb
from edgetruth.locate.esf_tables import EsfTables
from edgetruth.render.edge_truth import CircleEdge, StraightEdge
from tests.support.edge_scenes import near_candidates

CAMERA_PSF = BP.Optics(cutoff_cy_px=4.8 / (0.55 * 4.0), sigma_x_px=0.35, sigma_y_px=0.35, defocus_px=0.8,
                       olpf_px=0.3)
A, B = 40.0, 120.0
K_GAIN, DARK_E = 0.25, 8.0
SHAPE = (64, 64)
LINE = StraightEdge(32.3, 31.7, 0.7)
CIRCLE = CircleEdge(32.2, 31.9, 18.0, False)


@pytest.fixture(scope="module")
def spread():
    return BP.EdgeSpread(CAMERA_PSF, 1.0, 1 << 12)


def _exact_image(edge, spread):
    yy, xx = np.mgrid[0:SHAPE[0], 0:SHAPE[1]].astype(float)
    geo = crb.edge_geometry(edge, xx.ravel(), yy.ravel())
    M = BP.means_and_derivatives(spread, geo, np.zeros((1, 2)))[0][:, 0]
    return A + B * M.reshape(SHAPE)


def _inner(cand, margin=7):
    hi_x, hi_y = SHAPE[1] - 1 - margin, SHAPE[0] - 1 - margin
    keep = (cand.x >= margin) & (cand.x <= hi_x) & (cand.y >= margin) & (cand.y <= hi_y)
    return cand.subset(np.nonzero(keep)[0])


@pytest.mark.slow
@pytest.mark.parametrize("blur_known", [False, True])
def test_noise_free_line_is_exact(spread, blur_known):
    img = _exact_image(LINE, spread)
    cand = _inner(near_candidates(img, LINE))
    tab = spread.tables()
    pts = locate.refine(img, cand, "patch_esf_fit", esf=tab, blur_known=blur_known)
    assert pts.converged.all()
    e = LINE.signed_distance(pts.x, pts.y)
    assert np.max(np.abs(e)) < 1e-4, np.max(np.abs(e))  # the curvature estimate's ~1e-5/px scatter
    assert np.max(np.abs(pts.extras["lambda"] - 1.0)) < 1e-3
    straight = locate.refine(img, cand, "patch_esf_fit", esf=tab, blur_known=blur_known, curved=False, tol_px=1e-9)
    assert np.max(np.abs(LINE.signed_distance(straight.x, straight.y))) < 1e-12


@pytest.mark.parametrize("radius,bright_inside", [(18.0, False), (14.0, True)])
def test_noise_free_circle_within_the_curvature_estimate(spread, radius, bright_inside):
    edge = CircleEdge(32.2, 31.9, radius, bright_inside)
    img = _exact_image(edge, spread)
    cand = near_candidates(img, edge)
    pts = locate.refine(img, cand, "patch_esf_fit", esf=spread.tables())
    assert pts.converged.all()
    e = edge.signed_distance(pts.x, pts.y)
    assert np.sqrt(np.mean(e ** 2)) < 2.5e-3 and np.max(np.abs(e)) < 5e-3 and abs(e.mean()) < 5e-4, \
        (np.sqrt(np.mean(e ** 2)), np.max(np.abs(e)), e.mean())


def test_field_bins_pick_their_own_tables(spread):
    """bin_index chooses each point's tables: the true tables in a list with wrong ones give the same
    points as the true tables alone; swapping the index moves them."""
    img = _exact_image(LINE, spread)
    cand = _inner(near_candidates(img, LINE))
    wrong = BP.EdgeSpread(BP.Optics(CAMERA_PSF.cutoff_cy_px, 0.6, 0.6, 1.5, 0.3), 1.0, 1 << 12).tables()
    ref = locate.refine(img, cand, "patch_esf_fit", esf=spread.tables(), blur_known=True)
    idx = np.ones(len(cand), np.int64)
    got = locate.refine(img, cand, "patch_esf_fit", esf=[wrong, spread.tables()], bin_index=idx, blur_known=True)
    np.testing.assert_array_equal(got.x, ref.x)
    moved = locate.refine(img, cand, "patch_esf_fit", esf=[wrong, spread.tables()], bin_index=0 * idx,
                          blur_known=True)
    assert np.max(np.abs(LINE.signed_distance(moved.x, moved.y))) > 1e-2


def _monte_carlo(edge, spread, blur_known, n_images, seed):
    """(RMSE / bound, bias, clustered standard error of the bias, RMSE / se, n)."""
    mean = _exact_image(edge, spread)
    var_fn = BP.emva_variance(K_GAIN, DARK_E)
    sd = np.sqrt(var_fn(mean))
    tab = spread.tables()
    rng = np.random.default_rng(seed)
    errs, bounds, ses, per_image = [], [], [], []
    for _ in range(n_images):
        img = mean + sd * rng.standard_normal(SHAPE)
        cand = _inner(near_candidates(img, edge))
        pts = locate.refine(img, cand, "patch_esf_fit", esf=tab, blur_known=blur_known,
                            variance=(K_GAIN ** 2 * DARK_E ** 2 + 1.0 / 12.0, K_GAIN))
        masks = locate.METHODS["patch_esf_fit"].footprint_masks(cand)
        b = BP.footprint_bounds(CAMERA_PSF, crb.edge_geometry(edge, cand.x, cand.y), A, B, {"m": masks},
                                variance_fn=var_fn, blur_unknown=not blur_known, spread=spread)["m"]
        c = pts.converged
        assert c.mean() > 0.98
        e = edge.signed_distance(pts.x, pts.y)[c]
        errs.append(e)
        bounds.append(b[c])
        ses.append(pts.extras["se"][c])
        per_image.append(e.mean())
    e, b, s = map(np.concatenate, (errs, bounds, ses))
    rmse = np.sqrt(np.mean(e ** 2))
    return (rmse / np.sqrt(np.mean(b ** 2)), e.mean(), np.std(per_image, ddof=1) / np.sqrt(n_images),
            rmse / np.sqrt(np.mean(s ** 2)), e.size)


@pytest.mark.parametrize("edge", [LINE, CIRCLE], ids=["line", "circle"])
@pytest.mark.parametrize("blur_known", [False, True], ids=["blur-free", "blur-known"])
def test_noisy_fit_attains_the_bound(spread, edge, blur_known):
    ratio, bias, bias_se, over_se, n = _monte_carlo(edge, spread, blur_known, 24, 11)
    print(f"RMSE / bound = {ratio:.3f}, bias {bias:+.5f} +- {bias_se:.5f} px, RMSE / se = {over_se:.3f} ({n} points)")
    assert 0.90 <= ratio <= 1.10, ratio
    assert abs(bias) <= 3 * bias_se, (bias, bias_se)
    assert 0.9 <= over_se <= 1.1, over_se


def test_fused_and_batched_paths_agree(spread):
    """A tuple ``variance`` runs the fused per-point kernel, a callable the batched one: the same fit -- the
    model's last bits differ (the fused kernel's arc angle: esf_tables.atan_quadrant, 2 ulp of libm's atan2) --,
    so the same points to 1e-9 px (measured 1e-14) and the same flags."""
    mean = _exact_image(CIRCLE, spread)
    a, b = K_GAIN ** 2 * DARK_E ** 2 + 1.0 / 12.0, K_GAIN
    img = mean + np.sqrt(a + b * mean) * np.random.default_rng(5).standard_normal(SHAPE)
    cand = _inner(near_candidates(img, CIRCLE))
    tab = spread.tables()
    fused = locate.refine(img, cand, "patch_esf_fit", esf=tab, variance=(a, b))
    batched = locate.refine(img, cand, "patch_esf_fit", esf=tab, variance=lambda m: a + b * m)
    np.testing.assert_array_equal(fused.extras["status"], batched.extras["status"])
    assert fused.converged.mean() > 0.9
    assert np.max(np.hypot(fused.x - batched.x, fused.y - batched.y)) < 1e-9


def test_needs_the_camera(spread):
    img = _exact_image(LINE, spread)
    cand = _inner(near_candidates(img, LINE))
    with pytest.raises(InputError, match="patch_psf_fit"):
        locate.refine(img, cand, "patch_esf_fit")
    with pytest.raises(InputError, match="bin_index"):
        locate.refine(img, cand, "patch_esf_fit", esf=[spread.tables(), spread.tables()])
    with pytest.raises(InputError, match="variance"):
        locate.refine(img, cand, "patch_esf_fit", esf=spread.tables(), variance=(1.0,))
    part = BP.EdgeSpread(CAMERA_PSF, 1.0, 1 << 12)
    with pytest.raises(InputError, match="angle rows"):
        locate.refine(img, cand, "patch_esf_fit", esf=part.tables(bins=[0, 1]))
    assert isinstance(spread.tables(), EsfTables)


def test_studies_without_a_camera_leave_it_out():
    from edgetruth.locate.registry import camera_free

    assert locate.METHODS["patch_esf_fit"].needs_camera
    assert "patch_esf_fit" not in camera_free() and "patch_psf_fit" in camera_free()
    assert locate.METHODS["patch_esf_fit"].footprint is not None


@pytest.mark.slow  # 361 one-point fits: ~3 s idle, ~20 s on the loaded 2-core machine
def test_answer_depends_only_on_the_declared_footprint(spread):
    """As tests/locate/test_footprints.py for the camera-free methods: a pixel outside the footprint (and a
    ring beyond its radius) never changes the answer; one inside it does."""
    from edgetruth.locate import footprints as FP

    edge = StraightEdge(31.7, 32.2, 0.4)
    img = _exact_image(edge, spread) + np.random.default_rng(3).normal(0, 2.0, SHAPE)
    tab = spread.tables()
    cand = _inner(near_candidates(img, edge), 12)
    cand = cand.subset([len(cand) // 2])
    mask = locate.METHODS["patch_esf_fit"].footprint_masks(cand)[0]
    base = locate.refine(img, cand, "patch_esf_fit", esf=tab)
    x, y = int(cand.x[0]), int(cand.y[0])
    moved_inside = 0
    for dy in range(-FP.RADIUS - 1, FP.RADIUS + 2):
        for dx in range(-FP.RADIUS - 1, FP.RADIUS + 2):
            pert = img.copy()
            pert[y + dy, x + dx] += 50.0
            p = locate.refine(pert, cand, "patch_esf_fit", esf=tab)
            same = p.x[0] == base.x[0] and p.y[0] == base.y[0]
            inside = max(abs(dx), abs(dy)) <= FP.RADIUS and mask[FP.RADIUS + dy, FP.RADIUS + dx]
            assert inside or same, (dx, dy)
            moved_inside += inside and not same
    assert moved_inside > 0.9 * mask.sum()


def test_random_images_give_finite_points_inside(spread):
    """Flat, noise-only and tiny images (the property test of tests/test_properties.py, which leaves out the
    methods that need a camera): every point finite and inside the image."""
    tab = spread.tables()
    rng = np.random.default_rng(0)
    for k in range(12):
        h, w = rng.integers(3, 40, 2)
        kind = k % 3
        img = (np.full((h, w), 50.0) if kind == 0 else rng.normal(80, 30, (h, w)) if kind == 1
               else 40 + 120 * (np.arange(w)[None, :] > w / 2 + rng.normal(0, 3, (h, 1))))
        pts = locate.locate(img.astype(float), "patch_esf_fit", esf=tab, variance=(4.0, 0.25))
        n = len(pts)
        for a in (pts.x, pts.y, pts.nx, pts.ny):
            assert a.shape == (n,) and np.all(np.isfinite(a))
        assert np.all((pts.x >= 0) & (pts.x <= w - 1) & (pts.y >= 0) & (pts.y <= h - 1))
