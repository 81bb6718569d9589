"""Calibration from circle grids (evaluate/board/circles.py): OpenCV's blob centroids, the edge method's ellipse
centres and those corrected for perspective, on synthetic views whose every pixel is the exact lens-weighted
coverage of the circles (board_frame's composite with the shading flat; no Mitsuba): the corrected centres
recover fx, fy within 0.05 % and beat the blobs; --centres and the layouts."""
from __future__ import annotations

import numpy as np
import pytest

from edgetruth.errors import InputError
from edgetruth.evaluate.board import circles
from edgetruth.evaluate.pattern import parse_board_pattern
from tests.evaluate.board.circle_images import views


def test_object_points_follow_opencvs_sample():
    p = circles.object_points((4, 11), 0.02, True)
    want = np.array([((2 * j + i % 2) * 0.02, i * 0.02, 0.0) for i in range(11) for j in range(4)], np.float32)
    np.testing.assert_array_equal(p, want)
    from edgetruth.render.scene.circles_grid import CirclesGrid

    np.testing.assert_allclose(p, CirclesGrid(4, 11, 0.02, 0.01, True).object_points(), atol=1e-8)
    np.testing.assert_allclose(circles.object_points((7, 6), 0.03, False),
                               CirclesGrid(7, 6, 0.03, 0.01, False).object_points(), atol=1e-8)


def test_centres_option():
    assert circles.parse_centres("blobs")[0] == "blobs"
    assert circles.parse_centres("corrected:canny_devernay") == ("corrected", "canny_devernay")
    assert circles.parse_centres("conic") == ("conic", circles.DEFAULT_METHOD)
    for bad in ("centroid", "blobs:erf4p_fixed5"):
        with pytest.raises(InputError, match="--centres"):
            circles.parse_centres(bad)


@pytest.fixture(scope="module")
def synthetic():
    return views()


@pytest.mark.slow
def test_corrected_centres_recover_the_camera_and_beat_the_blobs(synthetic):
    cam, grid, views, truths = synthetic
    pattern = parse_board_pattern("circles:4x5:asymmetric")
    errs = {}
    for centres in ("blobs", "conic", "corrected"):
        cal, results, info = circles.calibrate_circles(views, pattern, grid.spacing_m, centres=centres)
        assert cal.n_views == len(views)
        e = np.array([cal.fx / cam.fx_px - 1.0, cal.fy / cam.fy_px - 1.0]) * 100.0
        pts = np.concatenate(info["image_points"])
        truth = np.concatenate([np.asarray(t["centre_distorted_px"]) for t in truths])
        errs[centres] = (np.abs(e).max(), float(np.sqrt(np.nanmean(np.sum((pts - truth) ** 2, axis=1)))))
        print(f"{centres}: fx, fy error {np.round(e, 4)} %, centres {errs[centres][1]:.4f} px RMS from the truth, "
              f"rounds {info['rounds']}")
    assert errs["corrected"][0] <= 0.05
    assert errs["corrected"][1] < errs["conic"][1] < errs["blobs"][1]
    assert errs["corrected"][1] <= 0.01
    assert errs["corrected"][0] < errs["blobs"][0]
