"""The window-share tally: every refined point counted once, and blur moves the shares to wider windows."""
from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter

from edgetruth.evaluate.ranging.window_shares import WINDOWS, image_window_counts


def _square(blur_px: float, size=(160, 200), ss=8):
    """A dark 80 px square on a bright board, slightly rotated, Gaussian-blurred, area-sampled."""
    import cv2

    h, w = size
    big = np.full((h * ss, w * ss), 3000.0)
    c, s = np.cos(0.05), np.sin(0.05)
    pts = np.array([[-40, -40], [40, -40], [40, 40], [-40, 40]]) @ np.array([[c, -s], [s, c]]).T + [w / 2, h / 2]
    cv2.fillPoly(big, [np.round(pts * ss).astype(np.int32)], 300.0)
    big = gaussian_filter(big, blur_px * ss)
    img = big.reshape(h, ss, w, ss).mean(axis=(1, 3))
    return img + np.random.default_rng(0).normal(0, 8, img.shape)


def test_counts_cover_every_point_and_follow_the_blur():
    sharp, wide = image_window_counts(_square(0.4)), image_window_counts(_square(2.5))
    assert set(sharp) == set(WINDOWS) and sum(sharp.values()) > 200
    mean = {k: sum(w * n for w, n in c.items()) / sum(c.values()) for k, c in (("sharp", sharp), ("wide", wide))}
    assert sharp[5] / sum(sharp.values()) > 0.8  # a sharp edge: the 5-sample window
    assert mean["wide"] > mean["sharp"] + 2
