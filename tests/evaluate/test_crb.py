"""The Cramér–Rao bound reproduces the brief's table and the closed form (BRIEF §6)."""
import numpy as np
import pytest

from edgetruth.evaluate.crb import continuous_mu_only_bound, position_std_bound, position_std_bound_many

# BRIEF §6, in units of sigma_n / B, edge centred in the window (mu = 0)
TABLE = {0.5: (1.39, 1.53, 1.64), 1.0: (1.92, 2.36, 2.79), 2.0: (2.68, 4.48, 7.67)}


@pytest.mark.parametrize("s", sorted(TABLE))
def test_bound_matches_the_brief_table(s):
    mu_only, w11, w7 = TABLE[s]
    assert position_std_bound(s, 1.0, 201, 0.0, "mu") == pytest.approx(mu_only, abs=0.006)
    assert position_std_bound(s, 1.0, 11, 0.0, "4p") == pytest.approx(w11, abs=0.006)
    assert position_std_bound(s, 1.0, 7, 0.0, "4p") == pytest.approx(w7, abs=0.006)


@pytest.mark.parametrize("s", [0.7, 1.0, 1.5, 3.0])
def test_mu_only_bound_matches_closed_form_for_a_long_row(s):
    # the closed form treats the pixel box as a Gaussian of variance 1/12: exact to ~0.5 % for s >= 0.7
    assert position_std_bound(s, 0.01, 401, 0.37, "mu") == pytest.approx(continuous_mu_only_bound(s, 0.01), rel=5e-3)


def test_bound_scales_with_noise_and_batches():
    a = position_std_bound_many([1.0, 1.0], [0.01, 0.02], [0.2, 0.2])
    assert a[1] == pytest.approx(2 * a[0])
    assert a[0] == pytest.approx(position_std_bound(1.0, 0.01, 11, 0.2))
    # fewer unknowns, smaller bound (off-centre: at mu = 0 the s column is orthogonal to mu's)
    assert position_std_bound(1.0, 1, 11, 0.3, "mu") < position_std_bound(1.0, 1, 11, 0.3, "2p") < position_std_bound(1.0, 1, 11, 0.3, "4p")


# ---------------------------------------------------------------- the footprint bound
from scipy.optimize import least_squares  # noqa: E402

from edgetruth import locate  # noqa: E402
from edgetruth.evaluate import crb  # noqa: E402
from edgetruth.locate import footprints as FP  # noqa: E402
from edgetruth.render.synthetic.analytic import StepProfile, step_image  # noqa: E402
from edgetruth.render.edge_truth import CircleEdge, StraightEdge  # noqa: E402
from edgetruth.render.synthetic.scenarios import render_edge_image  # noqa: E402

A_, B_ = 40.0, 120.0


@pytest.mark.parametrize("s_dark,s_bright", [(1.0, 1.0), (0.4, 1.3), (2.0, 0.7)])
def test_pixel_means_are_the_renderers_closed_form(s_dark, s_bright):
    """The bound's pixel model (numba) equals render.analytic's exact straight-edge pixel means (measured 1e-13)."""
    rng = np.random.default_rng(0)
    d = rng.uniform(-4, 4, 400)
    ang = rng.uniform(-np.pi, np.pi, 400)
    prof = StepProfile(s_dark, s_bright)
    for di, a in zip(d, ang):
        ref = prof.pixel_mean_straight(np.array([di]), np.cos(a), np.sin(a))[0]
        assert abs(crb.pixel_mean(di, np.cos(a), np.sin(a), s_dark, s_bright) - ref) < 1e-12


@pytest.mark.parametrize("blur", [0.5, 1.0, 2.0])
@pytest.mark.parametrize("bright_inside", [True, False])
def test_circle_pixel_means_match_the_renderers_quadrature(blur, bright_inside):
    """Circles: per-pixel tangent line with the in-pixel bend, against render's composite quadrature, radius
    12.5 px: measured max 2.0e-4 (blur 0.5), 3e-5 (blur 1) of the contrast.  Asserted < 5e-4."""
    e = CircleEdge(31.7, 32.2, 12.5, bright_inside)
    img = step_image((64, 64), e, StepProfile(blur, blur))
    for px, py in ((44.0, 32.0), (31.0, 20.0), (23.0, 41.0)):
        g = crb.edge_geometry(e, np.array([px]), np.array([py]))
        J, M = crb.footprint_jacobian(g, 0.0, 1.0, blur, blur, np.ones((1, FP.SIZE, FP.SIZE), bool))
        ref = img[int(py) - FP.RADIUS:int(py) + FP.RADIUS + 1, int(px) - FP.RADIUS:int(px) + FP.RADIUS + 1].ravel()
        assert np.abs(M[0] - ref).max() < 5e-4


