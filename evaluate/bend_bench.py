"""Speed of ``edgetruth calibrate``'s bent-board check (``board_bend``, quadratic and cubic): the block solver
against its dense reference on the same analytic views, in one run (``edgetruth bench --only calibrate``)."""
from __future__ import annotations

import time

import cv2
import numpy as np

from edgetruth.evaluate import block_lm
from edgetruth.evaluate.board_bend import bend_check
from edgetruth.evaluate.calibration import object_points, solve_points

#: (views, also time the dense reference): the dense solver's time grows with the square of the views
SIZES = ((13, True), (40, True), (200, False))


def analytic_views(n_views: int, noise_px: float = 0.05, seed: int = 0):
    """A flat 9x6 board (25 mm squares) in ``n_views`` random poses 0.35-0.5 m away through a 5-term lens, with
    Gaussian noise, and its calibration: the arguments of ``bend_check``."""
    rng = np.random.default_rng(seed)
    K = np.array([[530.0, 0, 330], [0, 531.0, 245], [0, 0, 1]])
    dist = np.array([-0.28, 0.06, 0.002, -0.0005, 0.1])
    obj = object_points((9, 6), 0.025)
    images = []
    for _ in range(n_views):
        r = rng.uniform(-0.6, 0.6, 3) * np.array([1, 1, 0.3])
        t = np.r_[rng.uniform(-0.03, 0.03, 2), rng.uniform(0.35, 0.5)] - cv2.Rodrigues(r)[0] @ [0.1, 0.0625, 0]
        p, _ = cv2.projectPoints(obj, r, t, K, dist)
        images.append((p[:, 0] + rng.normal(0, noise_px, (len(obj), 2))).astype(np.float32))
    poses: list = []
    _, K1, d1, _ = solve_points([obj] * n_views, images, (640, 480), 0, poses=poses)
    return [obj[:, :2]] * n_views, images, K1, d1, [r for r, _ in poses], [t for _, t in poses]


def _median_time(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def run_bench(repeats: int = 3) -> list[str]:
    lines = ["bent-board check (edgetruth calibrate; quadratic, cubic and common refits of 9x6 boards), median of "
             f"{repeats} (dense: 1 run):"]
    bend_check(*analytic_views(SIZES[0][0]))  # imports and first calls, untimed
    for n_views, dense in SIZES:
        args = analytic_views(n_views)
        block = _median_time(lambda: bend_check(*args, solver=block_lm.solve), repeats)
        line = f"  {n_views:4d} views: block LM {block:7.2f} s ({1e3 * block / n_views:.1f} ms a view)"
        if dense:
            ref = _median_time(lambda: bend_check(*args, solver=block_lm.solve_dense), 1)
            line += f"; dense MINPACK {ref:7.2f} s: x{ref / block:.1f}"
        lines.append(line)
    return lines
