"""OpenCV calls whose result must not depend on OpenCV's threads.

``cv2.calibrateCamera`` in OpenCV 5.0.0 gives different last bits from the same corners on several threads, from
one call to the next. With 16 threads, fx was 832.509275577807, ...8231 and ...8074 in three calls. With one
thread it was the same bits every time, and 5.1.0 gives them on any count. On an H200 with 16 cores two runs of the
same renders calibrated 2e-10 apart, and every ranging row that uses the calibration differed (docs/gpu.md).
pyproject allows any OpenCV from 4.8, so edgetruth's calibrations run OpenCV on one thread. It costs nothing
measurable: 15 boards calibrate in 0.014 s either way.
"""
from __future__ import annotations

from contextlib import contextmanager


@contextmanager
def one_thread():
    """OpenCV on one thread inside the block; its thread count as before after it."""
    import cv2  # lazy: OpenCV is slow to import

    before = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        yield
    finally:
        cv2.setNumThreads(before)


def calibrate_camera(*args, **kwargs):
    """``cv2.calibrateCamera(*args, **kwargs)`` on one OpenCV thread: the same bits on every run and machine."""
    import cv2  # lazy: OpenCV is slow to import

    with one_thread():
        return cv2.calibrateCamera(*args, **kwargs)
