"""edgetruth's calibrations run OpenCV on one thread (``edgetruth/opencv_threads.py``).

OpenCV 5.0.0's ``calibrateCamera`` on several threads gives other last bits on every call, from the same corners
(measured: three fx 1e-14 apart at 16 threads, one value at 1 thread; 5.1.0 gives one value on any count).  So:
- inside ``calibrate_camera`` OpenCV has one thread, and afterwards the count it had before, also after an error;
- both of the project's calibrations, the rendered boards' (``evaluate.calibration``) and the photos' squares'
  (``evaluate.board.calibrate``), go through it;
- a calibration repeated with OpenCV on 1 and on 4 threads gives the same bits, and the truth it was drawn from.
"""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from edgetruth import opencv_threads

K_TRUE = np.array([[832.5, 0.0, 320.0], [0.0, 832.5, 256.0], [0.0, 0.0, 1.0]])
DIST_TRUE = np.array([-0.07, 0.1, 0.0, 0.0, 0.0])


def _views(n=12, seed=1):
    from edgetruth.evaluate.calibration import object_points

    rng = np.random.default_rng(seed)
    obj = object_points((9, 6), 0.03).astype(np.float32)
    imgs = []
    for _ in range(n):
        r = rng.normal(0.0, 0.3, 3)
        t = np.array([rng.normal(0, 0.03), rng.normal(0, 0.03), 0.5 + 0.4 * rng.random()])
        p, _ = cv2.projectPoints(obj, r, t, K_TRUE, DIST_TRUE)
        imgs.append(p.astype(np.float32))
    return [obj] * n, imgs


@pytest.fixture
def seen(monkeypatch):
    """The OpenCV thread count inside each cv2.calibrateCamera call."""
    counts = []
    real = cv2.calibrateCamera

    def spy(*args, **kwargs):
        counts.append(cv2.getNumThreads())
        return real(*args, **kwargs)

    monkeypatch.setattr(cv2, "calibrateCamera", spy)
    before = cv2.getNumThreads()
    cv2.setNumThreads(4)
    yield counts
    cv2.setNumThreads(before)


def test_calibrate_camera_runs_on_one_thread_and_restores_the_count(seen):
    obj, img = _views()
    opencv_threads.calibrate_camera(obj, img, (640, 512), None, None)
    assert seen == [1] and cv2.getNumThreads() == 4
    with pytest.raises(cv2.error):
        opencv_threads.calibrate_camera(obj[:1], img[:2], (640, 512), None, None)  # views that do not pair up
    assert cv2.getNumThreads() == 4


def test_the_projects_calibrations_go_through_it(seen):
    from edgetruth.evaluate.board.calibrate.zhang import calibrate as calibrate_squares
    from edgetruth.evaluate.calibration import solve_points

    obj, img = _views()
    solve_points(obj, img, (640, 512), 0)
    squares = np.asarray(obj[0], np.float64)[:48].reshape(12, 4, 3)  # 12 "squares" of 4 corners each
    calibrate_squares(squares[..., :2], [np.asarray(i, np.float64).reshape(-1, 2)[:48].reshape(12, 4, 2) for i in img],
                      (640, 512))
    assert seen == [1, 1]


def test_repeated_calibrations_give_the_same_bits_and_the_truth():
    from edgetruth.evaluate.calibration import solve_points

    obj, img = _views()
    before = cv2.getNumThreads()
    try:
        out = []
        for n in (1, 4, 4, 1):
            cv2.setNumThreads(n)
            out.append(solve_points(obj, img, (640, 512), 0))
    finally:
        cv2.setNumThreads(before)
    for rms, K, dist, per_view in out[1:]:
        assert np.array_equal(K, out[0][1]) and np.array_equal(dist, out[0][2]) and rms == out[0][0]
    # exact corners but for their float32 rounding (~3e-5 px, which OpenCV requires): K within 1e-3 px (measured 1.3e-4)
    assert np.abs(out[0][1] - K_TRUE).max() < 1e-3 and out[0][0] < 1e-4
