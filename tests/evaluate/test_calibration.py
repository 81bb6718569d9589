"""Zhang calibration on the rendered default boards recovers the true intrinsics."""
from __future__ import annotations

import numpy as np
import pytest

from edgetruth.evaluate.calibration import distort_px, object_points, subpix_window, undistort_px


def test_object_points_are_opencv_order():
    p = object_points((3, 2), 0.5)
    assert p.shape == (6, 3)
    assert np.allclose(p[:4], [[0, 0, 0], [0.5, 0, 0], [1.0, 0, 0], [0, 0.5, 0]])


def test_subpix_window_scales_with_square_size():
    nx, ny = 3, 2
    g = np.stack(np.meshgrid(np.arange(nx) * 20.0, np.arange(ny) * 20.0), -1).reshape(-1, 2)
    assert subpix_window(g, (nx, ny)) == 8
    assert subpix_window(g / 10, (nx, ny)) == 2


@pytest.mark.slow
def test_undistort_px_and_distort_px_invert_each_other():
    """Through a strong barrel lens (k1 -0.3, k2 0.1, a skewed K) the two maps invert each other to 1e-9 px over the
    whole image; normalised output is the pixel output through K^-1; NaN stays NaN, row for row."""
    K = np.array([[600.0, 0.4, 319.5], [0, 598.0, 239.5], [0, 0, 1]])
    dist = np.array([-0.3, 0.1, 0.001, -0.0005, 0.02])
    p = np.random.default_rng(3).uniform([0, 0], [639, 479], size=(300, 2))
    u = undistort_px(p, K, dist)
    assert np.abs(distort_px(u, K, dist) - p).max() < 1e-9
    n = undistort_px(p, K, dist, normalised=True)
    assert np.allclose(np.c_[n, np.ones(len(n))] @ K.T[:, :2], u, atol=1e-9)
    q = p.copy()
    q[5] = np.nan
    out = undistort_px(q, K, dist)
    assert np.isnan(out[5]).all() and np.isfinite(np.delete(out, 5, axis=0)).all()
    assert np.isnan(distort_px(out, K, dist)[5]).all()


@pytest.mark.slow
def test_calibration_spec_recovers_fx_and_principal_point(tmp_path, fast_variant):
    """The `calibration` spec as shipped (20 boards, 1280x1024, default camera, every pixel composited: no
    Monte-Carlo noise, so its spp only sets the shading's). Measured (2026-12-04): fx -0.011 %, fy -0.013 %,
    principal point (-0.10, -0.24) px, RMS 0.034 px; path-traced at 16 spp the darks' noise gave -0.028 %, -0.026 %,
    (+0.12, +0.08) px, 0.084 px. The renders are deterministic, so the margins guard against code changes, not
    noise. All 20 boards, not a subset: Zhang's principal point scatters by ~0.3 px between subsets of these views
    (path-traced, 10 boards: cx -1.03 .. +0.70 px; 16: +0.50; 17: +0.47), so fewer would need a looser 0.5 px
    bound."""
    from edgetruth.evaluate.calibration import calibrate_dataset
    from edgetruth.render.dataset.driver import render_spec
    from edgetruth.resources import shipped_spec

    text = shipped_spec("calibration").read_text()
    assert '\nboard_mode = "frame"\n' in text
    spec = tmp_path / "calibration.toml"
    spec.write_text(text)
    render_spec(spec, tmp_path / "cal", progress=False, announce=lambda s: None)
    cal = calibrate_dataset(tmp_path / "cal")
    e = cal.errors()
    print(cal.to_dict()["errors"], cal.rms_px)
    assert cal.n_views == 20
    assert abs(e["fx_rel_pct"]) < 0.05 and abs(e["fy_rel_pct"]) < 0.05
    assert abs(e["cx_px"]) < 0.5 and abs(e["cy_px"]) < 0.5
    assert cal.rms_px < 0.05


