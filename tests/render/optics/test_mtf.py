"""The analytic MTF module and the sampling table built from it."""
from __future__ import annotations

import math

import numpy as np
import pytest

from edgetruth.render.optics import mtf
from edgetruth.render.optics.psf import FIELD_LEVELS, PsfParams, psf_table, table_otf_x


def test_factors_at_known_values():
    assert mtf.diffraction_mtf(np.array([0.0, 1.0, 2.0]), 1.0).tolist() == [1.0, 0.0, 0.0]
    # half the cutoff: (2/pi)(acos(1/2) - (1/2) sqrt(3/4)) = 0.3910
    assert mtf.diffraction_mtf(0.5, 1.0) == pytest.approx(0.39100221, abs=1e-8)
    assert mtf.diffraction_cutoff_cy_px(4.8, 550.0, 4.0) == pytest.approx(4.8 / (0.55 * 4.0))
    assert mtf.defocus_otf(0.0, 2.0) == 1.0
    # first zero of 2 J1(x)/x at x = 3.8317: nu = 3.8317 / (2 pi r)
    assert abs(mtf.defocus_otf(3.8317060 / (2 * math.pi * 1.5), 1.5)) < 1e-6
    # Gaussian: MTF50 = sqrt(ln 2 / 2) / (pi sigma) = 0.1874 / sigma (BRIEF 7)
    assert mtf.mtf50(lambda nu: mtf.gaussian_mtf(nu, 0.8)) == pytest.approx(0.18739 / 0.8, rel=1e-4)
    assert mtf.mtf50(lambda nu: np.sinc(nu)) == pytest.approx(0.6034, abs=1e-4)  # the bare pixel


@pytest.mark.parametrize("params,tol", [
    (PsfParams(mtf.diffraction_cutoff_cy_px(4.8, 550, 4), 2.13 / 4.8, 0.6, 0.0), 0.008),  # default lens
    (PsfParams(mtf.diffraction_cutoff_cy_px(4.8, 550, 16), 0.0, 0.0, 0.0), 0.012),  # f/16: 1 % tail dropped
    (PsfParams(math.inf, 0.6, 0.0, 0.0), 1e-6),  # a Gaussian has no tail to drop
    (PsfParams(mtf.diffraction_cutoff_cy_px(4.8, 550, 4), 1.0 / 4.8, 0.0, 3.0 / 4.8), 0.01),  # with an OLPF
])
def test_the_sampled_kernel_has_the_analytic_otf(params, tol):
    """The bilinear table the sensor samples reproduces pixel x PSF up to Nyquist at every field
    level, but for the renormalised Airy tail beyond the table (AIRY_TAIL_LOSS)."""
    table = psf_table(params)
    assert table.density.min() >= 0
    nu = np.linspace(0, 0.5, 51)
    levels = range(len(table.field_heights_sq))
    assert len(levels) == (FIELD_LEVELS if params.field_dependent else 1)
    for lv in levels:
        h = math.sqrt(table.field_heights_sq[lv])
        err = np.abs(table_otf_x(table, lv, nu) - params.otf(nu, 0 * nu, h))
        assert err.max() < tol, (lv, err.max())


def test_negligible_psf_is_not_sampled():
    assert psf_table(PsfParams(math.inf, 0.0, 0.0, 0.0)) is None
    # 20 mm pixels: the Airy pattern is 1e-4 of a pixel, its OTF within 7e-5 of 1 at Nyquist
    assert psf_table(PsfParams(mtf.diffraction_cutoff_cy_px(2e4, 550, 4), 0.0, 0.0, 0.0)) is None
    assert psf_table(PsfParams(mtf.diffraction_cutoff_cy_px(96.0, 550, 4), 0.0, 0.0, 0.0)) is not None  # 1.5 % at Nyquist
