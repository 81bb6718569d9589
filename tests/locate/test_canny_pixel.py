"""CannyPixel (locate/methods/canny_pixel.py): the candidate pixel centre, as a specification.

Known behaviour: the output is a lattice point, so on a straight edge its error
is the distance from the pixel chosen by Canny's non-maximum suppression to the
edge.  OpenCV's NMS compares neighbours along the gradient direction quantised
to 0/45/90/135 degrees, with lattice step L_q = 1 (axis) or sqrt(2) (diagonal).
The kept pixel is the one nearest the edge along that direction, so its
distance along the normal is ~uniform on +-L_q |cos(theta - q)| / 2 and

    RMSE^2 = mean over points of (L_q cos(theta - q))^2 / 12,

1/sqrt(12) = 0.289 px for axis-aligned edges, up to 0.38 px near 22.5 degrees.
"""
import numpy as np

from edgetruth.locate import refine
from edgetruth.locate.candidates import candidates
from edgetruth.render.synthetic.scenarios import render_edge_image
from tests.support.edge_scenes import A_LEVEL, B_CONTRAST, NEAR_PX, SHAPE_64 as SHAPE, make_edge, run_method, stats


def quantisation_rmse(edges_and_counts):
    """The uniform-quantisation prediction above for straight edges, weighted by point counts."""
    num = den = 0.0
    for edge, n in edges_and_counts:
        th = np.mod(edge.angle_rad, np.pi / 2)
        q = np.round(th / (np.pi / 4)) * np.pi / 4
        step = np.sqrt(2.0) if np.isclose(q, np.pi / 4) else 1.0
        num += n * (step * np.cos(th - q)) ** 2 / 12.0
        den += n
    return np.sqrt(num / den)


def test_returns_the_candidate_pixels_unchanged():
    edge = make_edge("line", 0)
    img = render_edge_image(SHAPE, edge, A_LEVEL, B_CONTRAST, 1.0)
    cand = candidates(img)
    pts = refine(img, cand, "canny_pixel")
    assert np.array_equal(pts.x, cand.x) and np.array_equal(pts.y, cand.y)
    assert pts.converged.all() and np.array_equal(pts.nx, cand.nx)


def test_ideal_straight_edges_match_the_quantisation_prediction():
    """Noise-free Ideal straight edges, blur 1 px, 20 random angles/offsets.

    Measured: |mean| = 0.002 px, RMSE = 0.368 px; the prediction above for the same
    angles agrees to < 1 %.  Asserted: RMSE within 5 % of the prediction (NMS is not
    exactly "nearest lattice point"), |mean| < 0.03 (random offsets, no bias)."""
    seeds = range(20)
    e, conv = run_method("canny_pixel", "line", seeds)
    counts = []
    for s in seeds:
        edge = make_edge("line", s)
        cand = candidates(render_edge_image(SHAPE, edge, A_LEVEL, B_CONTRAST, 1.0))
        counts.append((edge, int((np.abs(edge.signed_distance(cand.x, cand.y)) <= NEAR_PX).sum())))
    mean, rmse = stats(e)
    pred = quantisation_rmse(counts)
    assert conv == 1.0
    assert abs(rmse / pred - 1.0) < 0.05, (rmse, pred)
    assert mean < 0.03


def test_ideal_circles_have_quantisation_error():
    """Noise-free circles (radius 12-20 px), blur 1 px: every direction occurs, so the
    angle-averaged prediction applies: sqrt(<(L_q cos)^2>/12) = 0.345 px.
    Measured: |mean| = 0.022, RMSE = 0.356.  Asserted: RMSE in 0.345 +- 10 %, |mean| < 0.05."""
    e, conv = run_method("canny_pixel", "circle", range(6))
    mean, rmse = stats(e)
    assert 0.31 < rmse < 0.38, rmse
    assert mean < 0.05


def test_noise_barely_changes_the_pixel_error():
    """At sigma_n/B = 0.02 the error is still dominated by the +-0.5 px quantisation:
    noise moves the gradient maximum to a neighbouring pixel only rarely.  Expected:
    RMSE within 10 % of the noise-free value (measured 0.368 -> 0.369) -- the
    "growth with noise" of this method is nil by construction."""
    e0, _ = run_method("canny_pixel", "line", range(20))
    e2, _ = run_method("canny_pixel", "line", range(20), noise_rel=0.02)
    r0, r2 = stats(e0)[1], stats(e2)[1]
    assert abs(r2 / r0 - 1.0) < 0.10, (r0, r2)
