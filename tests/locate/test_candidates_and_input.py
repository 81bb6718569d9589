"""Stage 1 (Canny candidates) and the input contract of locate()."""
import numpy as np
import pytest

from edgetruth import locate
from edgetruth.locate.candidates import PROFILE_HALF, MASK_MARGIN_PX
from edgetruth.render.edge_truth import CircleEdge, StraightEdge
from edgetruth.render.synthetic.scenarios import render_edge_image


def circle_image(dtype=np.float64, scale=1.0):
    img = render_edge_image((64, 64), CircleEdge(31.7, 32.4, 17.3), 20, 200, 1.0)
    return (img * scale).round().astype(dtype) if dtype != np.float64 else img


def test_candidates_lie_on_the_edge_with_true_normals():
    truth = CircleEdge(31.7, 32.4, 17.3)
    cand = locate.candidates(circle_image())
    assert len(cand) > 80
    d = truth.signed_distance(cand.x, cand.y)
    assert np.all(np.abs(d) <= 1.0)
    tnx, tny = truth.normal_at(cand.x, cand.y)
    # normal from the smoothed gradient: within 2 degrees of the true radial normal
    assert np.all(cand.nx * tnx + cand.ny * tny > np.cos(np.radians(2)))
    assert np.allclose(np.hypot(cand.nx, cand.ny), 1.0)


def test_every_method_refines_the_same_candidates():
    img = circle_image()
    cand = locate.candidates(img)
    for m in ("erf4p_fixed5", "dynamic_erf_2p"):
        pts = locate.refine(img, cand, m)
        assert len(pts) == len(cand) and np.array_equal(pts.candidate_index, np.arange(len(cand)))


@pytest.mark.parametrize("dtype,scale", [(np.uint8, 1.0), (np.uint16, 250.0)])
def test_integer_images_never_wrap(dtype, scale):
    # an edge from 20 to 220 (uint8) has negative differences: they must not wrap
    img = circle_image(dtype, scale)
    a = locate.locate(img, "dynamic_erf_4p")
    b = locate.locate(img.astype(np.float64), "dynamic_erf_4p")
    assert len(a) > 80 and np.array_equal(a.x, b.x) and np.array_equal(a.y, b.y)
    truth = CircleEdge(31.7, 32.4, 17.3)
    assert np.sqrt(np.mean(truth.signed_distance(a.x, a.y) ** 2)) < 0.1  # rounding noise only


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_pixels_are_a_clear_value_error(bad):
    img = circle_image()
    img[3, 4] = bad
    with pytest.raises(ValueError, match="NaN or Inf"):
        locate.locate(img)


@pytest.mark.parametrize("shape", [(64,), (2, 64, 64), (64, 64, 3), (0, 0), (2, 2)])
def test_wrong_shapes_are_a_clear_value_error(shape):
    with pytest.raises(ValueError, match="image"):
        locate.locate(np.zeros(shape))


def test_non_numeric_arrays_are_rejected():
    with pytest.raises(ValueError, match="dtype"):
        locate.locate(np.full((10, 10), "a"))


@pytest.mark.parametrize("value", [0.0, 17.0, 255.0])
def test_flat_image_gives_zero_points(value):
    pts = locate.locate(np.full((50, 60), value, np.float64), "dynamic_erf_4p")
    assert len(pts) == 0 and pts.x.shape == (0,)


def test_unknown_method_is_a_value_error_listing_the_choices():
    with pytest.raises(ValueError, match="dynamic_erf_4p"):
        locate.locate(circle_image(), method="no_such_method")


def test_candidates_whose_window_leaves_the_image_are_dropped():
    # a vertical edge 2 px from the left border: Canny finds it, but the 11-sample
    # profile (5 px each side) would leave the image, so no point is returned
    img = render_edge_image((40, 40), StraightEdge(2.2, 20, 0.0), 10, 100, 0.8)
    assert len(locate.locate(img)) == 0
    # the same edge 8 px in is found along its whole length except near the top/bottom margin
    img = render_edge_image((40, 40), StraightEdge(8.2, 20, 0.0), 10, 100, 0.8)
    pts = locate.locate(img)
    assert len(pts) == 40 - 2 * MASK_MARGIN_PX
    assert np.all(pts.x - PROFILE_HALF >= 0)


def test_bad_options_are_value_errors():
    with pytest.raises(ValueError, match="sigma_px"):
        locate.candidates(circle_image(), sigma_px=-1)
    with pytest.raises(ValueError, match="thresholds"):
        locate.locate(circle_image(), "dynamic_erf_4p", tau=(0.9, 0.5, 0.1))
    with pytest.raises(ValueError, match="window"):
        from edgetruth.locate.methods.erf import erf_refine
        erf_refine(circle_image(), locate.candidates(circle_image()), True, window=6)


def test_points_are_finite_and_inside_the_image_even_on_noise():
    rng = np.random.default_rng(5)
    img = rng.normal(100, 20, (48, 48))
    for m in ("dynamic_erf_4p", "dynamic_erf_2p", "erf4p_fixed5"):
        pts = locate.locate(img, m)
        assert np.all(np.isfinite(pts.x)) and np.all(np.isfinite(pts.y))
        assert np.all((pts.x >= 0) & (pts.x <= 47) & (pts.y >= 0) & (pts.y <= 47))