@pytest.mark.parametrize("s", [0.5, 1.0, 2.0])
@pytest.mark.parametrize("mu", [0.0, 0.3, -0.45])
def test_axis_aligned_eleven_pixels_reproduce_the_reference_bound(s, mu):
    """An axis-aligned normal puts the 11 profile samples on pixel centres: the footprint is those 11 pixels,
    the rotation is unobservable (dropped), and the bound is BRIEF §6's 11-sample 4-unknown figure."""
    for angle in (0.0, np.pi / 2, np.pi):
        e = StraightEdge(30.0 + mu * np.cos(angle), 30.0 + mu * np.sin(angle), angle)
        cand = _cand_at(30.0, 30.0, np.cos(angle), np.sin(angle))
        mask = FP.profile_masks(cand, 5)
        assert mask.sum() == 11
        g = crb.edge_geometry(e, cand.x, cand.y)
        b = crb.footprint_bounds(g, A_, B_, s, s, {"p": mask}, noise_var=(0.01 * B_) ** 2)["p"][0]
        assert b == pytest.approx(position_std_bound(s, 0.01, 11, mu, "4p"), rel=1e-5)


def test_bound_scales_with_noise_and_signal_dependent_variance():
    e = StraightEdge(30.2, 29.9, 0.6)
    cand = _cand_at(30.0, 30.0, np.cos(0.6), np.sin(0.6))
    g = crb.edge_geometry(e, cand.x, cand.y)
    m = {"p": FP.profile_masks(cand, 5)}
    b1 = crb.footprint_bounds(g, A_, B_, 1.0, 1.0, m, noise_var=1.0)["p"]
    b2 = crb.footprint_bounds(g, A_, B_, 1.0, 1.0, m, noise_var=4.0)["p"]
    b3 = crb.footprint_bounds(g, A_, B_, 1.0, 1.0, m, variance_fn=lambda mean: np.full_like(mean, 4.0))["p"]
    assert b2 == pytest.approx(2 * b1) and b3 == pytest.approx(b2)
    # brighter pixels noisier (shot noise): the bound grows
    b4 = crb.footprint_bounds(g, A_, B_, 1.0, 1.0, m, variance_fn=lambda mean: 4.0 + 0.05 * mean)["p"]
    assert b4 > b2
    # more pixels, more information; more unknowns, less
    big = {"p": FP.block_masks(1, 5, 5)}
    assert crb.footprint_bounds(g, A_, B_, 1.0, 1.0, big, noise_var=4.0)["p"] < b2
    assert (crb.footprint_bounds(g, A_, B_, 1.5, 0.7, m, noise_var=4.0, blur_unknowns="both")["p"]
            > crb.footprint_bounds(g, A_, B_, 1.5, 0.7, m, noise_var=4.0)["p"])


def _cand_at(x, y, nx, ny):
    from edgetruth.locate.candidates import Candidates

    a = lambda v: np.array([float(v)])  # noqa: E731
    z = np.zeros((64, 64))
    return Candidates(a(x), a(y), a(nx), a(ny), a(1.0), (64, 64), 1.0, z, z, z)


def _ml_footprint_fit(img, edge, px, py, mask, s):
    """Maximum likelihood (least squares) of (rho, phi, A, B, s) from the footprint pixels alone, with
    render.analytic's pixel means: the efficient estimator the bound is about."""
    iy, ix = np.nonzero(mask)
    dy, dx = iy - FP.RADIUS, ix - FP.RADIUS
    y = img[int(py) + dy, int(px) + dx]
    c0, s0 = edge.normal

    def model(p):
        rho, phi, a, b, sb = p
        c, sn = np.cos(phi), np.sin(phi)
        return a + b * StepProfile(abs(sb), abs(sb)).pixel_mean_straight(dx * c + dy * sn + rho, c, sn)

    p0 = [float(edge.signed_distance(px, py)), float(np.arctan2(s0, c0)), A_, B_, s]
    return least_squares(lambda p: model(p) - y, p0, method="lm", xtol=1e-12).x[0]


@pytest.mark.slow
def test_monte_carlo_an_efficient_estimator_reaches_the_footprint_bound():
    """Straight noisy edges at random angles (blur 1, sigma_n/B = 0.02), the 11-sample profile's footprint
    (11 pixels on axis, 23-27 oblique): the ML fit over exactly those pixels has RMSE / bound = 1.022
    (measured, 1272 fits); asserted within [0.97, 1.10] -- the bound is attained, so it is neither too
    low nor too high."""
    rng = np.random.default_rng(5)
    err, bnd = [], []
    for k in range(24):
        e = StraightEdge(31.5 + rng.uniform(-1, 1), 31.5 + rng.uniform(-1, 1), rng.uniform(-np.pi, np.pi))
        clean = render_edge_image((64, 64), e, A_, B_, 1.0)
        cand = locate.candidates(clean)
        cand = cand.subset(np.abs(e.signed_distance(cand.x, cand.y)) <= 1.0)
        cand = cand.subset(np.arange(0, len(cand), 6))
        masks = FP.profile_masks(cand, 5)
        b = crb.footprint_bounds(crb.edge_geometry(e, cand.x, cand.y), A_, B_, 1.0, 1.0, {"p": masks},
                                 noise_var=(0.02 * B_) ** 2)["p"]
        for rep in range(4):
            img = clean + rng.normal(0, 0.02 * B_, clean.shape)
            for i in range(len(cand)):
                rho = _ml_footprint_fit(img, e, cand.x[i], cand.y[i], masks[i], 1.0)
                err.append(rho - e.signed_distance(cand.x[i], cand.y[i]))
                bnd.append(b[i])
    ratio = np.sqrt(np.mean(np.square(err)) / np.mean(np.square(bnd)))
    assert len(err) > 300
    assert 0.97 <= ratio <= 1.10, ratio


