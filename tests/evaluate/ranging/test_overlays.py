"""Overlays show what was measured: the drawn outline lies on the found one (and on the true one)."""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from edgetruth.evaluate.ranging.overlays import OUTLINE, overlay_name, photo_overlay
from edgetruth.evaluate.ranging.target_finder import find_region
from edgetruth.render.synthetic.room_photos import RoomPhoto, render_room_photo


def _found():
    img, truth = render_room_photo(RoomPhoto(kind="light_sheet", z_m=1.1, yaw_deg=25, pitch_deg=-10, seed=2))
    reg = find_region(img, shape="rectangle", aspect=0.297 / 0.21, K=np.asarray(truth["K"]))
    return img, truth, reg


def _outline_pixels(rgb):
    ys, xs = np.nonzero(np.all(rgb == np.array(OUTLINE, np.uint8), axis=2))
    return np.column_stack([xs, ys]).astype(float)


def test_the_drawn_outline_lies_on_the_found_one():
    img, truth, reg = _found()
    outline = np.asarray(reg.finder["outline_px"], float)
    rgb, s = photo_overlay(img, outline, runners_up=reg.finder["runner_up_contours_px"], text=["l = 1 px"])
    assert s == 1.0 and rgb.shape == img.shape + (3,)
    drawn = _outline_pixels(rgb)
    d_drawn, _ = cKDTree(outline).query(drawn)
    d_found, _ = cKDTree(drawn).query(outline)
    assert d_drawn.max() <= 1.0  # every green pixel is on the found outline (1 px lines between its points)
    assert np.mean(d_found <= 0.5) > 0.99  # and the outline is drawn all round (text band aside)
    # and the found outline is the true one (within the 1 px of a pixel-boundary trace)
    true_pts = np.asarray(truth["outline_px"])
    from edgetruth.evaluate.ranging.target_finder import _segment_distance

    assert np.percentile(_segment_distance(drawn, true_pts), 95) <= 1.5


def test_a_large_photo_is_shrunk_and_the_outline_scaled_with_it():
    img, truth, reg = _found()
    big = np.kron(img.astype(float), np.ones((3, 3)))  # 1920 x 1440: over MAX_SIDE_PX
    outline = (np.asarray(reg.finder["outline_px"], float) + 0.5) * 3 - 0.5
    rgb, s = photo_overlay(big, outline)
    assert s < 1 and max(rgb.shape[:2]) == 1600
    drawn = _outline_pixels(rgb)
    from edgetruth.evaluate.ranging.target_finder import _segment_distance

    assert _segment_distance(drawn, (outline + 0.5) * s - 0.5).max() <= 1.0  # on the scaled polyline


def test_overlay_names_are_flat_files():
    assert overlay_name("sub/dir/IMG 01.jpg") == "overlay_sub_dir_IMG_01.jpg.png"
