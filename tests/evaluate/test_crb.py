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