def test_a_bent_board_needs_every_photo_in_the_bend():
    """``use_bent_board``: a photo with fewer than board_bend.MIN_CORNERS corners sat out of the bend fit, so its pose
    has no bent counterpart: one line naming it and the fix."""
    from edgetruth.errors import InputError
    from edgetruth.evaluate.calibration import Calibration, PhotoResult, use_bent_board

    cal = Calibration(K=np.eye(3), dist=np.zeros(5), image_size=(640, 480), rms_px=0.2, n_views=3,
                      board_bend={"quadratic": {"views": 2}})
    results = [PhotoResult("a.jpg", True, 54), PhotoResult("b.jpg", True, 8), PhotoResult("c.jpg", True, 54)]
    with pytest.raises(InputError, match="b.jpg measured fewer than 13 corners.*--board flat"):
        use_bent_board(cal, results)
    with pytest.raises(InputError, match="--board bent"):
        use_bent_board(Calibration(K=np.eye(3), dist=np.zeros(5), image_size=(640, 480), rms_px=0.2, n_views=3),
                       results)
    with pytest.raises(InputError, match="--board common: b.jpg"):
        use_bent_board(cal, results, "common")


def test_a_board_the_default_flags_miss_is_found():
    """A noisy render of a board on a black background (tests/evaluate/data/chessboard, PROVENANCE.md) that OpenCV's
    default flags do not find: ``detect_corners`` falls back to the next flags (``DETECT_FLAGS``) and finds all 54
    inner corners, each the exact junction's (within 0.2 px; measured: median 0.047, max 0.115 px)."""
    import json
    from pathlib import Path

    import cv2

    from edgetruth.evaluate.calibration import DETECT_FLAGS, detect_corners, to_uint8

    here = Path(__file__).parent / "data" / "chessboard"
    img = cv2.imread(str(here / "twin_left02_64spp.png"), cv2.IMREAD_GRAYSCALE).astype(float)
    truth = np.asarray(json.loads((here / "twin_left02_64spp.json").read_text())["inner_corners_px"])
    assert not cv2.findChessboardCorners(to_uint8(img), (9, 6), flags=DETECT_FLAGS[0])[0]
    corners = detect_corners(img, (9, 6))
    assert corners is not None and corners.shape == (54, 2)
    d = np.linalg.norm(truth[:, None] - corners[None], axis=2)
    assert len(set(d.argmin(axis=1))) == len(truth) == 52  # one detected corner per junction
    assert d.min(axis=1).max() < 0.2 and np.median(d.min(axis=1)) < 0.1


def test_a_corner_whose_window_reaches_another_edge_takes_the_narrower_one():
    """The same render: its last row's inner corners lie half a square from the cut outer ring, and the automatic
    8 px half-window reaches the ring squares' long sides.  Used as a fixed window it leaves three corners 0.35,
    1.1 and 2.4 px from their junctions; with the automatic window those three move by more than
    ``NARROW_SHIFT_PX`` under the narrower one and take it (all 52 then within 0.2 px)."""
    import json
    from pathlib import Path

    import cv2

    from edgetruth.evaluate.calibration import detect_corners

    here = Path(__file__).parent / "data" / "chessboard"
    img = cv2.imread(str(here / "twin_left02_64spp.png"), cv2.IMREAD_GRAYSCALE).astype(float)
    truth = np.asarray(json.loads((here / "twin_left02_64spp.json").read_text())["inner_corners_px"])

    def worst(corners):
        return np.sort(np.linalg.norm(truth[:, None] - corners[None], axis=2).min(axis=1))

    auto, fixed = {}, {}
    e_auto = worst(detect_corners(img, (9, 6), None, auto))
    e_fixed = worst(detect_corners(img, (9, 6), auto["window_px"], fixed))
    assert auto["window_px"] == fixed["window_px"] == 8 and auto["narrowed"] == 3 and fixed["narrowed"] == 0
    assert e_fixed[-3] > 0.3 and e_auto[-1] < 0.2
