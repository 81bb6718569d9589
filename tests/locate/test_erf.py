"""The ERF family (fixed windows and the entropy-guided dynamic window) against analytic truth."""
import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.special import ndtr

from edgetruth import locate
from edgetruth.evaluate.crb import position_std_bound_many
from edgetruth.locate import erf_kernels as K
from edgetruth.render.edge_truth import StraightEdge
from edgetruth.render.synthetic.scenarios import render_edge_image

ERF_IDS = [f"erf{m}_fixed{w}" for m in ("2p", "4p") for w in (5, 7, 9, 11)] + ["dynamic_erf_2p", "dynamic_erf_4p"]


def test_all_erf_methods_are_registered():
    assert set(ERF_IDS) <= set(locate.METHODS)
    assert locate.METHODS["dynamic_erf_4p"].label == "ProposedDynamicERF_4P"


def ideal_line_errors(method, n_images=24, noise_rel=0.0, seed=0, shape=(48, 48)):
    rng = np.random.default_rng(seed)
    errs = []
    for _ in range(n_images):
        e = StraightEdge(shape[1] / 2 + rng.uniform(-1, 1), shape[0] / 2 + rng.uniform(-1, 1), rng.uniform(-np.pi, np.pi))
        img = render_edge_image(shape, e, 30.0, 150.0, rng.uniform(0.6, 2.0), noise_sigma=noise_rel * 150, rng=rng)
        pts = locate.locate(img, method)
        assert len(pts) > 20 and pts.converged.all()
        errs.append(e.signed_distance(pts.x, pts.y))
    return np.concatenate(errs)


def test_erf4p_fixed11_is_unbiased_on_noise_free_ideal_edges():
    """Spec: blur 0.6-2.0 px, random angle/offset, no noise -> |mean| and RMSE <= 0.02 px.
    (What remains is the bilinear sampling of oblique profiles and the ERF vs
    pixel-integrated-ERF model difference.)"""
    e = ideal_line_errors("erf4p_fixed11")
    assert abs(e.mean()) <= 0.02
    assert np.sqrt(np.mean(e**2)) <= 0.02


@pytest.mark.parametrize("method,rmse_bound", [("dynamic_erf_4p", 0.03), ("erf4p_fixed7", 0.03), ("erf2p_fixed11", 0.03),
                                               ("dynamic_erf_2p", 0.08)])
def test_other_erf_variants_are_accurate_without_noise(method, rmse_bound):
    """Without noise every variant is unbiased on average (symmetric profiles).  2P fixes A, B at the
    window's extrema: on a short window around an off-centre blurred edge the two extrema are cut
    unequally far down the transition, which pulls mu towards the centre (measured RMSE: erf2p_fixed5
    0.164, fixed7 0.086, fixed11 0.012 px).  The calibrated thresholds send many edges to 5/7-sample
    windows, so dynamic_erf_2p measures 0.059 px; the 4P variants measure <= 0.007 px."""
    e = ideal_line_errors(method, n_images=12, seed=1)
    assert abs(e.mean()) <= 0.02 and np.sqrt(np.mean(e**2)) <= rmse_bound


def axis_aligned_noisy(method, noise_rel=0.0125, blur=1.0, n_images=16, seed=7):
    """Vertical and horizontal edges at random subpixel offsets; returns errors, se, CRB per point."""
    rng = np.random.default_rng(seed)
    errs, ses, crbs = [], [], []
    for i in range(n_images):
        angle = [0.0, np.pi / 2, np.pi, -np.pi / 2][i % 4]
        e = StraightEdge(40 + rng.uniform(-0.5, 0.5), 40 + rng.uniform(-0.5, 0.5), angle)
        img = render_edge_image((80, 80), e, 40.0, 160.0, blur, noise_sigma=noise_rel * 160, rng=rng)
        cand = locate.candidates(img)
        d_cand = e.signed_distance(cand.x, cand.y)
        cand = cand.subset(np.abs(d_cand) <= 1.0)
        pts = locate.refine(img, cand, method)
        errs.append(e.signed_distance(pts.x, pts.y))
        ses.append(pts.se)
        crbs.append(position_std_bound_many(blur, noise_rel, -e.signed_distance(cand.x, cand.y), 11, "4p"))
    return np.concatenate(errs), np.concatenate(ses), np.concatenate(crbs)


