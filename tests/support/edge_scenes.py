"""Synthetic edge scenes shared by the baseline method specifications in tests/locate/.

Every scene is an exact pixel-integrated edge (render.synthetic.render_edge_image),
dark level A_LEVEL = 40, contrast B_CONTRAST = 120, refined on the shared Canny
candidates whose pixel centre lies within NEAR_PX = 1.5 px of the true edge; the
error of a point is edge.signed_distance(x, y).  Two settings are in use, and
each is reproduced bit for bit so that the numbers measured in the tests'
docstrings stay true:

* 64x64 (test_canny_pixel, test_canny_devernay, test_glm1984,
  test_canny_zernike2020, test_pae2013): ``make_edge(kind, seed)`` draws from
  default_rng([0xED6E, seed]), circle radii 12-20 px, bright inside for even
  seeds; noise from default_rng([0x401E, seed]) -- ``run_method``,
  ``noise_displacement``.
* 48x48 (test_hagara_aef2011, test_gaussian_fit2014, test_arctan_fit2016,
  test_sigmoid_logistic_fit2023, test_ser_cis): ``straight(seed)`` draws from
  default_rng(1000 + seed), ``circle(seed)`` from default_rng(2000 + seed),
  radii 12-16 px, bright inside for odd seeds; blur BLUR = 1 px; noise from
  default_rng(seed) -- ``scored``, ``errors``, ``rmse_at``.
"""
import numpy as np
from scipy.optimize import least_squares

from edgetruth.locate import refine
from edgetruth.locate.candidates import candidates
from edgetruth.locate.profiles import profile_offsets, sample_profiles
from edgetruth.render.edge_truth import CircleEdge, StraightEdge
from edgetruth.render.synthetic.scenarios import render_edge_image

A_LEVEL, B_CONTRAST = 40.0, 120.0
BLUR = 1.0
NEAR_PX = 1.5  # candidates whose pixel centre lies within 1.5 px of the true edge
SHAPE_64 = (64, 64)
SHAPE_48 = (48, 48)


# ---- building blocks ----
def _centre(shape, rng):
    """The image centre moved by up to +-1 px in x and y (x drawn first)."""
    return shape[1] / 2 - 0.5 + rng.uniform(-1, 1), shape[0] / 2 - 0.5 + rng.uniform(-1, 1)


def straight_edge(shape, seed):
    """A straight edge near the centre of ``shape`` at a uniform angle; ``seed`` is
    anything np.random.default_rng accepts (draws: x offset, y offset, angle)."""
    rng = np.random.default_rng(seed)
    cx, cy = _centre(shape, rng)
    return StraightEdge(cx, cy, rng.uniform(-np.pi, np.pi))


def circle_edge(shape, seed, radius_range, bright_inside):
    """A circle near the centre of ``shape``, radius uniform in ``radius_range``
    (draws: x offset, y offset, radius)."""
    rng = np.random.default_rng(seed)
    cx, cy = _centre(shape, rng)
    return CircleEdge(cx, cy, rng.uniform(*radius_range), bright_inside)


def render(shape, edge, blur, noise_rel=0.0, rng=None):
    """A_LEVEL + B_CONTRAST * step, Gaussian blur ``blur`` px, noise sigma_n = noise_rel * B_CONTRAST."""
    return render_edge_image(shape, edge, A_LEVEL, B_CONTRAST, blur, noise_sigma=noise_rel * B_CONTRAST, rng=rng)


def near_candidates(img, edge, near_px=NEAR_PX):
    """The Canny candidates of ``img`` whose pixel centre lies within ``near_px`` of the true edge."""
    cand = candidates(img)
    return cand.subset(np.abs(edge.signed_distance(cand.x, cand.y)) <= near_px)


def refine_near_edge(img, edge, method, **opts):
    """(near candidates, EdgePoints of ``method`` refined on them)."""
    cand = near_candidates(img, edge)
    return cand, refine(img, cand, method, **opts)


def stats(e):
    """(|mean|, RMSE) of the errors ``e``."""
    return abs(float(e.mean())), float(np.sqrt(np.mean(e * e)))


# ---- the 64x64 setting ----
def make_edge(kind, seed):
    """"line" or "circle" number ``seed`` of the 64x64 setting."""
    key = [0xED6E, seed]
    if kind == "line":
        return straight_edge(SHAPE_64, key)
    return circle_edge(SHAPE_64, key, (12.0, 20.0), seed % 2 == 0)


