"""The lens blur a twin renders with, from the ERF σ a photo shows (``blur_inverse``): the forward model against its
analytic limits, the inverse against the forward model, and what a JPEG adds, against a JPEG of a rendered view."""
from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from edgetruth.evaluate.board import blur_inverse as bi
from edgetruth.evaluate.board import chessboard as cb
from edgetruth.evaluate.board.photo_model import blur, board_lines
from tests.evaluate.board.chessboard_images import ROTATIONS, render

#: f/4, 6 µm pixels, 550 nm (``TwinAssumptions``' defaults): the diffraction cutoff p / (λN) in cy/px
CUTOFF = 6.0 / (0.55 * 4.0)
MODEL = cb.chessboard_model((9, 6), 1.0)


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


def _view(sigma_px=0.9):
    img, _ = render((9, 6), ROTATIONS[0], sigma_px=sigma_px)
    u8 = np.clip(np.round(img), 0, 255).astype(np.uint8)
    return u8, board_lines(u8.astype(float), MODEL)


def test_the_synthetic_board_reads_its_own_sigma():
    """On a view's own side lines, the synthetic board of σ 0.9 px (both axes) reads 0.9 px to 0.005 px."""
    u8, lines = _view()
    b = blur(np.round(bi.synthetic_board(u8.shape, lines, 0.9, 0.9, 40.0, 210.0)), lines)
    assert b["vertical"]["sigma_px"] == pytest.approx(0.9, abs=5e-3)
    assert b["horizontal"]["sigma_px"] == pytest.approx(0.9, abs=5e-3)


@pytest.mark.parametrize("quality", [30, 50, 75])
def test_what_a_jpeg_adds_is_what_it_adds_to_a_view(quality):
    """A rendered view (σ 0.9 px, dark 40, white 210) through OpenCV's JPEG reads a larger σ; the synthetic board
    on the view's measured lines and σ predicts the increase to 0.01 px (measured: within 0.005), and quality 100
    adds nothing (< 0.003 px)."""
    from edgetruth.render.sensor.pipeline import jpeg_round_trip

    u8, lines = _view()
    plain = blur(u8.astype(float), lines)
    coded = blur(jpeg_round_trip(u8, quality).astype(float), lines)
    sx, sy = plain["vertical"]["sigma_px"], plain["horizontal"]["sigma_px"]
    pred = bi.jpeg_blur_px(u8.shape, lines, sx, sy, 40.0, 210.0, quality)
    seen = {"x": coded["vertical"]["sigma_px"] - sx, "y": coded["horizontal"]["sigma_px"] - sy}
    print(f"q{quality}: JPEG adds {seen}, predicted {pred}")
    assert max(abs(seen[k] - pred[k]) for k in "xy") < 0.01
    assert max(abs(v) for v in bi.jpeg_blur_px(u8.shape, lines, sx, sy, 40.0, 210.0, 100).values()) < 3e-3


def test_a_lower_quality_adds_more_blur():
    u8, lines = _view()
    added = [sum(bi.jpeg_blur_px(u8.shape, lines, 0.9, 0.9, 40.0, 210.0, q).values()) for q in (90, 50, 20)]
    assert added[0] < added[1] < added[2]
