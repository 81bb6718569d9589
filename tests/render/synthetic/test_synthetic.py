"""Synthetic scenarios: reproducible, split-disjoint, with exact ground truth."""
import numpy as np
import pytest

from edgetruth.render.edge_truth import CircleEdge, StraightEdge
from edgetruth.render.synthetic.scenarios import SCENARIOS, SPLIT_ID, seed_sequence, synthetic_image


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_same_split_and_index_give_identical_images(scenario):
    a = synthetic_image(scenario, 3)
    b = synthetic_image(scenario, 3)
    assert np.array_equal(a.image, b.image) and a.truth == b.truth


def test_calibration_and_test_splits_never_share_a_seed():
    cal = {tuple(seed_sequence("calibration", s, i).generate_state(4)) for s in SCENARIOS for i in range(500)}
    test = {tuple(seed_sequence("test", s, i).generate_state(4)) for s in SCENARIOS for i in range(500)}
    assert len(cal) == 2000 and len(test) == 2000 and not (cal & test)
    assert len(set(SPLIT_ID.values())) == len(SPLIT_ID)


def test_kind_alternates_and_truth_types():
    assert isinstance(synthetic_image("ideal", 0).truth, StraightEdge)
    assert isinstance(synthetic_image("ideal", 1).truth, CircleEdge)


def test_noise_free_ideal_image_equals_step_model():
    s = synthetic_image("ideal", 0, noise_rel=0.0)
    A, B = s.params["A"], s.params["B"]
    assert s.image.min() >= A - 1e-9 and s.image.max() <= A + B + 1e-9
    # far from the edge the image is the plateau value to double precision
    y, x = np.mgrid[0:64, 0:64]
    d = s.truth.signed_distance(x, y)
    assert np.allclose(s.image[d > 12], A + B) and np.allclose(s.image[d < -12], A)


def test_noise_has_the_requested_sigma():
    a = synthetic_image("ideal", 0, noise_rel=0.0, shape=(200, 200))
    b = synthetic_image("ideal", 0, noise_rel=0.02, shape=(200, 200))
    sd = np.std(b.image - a.image)
    assert sd == pytest.approx(0.02 * a.params["B"], rel=0.03)


def test_asymmetric_blurs_differ_and_keep_half_value_on_the_edge():
    s = synthetic_image("asymmetric", 0, noise_rel=0.0)
    assert s.params["s_dark"] != pytest.approx(s.params["s_bright"], rel=0.2)
