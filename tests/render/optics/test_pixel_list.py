"""The lens sensor's pixel-list mode (``set_pixels``): film pixel k images the k-th listed frame pixel, as
the analytic edge band renders the pixels whose kernel meets an outline (render/scene/edge_band.py)."""
from __future__ import annotations

import numpy as np
import pytest


def _rig(fast_variant):
    from edgetruth.render.optics.camera import load_camera
    from edgetruth.render.scene.edge_band import tile_rig
    from edgetruth.render.scene.mitsuba_scene import RenderSettings
    from edgetruth.render.scene.pose import Pose

    cam = load_camera("quick")
    rig = tile_rig(cam, RenderSettings(spp=16), 0.13, 16)
    rig.set_state("T1", Pose(1.0, 0.0, 0.0, 0.0, 0.0), 0.075)
    return cam, rig


def test_listed_pixels_equal_the_window_render_of_the_same_pixels(fast_variant):
    """A list that is a window's pixels in row-major order gives that window's image: same samples, same
    seed (the film and its sampler are the same), so the same values to float rounding."""
    cam, rig = _rig(fast_variant)
    cx, cy = cam.principal_point_px
    x0, y0 = int(round(cx - cam.fx_px * 0.065)) - 8, int(round(cy)) - 8  # across the square's left side at 1 m
    ys, xs = np.mgrid[y0:y0 + 16, x0:x0 + 16]
    win = rig.render(5, window_at=(x0, y0))
    lst = rig.render(5, pixels=(xs.ravel().astype(float), ys.ravel().astype(float)))
    np.testing.assert_allclose(lst, win, rtol=1e-6, atol=0)
    # a permuted list permutes the pixels (up to the samples, which follow the film position)
    perm = np.random.default_rng(1).permutation(256)
    out = rig.render(6, pixels=(xs.ravel()[perm].astype(float), ys.ravel()[perm].astype(float))).ravel()
    back = np.empty(256)
    back[perm] = out
    ref = rig.render(6, window_at=(x0, y0)).ravel()
    assert np.ptp(ref) > 0.5 * ref.max()  # the edge is in the window: a wrong pixel would show
    # the 16-spp path noise (largest on the edge pixels), not a wrong pixel (which would be off by ~the step)
    assert np.sqrt(np.mean((back - ref) ** 2)) <= 0.05 * np.ptp(ref) and np.max(np.abs(back - ref)) <= 0.3 * np.ptp(ref)


def test_a_sample_rounded_onto_the_film_edge_stays_in_its_pixel(fast_variant):
    """pixel + jitter in float32 rounds to the next integer for a jitter within ~4e-6 of 1: on the last
    column or row that is one past the film, whose list index would read past the list."""
    import mitsuba as mi

    _, rig = _rig(fast_variant)
    rig.render(1, pixels=(np.arange(256, dtype=float), np.zeros(256)))
    pu, pv = rig.sensor._film_pixel(mi.Float([16.0, 15.5, 0.0]), mi.Float([16.0, 3.25, 15.999]))
    assert np.array(pu).tolist() == [15.0, 15.0, 0.0] and np.array(pv).tolist() == [15.0, 3.0, 15.0]
    with pytest.raises(ValueError, match="256 pixels expected"):
        rig.sensor.set_pixels(np.zeros(10), np.zeros(10))