def test_erf4p_fixed11_reaches_the_cramer_rao_bound():
    """Spec: RMSE <= 1.15 x the 11-sample 4P CRB computed for the same offsets (BRIEF §6)."""
    err, _, crb = axis_aligned_noisy("erf4p_fixed11")
    assert err.size > 1000
    rmse = np.sqrt(np.mean(err**2))
    bound = np.sqrt(np.mean(crb**2))
    assert 0.8 * bound < rmse <= 1.15 * bound, (rmse, bound)


@pytest.mark.parametrize("method", ["erf4p_fixed11", "dynamic_erf_4p"])
def test_standard_errors_are_honest(method):
    """93-97 % of points fall within 1.96 se of the truth."""
    err, se, _ = axis_aligned_noisy(method, seed=11)
    assert np.all(np.isfinite(se)) and np.all(se > 0)
    cover = np.mean(np.abs(err) <= 1.96 * se)
    assert 0.93 <= cover <= 0.97, cover


def test_kernel_agrees_with_scipy_least_squares():
    rng = np.random.default_rng(3)
    t = np.arange(11) - 5.0
    profiles = np.array([20 + 100 * ndtr((t - rng.uniform(-1, 1)) / rng.uniform(0.5, 2)) + rng.normal(0, 2, 11)
                         for _ in range(40)])
    for four, w in [(True, 11), (True, 7), (False, 9), (False, 5)]:
        windows = np.full(len(profiles), w, np.int64)
        out = np.empty((len(profiles), 8))
        K.fit_profiles(profiles, windows, four, 50, 1e-5, out)
        half = (w - 1) // 2
        tt = t[5 - half:6 + half]
        for prof, o in zip(profiles, out):
            y = prof[5 - half:6 + half]
            if four:
                res = least_squares(lambda p: p[0] + p[1] * ndtr((tt - p[2]) / p[3]) - y, o[:4] * [1, 1, 1, 1.01] + [0.5, -0.5, 0.05, 0],
                                    method="lm", xtol=1e-14, ftol=1e-14)
                mu = res.x[2]
            else:
                A, B = y.min(), y.max() - y.min()
                res = least_squares(lambda p: A + B * ndtr((tt - p[0]) / p[1]) - y, [o[2] + 0.05, o[3] * 1.01],
                                    method="lm", xtol=1e-14, ftol=1e-14)
                mu = res.x[0]
            assert o[7] == K.OK
            assert mu == pytest.approx(o[2], abs=2e-6)  # A&S erfc (1.5e-7) + stopping rule


def test_normalised_entropy_limits():
    step = np.array([0.0] * 5 + [1.0] * 6)  # all gradient in one interval
    ramp = np.arange(11.0)  # gradient spread evenly over M = 10 intervals
    assert K.normalised_entropy(step) == pytest.approx(0.0)
    assert K.normalised_entropy(ramp) == pytest.approx(1.0)
    assert np.isnan(K.normalised_entropy(np.ones(11)))


def test_window_follows_the_thresholds():
    tau = (0.3, 0.5, 0.7)
    assert [K.window_from_entropy(h, *tau) for h in (0.1, 0.3, 0.45, 0.5, 0.69, 0.7, 0.95)] == [5, 7, 7, 9, 9, 11, 11]
    rng = np.random.default_rng(0)
    img = render_edge_image((64, 64), StraightEdge(31.6, 30.2, 0.4), 20, 100, 1.2, noise_sigma=2, rng=rng)
    pts = locate.locate(img, "dynamic_erf_4p", tau=tau)
    expected = [K.window_from_entropy(h, *tau) for h in pts.entropy]
    assert list(pts.window) == expected


def test_fixed_window_fields():
    img = render_edge_image((40, 40), StraightEdge(19.3, 20, 0.2), 10, 200, 1.0)
    pts = locate.locate(img, "erf4p_fixed9")
    assert set(["A", "B", "s", "window", "entropy", "se", "converged"]) <= set(pts.columns())
    assert np.all(pts.window == 9)
    # s of a pixel-integrated blur-1 edge: sqrt(1 + 1/12) = 1.04 along the normal (to sampling error)
    assert np.median(pts.s) == pytest.approx(np.sqrt(1 + 1 / 12), abs=0.05)
    assert np.median(pts.A) == pytest.approx(10, abs=1) and np.median(pts.B) == pytest.approx(200, abs=2)
