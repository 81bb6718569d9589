"""GLM1984 (locate/methods/glm1984.py): Tabatabai-Mitchell moment-preserving step, as a specification.

Known behaviour: the three-moment step is *exact* for a profile that is itself a
sampled step (n1 samples at h1, n2 at h2); for a symmetric blurred edge centred
in the window it gives p1 = 1/2 exactly (skewness 0); off centre, the window
truncates one blur tail more than the other, which biases the estimate toward
the window centre.  With the 11-sample window and blur ~1 px (profile width
S = sqrt(1 + 1/12) ~ 1.04 px, tails below 1e-4 at 4 S) the truncation is small.
"""
import math

import numpy as np
import pytest

from edgetruth.locate.methods.glm1984 import glm1984
from tests.support.edge_scenes import run_method, stats


class _Cand:
    """A one-point candidate set on a 1-row image (enough for the kernel)."""

    def __init__(self, x):
        self.x = np.array([float(x)])
        self.y = np.array([0.0])
        self.nx = np.array([1.0])
        self.ny = np.array([0.0])

    def __len__(self):
        return 1


@pytest.mark.parametrize("n_dark", [3, 4, 5, 6, 7, 8])
def test_exact_on_a_sampled_step(n_dark):
    """A profile of n_dark samples at h1 and 11 - n_dark at h2 is a moment-preserving
    step itself: p1 = n_dark / 11 and the edge is at the cell boundary t = n_dark - 5.5."""
    row = np.array([[10.0] * (5 + n_dark) + [90.0] * (11 - n_dark + 5)])
    img = np.vstack([row, row])
    r = glm1984(img, _Cand(10))
    assert r.converged[0]
    assert abs(r.extras["p1"][0] - n_dark / 11) < 1e-12
    assert abs(r.x[0] - (10 + n_dark - 5.5)) < 1e-12
    assert abs(r.extras["h1"][0] - 10) < 1e-9 and abs(r.extras["h2"][0] - 90) < 1e-9


def test_flat_profile_is_not_converged():
    img = np.full((2, 30), 7.0)
    r = glm1984(img, _Cand(10))
    assert not r.converged[0] and r.x[0] == 10.0


def test_ideal_straight_edges():
    """Noise-free straight edges, blur 1 px, 12 random angles/offsets, 11-sample window.
    Measured: |mean| = 0.0000 px, RMSE = 0.0044 px.  Asserted: RMSE < 0.012, |mean| < 0.003."""
    e, conv = run_method("glm1984", "line", range(12))
    mean, rmse = stats(e)
    assert conv == 1.0
    assert rmse < 0.012, rmse
    assert mean < 0.003, mean


def test_ideal_circles():
    """Circles, radius 12-20 px, blur 1 px: the profile along the normal of a curved edge is
    slightly asymmetric (curvature), adding a little to the error.
    Measured: |mean| = 0.0004, RMSE = 0.0074.  Asserted: RMSE < 0.015, |mean| < 0.004."""
    e, conv = run_method("glm1984", "circle", range(6))
    mean, rmse = stats(e)
    assert conv == 1.0
    assert rmse < 0.015, rmse
    assert mean < 0.004, mean


def test_shorter_window_truncates_more():
    """half=3 (7 samples) cuts the blur tails: larger bias than the default 11 samples."""
    r5 = stats(run_method("glm1984", "line", range(12))[0])[1]
    r3 = stats(run_method("glm1984", "line", range(12), half=3)[0])[1]
    assert r3 > 2 * r5


def test_error_grows_linearly_with_noise():
    """RMSE at sigma_n/B = 0.02 is many times the noise-free value (an 11-sample moment
    estimate integrates the noise of every sample), and the noise part
    sqrt(RMSE^2 - RMSE_0^2) doubles from 0.01 to 0.02: to first order t_e is a
    smooth function of the samples, linear in small noise.
    Measured (24 lines): RMSE 0.0046, 0.0208, 0.0410 at 0, 0.01, 0.02; noise part ratio 2.01."""
    seeds = range(24)
    r0 = stats(run_method("glm1984", "line", seeds)[0])[1]
    r1 = stats(run_method("glm1984", "line", seeds, noise_rel=0.01)[0])[1]
    r2 = stats(run_method("glm1984", "line", seeds, noise_rel=0.02)[0])[1]
    assert r2 > 4.0 * r0, (r0, r2)
    n1, n2 = math.sqrt(r1 ** 2 - r0 ** 2), math.sqrt(r2 ** 2 - r0 ** 2)
    assert 1.6 < n2 / n1 < 2.4, (n1, n2)
