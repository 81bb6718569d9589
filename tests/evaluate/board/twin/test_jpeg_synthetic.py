"""What a photo's JPEG did (``jpeg_synthetic``), measured on a synthetic image of its squares: the synthetic board
reads its own σ, and what a JPEG adds to the blur, and what it leaves of the noise, are what it does to a rendered
view."""
from __future__ import annotations

import numpy as np
import pytest

from edgetruth.evaluate.board.detect import chessboard as cb
from edgetruth.evaluate.board.twin import jpeg_synthetic as js
from edgetruth.evaluate.board.tone.photo_model import blur, board_lines
from tests.evaluate.board.chessboard_images import ROTATIONS, render

MODEL = cb.chessboard_model((9, 6), 1.0)


def _view(sigma_px=0.9):
    img, _ = render((9, 6), ROTATIONS[0], sigma_px=sigma_px)
    u8 = np.clip(np.round(img), 0, 255).astype(np.uint8)
    return u8, board_lines(u8.astype(float), MODEL)


def test_the_synthetic_board_reads_its_own_sigma():
    """On a view's own side lines, the synthetic board of σ 0.9 px (both axes) reads 0.9 px to 0.005 px."""
    u8, lines = _view()
    b = blur(np.round(js.synthetic_board(u8.shape, lines, 0.9, 0.9, 40.0, 210.0)), lines)
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
    pred = js.jpeg_blur_px(u8.shape, lines, sx, sy, 40.0, 210.0, quality)
    seen = {"x": coded["vertical"]["sigma_px"] - sx, "y": coded["horizontal"]["sigma_px"] - sy}
    print(f"q{quality}: JPEG adds {seen}, predicted {pred}")
    assert max(abs(seen[k] - pred[k]) for k in "xy") < 0.01
    assert max(abs(v) for v in js.jpeg_blur_px(u8.shape, lines, sx, sy, 40.0, 210.0, 100).values()) < 3e-3


def test_a_lower_quality_adds_more_blur():
    u8, lines = _view()
    added = [sum(js.jpeg_blur_px(u8.shape, lines, 0.9, 0.9, 40.0, 210.0, q).values()) for q in (90, 50, 20)]
    assert added[0] < added[1] < added[2]


@pytest.mark.parametrize("quality, shot, read", [(50, 4.0, 2.0), (75, 4.0, 2.0), (50, 6.0, 3.0), (75, 3.0, 0.0)])
def test_the_noise_before_a_jpeg_is_found_from_the_noise_after_it(quality, shot, read):
    """A rendered view (dark 40, white 210) with shot noise of SD ``shot`` at its white and ``read`` DN of constant
    noise, through OpenCV's JPEG: from the white and dark SDs left after it, ``noise_before_jpeg`` finds the shot SD
    to 10 % and the read noise to 0.75 DN (measured: within 7 % and 0.56 DN; the dark's SD after a JPEG moves
    little with the read noise before it), where the JPEG took 31-49 % of the white's SD off."""
    from edgetruth.evaluate.board.detect.levels import square_levels
    from edgetruth.render.sensor.pipeline import jpeg_round_trip

    img, _ = render((9, 6), ROTATIONS[1], sigma_px=0.9)
    sd = np.sqrt(shot ** 2 * img / 210.0 + read ** 2)
    noisy = img + np.random.default_rng(7).standard_normal(img.shape) * sd
    photo = jpeg_round_trip(np.clip(np.round(noisy), 0, 255).astype(np.uint8), quality).astype(float)
    lines = board_lines(photo, MODEL)
    squares = cb.find_squares(photo, MODEL).squares.corners
    lev = square_levels(photo, squares)
    b = blur(photo, lines)
    found = js.noise_before_jpeg(photo.shape, lines, squares, b["vertical"]["sigma_px"], b["horizontal"]["sigma_px"],
                                 lev.dark, lev.white, lev.white_sd, lev.dark_sd, quality)
    print(f"q{quality}: shot {shot}, read {read} before; white {lev.white_sd:.2f}, dark {lev.dark_sd:.2f} after; "
          f"found {found}")
    assert found["shot_dn"] == pytest.approx(shot, rel=0.1) and abs(found["read_dn"] - read) < 0.75


def test_no_noise_after_is_no_answer():
    u8, lines = _view()
    squares = cb.find_squares(u8.astype(float), MODEL).squares.corners
    assert js.noise_before_jpeg(u8.shape, lines, squares, 0.9, 0.9, 40.0, 210.0, 0.0, 0.0, 50) is None
