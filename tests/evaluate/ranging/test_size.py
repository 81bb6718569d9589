"""Size extraction on analytic geometry: exact points give exact sizes; outliers are rejected."""
from __future__ import annotations

import numpy as np
import pytest

from edgetruth.errors import InputError
from edgetruth.evaluate.ranging.size import (circle_taubin, distance_from_size, fit_circle, fit_line_robust, fit_square)


def square_points(cx, cy, side, roll_deg=0.0, step=0.5, trim=0.0):
    """Points and outward normals on the four sides of a square (corners excluded by ``trim``)."""
    h = side / 2
    t = np.arange(-h + trim, h - trim + 1e-9, step)
    xs, ys, nxs, nys = [], [], [], []
    for ox, oy, nx, ny in ((h, None, 1, 0), (-h, None, -1, 0), (None, h, 0, 1), (None, -h, 0, -1)):
        if ox is not None:
            x, y = np.full_like(t, ox), t
        else:
            x, y = t, np.full_like(t, oy)
        xs.append(x); ys.append(y); nxs.append(np.full_like(t, nx)); nys.append(np.full_like(t, ny))
    x, y, nx, ny = map(np.concatenate, (xs, ys, nxs, nys))
    a = np.radians(roll_deg)
    c, s = np.cos(a), np.sin(a)
    return cx + c * x - s * y, cy + s * x + c * y, c * nx - s * ny, s * nx + c * ny


@pytest.mark.parametrize("roll", [0.0, 3.0, 17.0, 44.0])
def test_exact_square_gives_exact_width_and_height(roll):
    x, y, nx, ny = square_points(300.3, 211.7, 123.456, roll)
    fit = fit_square(x, y, nx, ny)
    assert fit.width_px == pytest.approx(123.456, abs=1e-9)
    assert fit.height_px == pytest.approx(123.456, abs=1e-9)
    if roll == 0.0:
        assert fit.width_seed_px == pytest.approx(123.456, abs=1e-9)


def test_square_normals_may_point_inwards():
    x, y, nx, ny = square_points(50, 60, 40, 5.0)
    assert fit_square(x, y, -nx, -ny).width_px == pytest.approx(40, abs=1e-9)


def test_square_rejects_outliers_and_corner_points():
    rng = np.random.default_rng(1)
    x, y, nx, ny = square_points(200, 200, 80, 2.0)
    x = x + rng.normal(0, 0.02, x.size)
    # 10 % gross outliers along the normal (1-4 px), e.g. highlight or texture edges
    k = rng.choice(x.size, x.size // 10, replace=False)
    off = rng.uniform(1.0, 4.0, k.size) * rng.choice([-1, 1], k.size)
    x[k] += off * nx[k]
    y[k] += off * ny[k]
    fit = fit_square(x, y, nx, ny)
    assert fit.width_px == pytest.approx(80, abs=0.01)
    assert fit.height_px == pytest.approx(80, abs=0.01)
    assert not fit.used[k[np.abs(off) > 1.5]].any()


def test_line_fit_exact_and_robust():
    t = np.linspace(-20, 20, 81)
    n = np.array([np.cos(0.3), np.sin(0.3)])
    d = 7.25
    p = d * n + t[:, None] * np.array([-n[1], n[0]])
    ln = fit_line_robust(p[:, 0], p[:, 1])
    assert abs(abs(ln.d) - d) < 1e-10 and abs(abs(ln.n @ n) - 1) < 1e-12
    q = p.copy()
    q[::7] += 3.0 * n  # 12 outliers 3 px off the line
    ln = fit_line_robust(q[:, 0], q[:, 1])
    assert abs(ln.d * np.sign(ln.n @ n) - d) < 1e-9
    assert ln.inliers.sum() == 81 - 12


def test_too_few_points_is_an_input_error():
    x, y, nx, ny = square_points(50, 50, 20, 0.0, step=5.0)
    with pytest.raises(InputError):
        fit_square(x, y, nx, ny)


def test_exact_circle_taubin_and_geometric():
    t = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    x, y = 321.25 + 45.5 * np.cos(t), 123.75 + 45.5 * np.sin(t)
    assert circle_taubin(x, y) == pytest.approx((321.25, 123.75, 45.5), abs=1e-9)
    fit = fit_circle(x, y)
    assert fit.diameter_px == pytest.approx(91.0, abs=1e-9)
    assert (fit.cx, fit.cy) == pytest.approx((321.25, 123.75), abs=1e-9)


def test_circle_rejects_outliers():
    rng = np.random.default_rng(3)
    t = rng.uniform(0, 2 * np.pi, 600)
    r = 30.0 + rng.normal(0, 0.02, t.size)
    r[:60] += rng.uniform(1.5, 5.0, 60)  # 10 % outliers outside
    x, y = 100 + r * np.cos(t), 80 + r * np.sin(t)
    fit = fit_circle(x, y)
    assert fit.r == pytest.approx(30.0, abs=0.005)
    assert not fit.used[:60].any()


def test_circle_anisotropic_pixels():
    """An ellipse from fx != fy is a circle in fx units: aspect = fx / fy recovers it."""
    fx, fy, cy = 1000.0, 990.0, 240.0
    t = np.linspace(0, 2 * np.pi, 360, endpoint=False)
    x = 300 + 50 * np.cos(t)
    y = cy + 20 + 50 * np.sin(t) * fy / fx
    fit = fit_circle(x, y, aspect=fx / fy, cy_px=cy)
    assert fit.diameter_px == pytest.approx(100.0, abs=1e-6)
    assert fit.cy == pytest.approx(cy + 20, abs=1e-6)  # reported in image pixels


def test_distance_from_size():
    assert distance_from_size(1666.0, 0.13, 1666.0 * 0.13 / 2.0) == pytest.approx(2.0)
    assert np.isnan(distance_from_size(1666.0, 0.13, 0.0))