def _method_ratio(method, angles, reps=8, seed=1):
    rng = np.random.default_rng(seed)
    err, bnd = [], []
    for ang in angles:
        e = StraightEdge(31.5 + rng.uniform(-1, 1), 31.5 + rng.uniform(-1, 1), ang)
        clean = render_edge_image((64, 64), e, A_, B_, 1.0)
        cand = locate.candidates(clean)
        cand = cand.subset(np.abs(e.signed_distance(cand.x, cand.y)) <= 1.5)
        b = crb.footprint_bounds(crb.edge_geometry(e, cand.x, cand.y), A_, B_, 1.0, 1.0,
                                 {"m": locate.METHODS[method].footprint_masks(cand)}, noise_var=(0.02 * B_) ** 2)["m"]
        for _ in range(reps):
            pts = locate.refine(clean + rng.normal(0, 0.02 * B_, clean.shape), cand, method)
            ok = pts.converged
            err.append(e.signed_distance(pts.x, pts.y)[ok])
            bnd.append(b[ok])
    return float(np.sqrt(np.mean(np.concatenate(err) ** 2) / np.mean(np.concatenate(bnd) ** 2)))


def test_monte_carlo_the_4p_erf_fit_on_its_footprint():
    """erf4p_fixed11 on straight noisy edges.  Axis-aligned (its footprint is the 11 pixels it samples):
    measured RMSE / bound = 1.005, asserted within [0.97, 1.10].  Random angles: measured 1.39 -- the
    bilinear samples of an oblique profile mix 23-27 pixels into 11 values and lose their information;
    the bound counts the pixels, so the fit is not efficient there (asserted >= 0.97: it bounds)."""
    axis = _method_ratio("erf4p_fixed11", [0.0, np.pi / 2, np.pi, -np.pi / 2] * 6)
    assert 0.97 <= axis <= 1.10, axis
    oblique = _method_ratio("erf4p_fixed11", np.random.default_rng(3).uniform(-np.pi, np.pi, 24))
    assert 0.97 <= oblique, oblique


def test_every_builtin_method_declares_its_footprint():
    for m in locate.METHODS.values():
        if m.builtin:
            assert m.footprint is not None, m.id


def test_jacobian_kernel_gives_the_same_bits_on_one_thread():
    """On one numba thread the footprint Jacobian runs its serial copy (edgetruth.jit): the same bits."""
    numba = pytest.importorskip("numba")
    from edgetruth.backends import numba_threads

    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba runs on one thread here")
    rng = np.random.default_rng(2)
    xs, ys = rng.uniform(20.0, 44.0, 40), rng.uniform(20.0, 44.0, 40)
    geo = crb.edge_geometry(CircleEdge(32.0, 31.5, 9.0, True), xs, ys)
    union = np.ones((40, 11, 11), bool)
    out = []
    for threads in (2, 1):
        with numba_threads(threads):
            out.append(crb.footprint_jacobian(geo, 40.0, 120.0, 0.7, 0.9, union))
    for a, b in zip(*out):
        assert np.array_equal(a.view(np.int64), b.view(np.int64))
    assert crb._jacobian_kernel.serial.signatures and crb._jacobian_kernel.dispatcher.signatures


@pytest.mark.parametrize("n_pix", [1, 49, 121, 225, 1000])
def test_fisher_kernel_is_einsum_bit_for_bit(n_pix):
    """The Fisher sums of footprint_bounds: the kernel gives np.einsum's bits (zero weights off a mask,
    magnitudes over six decades)."""
    rng = np.random.default_rng(n_pix)
    wm = rng.random((60, n_pix)) * (rng.random((60, n_pix)) < 0.6)
    J = rng.normal(size=(60, n_pix, 5)) * 10.0 ** rng.uniform(-3, 3, (60, n_pix, 5))
    F = np.empty((60, 5, 5))
    crb._fisher_kernel(wm, J, F)
    assert np.array_equal(F.view(np.int64), np.einsum("np,npk,npl->nkl", wm, J, J).view(np.int64))