def run_method(method, kind, seeds, blur=1.0, noise_rel=0.0, **opts):
    """Errors (signed distance to the true edge, px) of the converged points, and the converged fraction."""
    errs, conv = [], []
    for seed in seeds:
        edge = make_edge(kind, seed)
        img = render(SHAPE_64, edge, blur, noise_rel, rng=np.random.default_rng([0x401E, seed]))
        _, pts = refine_near_edge(img, edge, method, **opts)
        errs.append(edge.signed_distance(pts.x, pts.y)[pts.converged])
        conv.append(pts.converged)
    e = np.concatenate(errs)
    return e, float(np.concatenate(conv).mean())


def noise_displacement(method, noise_rel, seeds, converged_only=False, **opts):
    """RMS per-point displacement caused by noise alone on straight edges (blur 1 px):
    the noisy image refined on the noise-free image's candidates (the method reads
    the image, not cand.smoothed).  ``converged_only``: score only the points that
    converge on both images."""
    out = []
    for seed in seeds:
        edge = make_edge("line", seed)
        clean = render(SHAPE_64, edge, 1.0)
        noisy = clean + np.random.default_rng([0x401E, seed]).normal(0, noise_rel * B_CONTRAST, SHAPE_64)
        cand, p0 = refine_near_edge(clean, edge, method, **opts)
        p1 = refine(noisy, cand, method, **opts)
        d = edge.signed_distance(p1.x, p1.y) - edge.signed_distance(p0.x, p0.y)
        out.append(d[p0.converged & p1.converged] if converged_only else d)
    return float(np.sqrt(np.mean(np.concatenate(out) ** 2)))


# ---- the 48x48 setting ----
def straight(seed):
    """Straight edge number ``seed`` of the 48x48 setting."""
    return straight_edge(SHAPE_48, 1000 + seed)


def circle(seed):
    """Circle number ``seed`` of the 48x48 setting."""
    return circle_edge(SHAPE_48, 2000 + seed, (12, 16), bool(seed % 2))


def scored(method, edge, noise_rel=0.0, seed=0, **options):
    """(image, near candidates, EdgePoints) for one rendered edge."""
    img = render(SHAPE_48, edge, BLUR, noise_rel, rng=np.random.default_rng(seed))
    cand, pts = refine_near_edge(img, edge, method, **options)
    return img, cand, pts


def errors(method, edge, **kw):
    """Signed errors of every point; all of them must converge."""
    _, _, pts = scored(method, edge, **kw)
    assert pts.converged.all()
    return edge.signed_distance(pts.x, pts.y)


def rmse_at(method, noise_rel, **options):
    """RMSE over straight edges 0-3, three noise draws each (seeds 10 s + rep + 1)."""
    e = np.concatenate([errors(method, straight(s), noise_rel=noise_rel, seed=10 * s + rep + 1, **options)
                        for s in range(4) for rep in range(3)])
    return np.sqrt(np.mean(e ** 2))


def assert_flat_region_not_converged(method, **options):
    """A profile without contrast cannot be refined: on a flat image, the near
    candidates of straight(0) all come back converged=False at their candidate pixel."""
    img, cand, _ = scored(method, straight(0))
    pts = refine(np.full_like(img, 50.0), cand, method, **options)
    assert not pts.converged.any()
    np.testing.assert_array_equal(pts.x, cand.x)
    np.testing.assert_array_equal(pts.y, cand.y)


def lm_reference_fits(method, model, initial, differences=False):
    """``method`` on the noisy straight(1) edge (sigma_n/B = 0.01, seed 3) and, for
    every ~6th point, scipy's LM minimum of model(t, p) - y on the point's profile y
    at the offsets t (``differences``: on the profile's differences, at the midpoints
    of the offsets), started from initial(t, y).  Returns (EdgePoints, [(i, p_ref), ...])."""
    img, cand, pts = scored(method, straight(1), noise_rel=0.01, seed=3)
    prof = sample_profiles(img, cand)
    t = profile_offsets()
    if differences:
        prof, t = np.diff(prof, axis=1), 0.5 * (t[1:] + t[:-1])
    refs = []
    for i in range(0, len(cand), max(1, len(cand) // 6)):
        y = prof[i]

        def res(p):
            return model(t, p) - y

        ref = least_squares(res, initial(t, y), method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=10000)
        refs.append((i, ref.x))
    return pts, refs
