"""The lens blur a twin renders with, from the ERF σ a photo shows (``blur_inverse``): the forward model against its
analytic limits, and the inverse against the forward model."""
from __future__ import annotations

import math

import numpy as np
import pytest

from edgetruth.evaluate.board.twin import blur_inverse as bi

#: f/4, 6 µm pixels, 550 nm (``TwinAssumptions``' defaults): the diffraction cutoff p / (λN) in cy/px
CUTOFF = 6.0 / (0.55 * 4.0)


def test_a_wide_gaussian_reads_as_itself_with_the_pixel():
    """Without diffraction a Gaussian of 2 px through the pixel box is nearly Gaussian: ERF σ² = 4 + 1/12 to 1e-3."""
    assert bi.erf_sigma_px(2.0, math.inf) == pytest.approx(math.sqrt(4.0 + 1.0 / 12.0), abs=1e-3)


def test_the_airy_tails_widen_the_erf_beyond_the_core():
    """At f/4, 6 µm, 550 nm the Airy core is a Gaussian of 0.154 px; taken off in quadrature with the pixel, an
    ERF σ of 0.78 px leaves σ_ab 0.708, which renders 0.83 px: the tails add about twice what the core does."""
    quadrature = math.sqrt(0.78 ** 2 - 1.0 / 12.0 - 0.154 ** 2)
    assert bi.erf_sigma_px(quadrature, CUTOFF) == pytest.approx(0.8315, abs=2e-3)
    assert bi.aberration_sigma_px(0.78, CUTOFF) == pytest.approx(0.650, abs=2e-3)


@pytest.mark.parametrize("sigma_ab, defocus, gamma", [(0.3, 0.0, 1.0), (0.7, 0.1, 1.0), (1.5, 0.5, 1.0),
                                                      (0.7, 0.0, 2.2)])
def test_the_inverse_returns_the_aberration(sigma_ab, defocus, gamma):
    """``aberration_sigma_px`` undoes ``erf_sigma_px`` to 1e-5 px, with defocus and through a tone curve."""
    s = bi.erf_sigma_px(sigma_ab, CUTOFF, defocus, 10.0 ** gamma, gamma)
    assert bi.aberration_sigma_px(s, CUTOFF, defocus, 10.0 ** gamma, gamma) == pytest.approx(sigma_ab, abs=1e-5)


def test_an_edge_sharper_than_the_optics_takes_no_aberration():
    """The pixel and the diffraction alone read 0.39 px: a sharper photo gets σ_ab = 0 (not a negative one)."""
    floor = bi.erf_sigma_px(0.0, CUTOFF)
    assert 0.38 < floor < 0.40
    assert bi.aberration_sigma_px(floor - 0.05, CUTOFF) == 0.0 and bi.aberration_sigma_px(math.nan, CUTOFF) == 0.0


def test_a_linear_output_ignores_the_contrast():
    assert bi.erf_sigma_px(0.7, CUTOFF, 0.0, 5.0, 1.0) == bi.erf_sigma_px(0.7, CUTOFF, 0.0, 50.0, 1.0)

