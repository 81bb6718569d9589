"""The sharpening a twin renders (``twin.sharpening``): the axes a set's overshoot calls for, and the mask and lens
blur fitted back from edge-spread functions made with them."""
from __future__ import annotations

import numpy as np
import pytest

from edgetruth.evaluate.board.tone.photo_model import normalised_model
from edgetruth.evaluate.board.twin.sharpening import fit_sharpening, sharpened_axes
from edgetruth.render.optics.camera import camera_from_dict


def test_sharpened_axes_follow_the_median_overshoot():
    """An axis is sharpened where the photos' median overshoot exceeds 3 %: one photo's does not make it."""
    def photo(x, y):
        return {"overshoot_pct": {"x": x, "y": y}}

    assert sharpened_axes([photo(12, 0.5), photo(10, 0.2), photo(0.1, 4.0)]) == "x"
    assert sharpened_axes([photo(5, 5), photo(6, 4)]) == "xy"
    assert sharpened_axes([photo(1, 0), photo(2, 1), photo(0, 9)]) is None and sharpened_axes([{}]) is None


@pytest.mark.parametrize("axes", ["x", "xy"])
def test_the_mask_and_the_blur_come_back(axes):
    """Pooled ESFs made by the renderer's model (pixel, f/4 diffraction, a Gaussian aberration of 4.4 um along x and
    5.0 along y, an unsharp mask of amount 2.5 and sigma 1.0 px, sRGB-like power 2.2, output gain 1.6, levels 0.02
    and 0.6): the fit returns the ESFs to 1e-4 of the step (RMS) and each parameter to 0.1 % (measured: to 1e-8;
    the amount and sigma trade along a valley when the data are noisy, ``photo_model.fit_esf``)."""
    cam = camera_from_dict({"width_px": 640, "height_px": 480, "pitch_um": 6.0, "fx_px": 800.0, "f_number": 4.0},
                           "t")
    truth = {"x": 4.4, "y": 5.0}
    t = np.arange(-4.9375, 4.94, 0.125)
    base = dict(camera=cam, defocus_px=0.1, black=0.02, white=0.6, gain=1.6, gamma=2.2)
    esfs = {a: (t, normalised_model(t, **base, sigma_ab_um=truth[a], amount=2.5, sigma_s=1.0)) for a in axes}
    f = fit_sharpening(esfs, cam, 0.1, 0.02, 0.6, 1.6, 2.2)
    assert f["fit_rms"] < 1e-4 and sorted(f["sigma_um"]) == sorted(axes)
    assert all(f["sigma_um"][a] == pytest.approx(truth[a], rel=1e-3) for a in axes)
    assert f["amount"] == pytest.approx(2.5, rel=1e-3) and f["sigma_px"] == pytest.approx(1.0, rel=1e-3)


def test_the_masks_noise_gain():
    """White noise through e + a (e - G * e): variance x (1 + a)^2 - 2 a (1 + a) g0 + a^2 sum g^2, g the Gaussian
    kernel; for a continuous Gaussian of sigma 1 px g0 = 1 / sqrt(2 pi), sum g^2 = 1 / (2 sqrt(pi)) along one axis,
    their squares along both (the renderer's 'xy': one 2-D Gaussian): 7.032 and 9.962 at a = 2.5 (the sampled
    kernel's to 1e-3); no mask, 1."""
    from edgetruth.evaluate.board.twin.sharpening import mask_noise_gain

    a = 2.5
    g0, g2 = 1.0 / np.sqrt(2.0 * np.pi), 1.0 / (2.0 * np.sqrt(np.pi))
    assert mask_noise_gain(a, 1.0, "x") == pytest.approx((1 + a) ** 2 - 2 * a * (1 + a) * g0 + a * a * g2, abs=1e-3)
    assert mask_noise_gain(a, 1.0, "xy") == pytest.approx((1 + a) ** 2 - 2 * a * (1 + a) * g0 ** 2
                                                         + a * a * g2 ** 2, abs=1e-3)
    assert mask_noise_gain(0.0, 1.0, "x") == 1.0
