"""A chessboard photo's flat levels (``evaluate/board/detect/levels.py``): the dark and light squares' values and noise at
their centres, and the saturated white they show."""
import numpy as np
import pytest

from edgetruth.evaluate.board.detect.levels import SquareLevels, saturated, square_levels
from tests.evaluate.board.board_images import apply_h
from tests.evaluate.board.chessboard_images import ROTATIONS, all_dark_squares, render, stored_views


def test_square_levels_read_the_dark_and_the_light_squares():
    """The exact render's levels 40 and 210 (of 255), stored on 16 bits, at the squares' centres; no noise."""
    _, h = render((9, 6), ROTATIONS[0])
    lv = square_levels(stored_views(lambda v: v)[0], apply_h(h, all_dark_squares((9, 6))))
    assert lv.dark == pytest.approx(65535 * 40 / 255, abs=0.5) and lv.white == pytest.approx(65535 * 210 / 255, abs=0.5)
    assert lv.dark_sd < 0.5 and lv.white_sd < 0.5


def test_square_levels_read_the_flats_noise_and_see_a_clip_flatten_it():
    """Gaussian noise of SD 3 on levels 40 / 210: both levels and both SDs come back (the SD pooled about each
    patch's own mean, with its degrees of freedom); the same image clipped at 200 reads a white SD near 0."""
    img, h = render((9, 6), ROTATIONS[1])
    quads = apply_h(h, all_dark_squares((9, 6)))
    noisy = img + np.random.default_rng(3).normal(0.0, 3.0, img.shape)
    lv = square_levels(noisy, quads)
    assert lv.dark == pytest.approx(40, abs=0.3) and lv.white == pytest.approx(210, abs=0.3)
    assert lv.dark_sd == pytest.approx(3, rel=0.05) and lv.white_sd == pytest.approx(3, rel=0.05)
    clipped = square_levels(np.minimum(noisy, 200.0), quads)
    assert clipped.white == 200 and clipped.white_sd < 0.3 and clipped.dark_sd == pytest.approx(lv.dark_sd)
    assert saturated(clipped) and not saturated(lv)


def test_a_noise_free_image_is_never_called_saturated():
    """Exact renders have no noise in the dark either: a flat white there says nothing."""
    img, h = render((9, 6), ROTATIONS[0])
    lv = square_levels(np.minimum(img, 200.0), apply_h(h, all_dark_squares((9, 6))))
    assert lv.dark_sd == 0 and lv.white_sd == 0 and not saturated(lv)
    assert not saturated(SquareLevels(40.0, 210.0, 0.0, 0.0)) and saturated(SquareLevels(40.0, 210.0, 2.0, 0.9))


def test_larger_patches_about_their_planes_and_a_clip_left_out():
    """Noise of SD 5 on a board lit with a ramp of 0.5 DN/px along x: 17 x 17 patches about their means read the
    ramp too (sqrt(25 + 0.5² (17² - 1) / 12) = 5.57), about their planes the noise alone (to 3 %: ~10,000 values
    a level); with a clip at 200 the light squares' patches that reach it are left out, and the rest read the
    noise they kept (to 3 %)."""
    img, h = render((9, 6), ROTATIONS[0])
    quads = apply_h(h, all_dark_squares((9, 6)))
    ramp = 0.5 * (np.arange(img.shape[1]) - img.shape[1] / 2)[None, :]
    noisy = img + ramp + np.random.default_rng(3).normal(0.0, 5.0, img.shape)
    mean, plane = (square_levels(noisy, quads, half_px=8, plane=p) for p in (False, True))
    assert mean.white_sd == pytest.approx(np.sqrt(25 + 0.25 * 288 / 12), rel=0.03)
    assert plane.white_sd == pytest.approx(5.0, rel=0.03) and plane.dark_sd == pytest.approx(5.0, rel=0.03)
    clipped = np.minimum(noisy, 200.0)
    kept = square_levels(clipped, quads, half_px=8, plane=True, clip=200.0)
    assert kept.white_sd == pytest.approx(5.0, rel=0.03) and kept.white < plane.white
    assert square_levels(clipped, quads, half_px=8, plane=True).white_sd < 4.5  # the clip truncates the noise
