"""``closed_polyline_signed_distance``: the exact distance to a closed polyline, > 0 outside, with the
right sign everywhere -- also off the corners of a polygon whose image corners are not right angles."""
from __future__ import annotations

import numpy as np
import pytest

from edgetruth.render.edge_truth import closed_polyline_signed_distance


def _inside(poly: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Even-odd crossing test (independent of the chord geometry the function uses)."""
    x, y = pts[:, 0][:, None], pts[:, 1][:, None]
    a, b = poly[None, :, :], np.roll(poly, -1, axis=0)[None, :, :]
    ay, by = a[..., 1], b[..., 1]
    crosses = (ay > y) != (by > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xc = a[..., 0] + (y - ay) * (b[..., 0] - a[..., 0]) / (by - ay)
    return (np.sum(crosses & (x < xc), axis=1) % 2) == 1


def _segment_distance(poly: np.ndarray, pts: np.ndarray) -> np.ndarray:
    a, b = poly[None], np.roll(poly, -1, axis=0)[None]
    d = b - a
    u = np.clip(((pts[:, None] - a) * d).sum(-1) / (d * d).sum(-1), 0.0, 1.0)
    return np.linalg.norm(pts[:, None] - (a + u[..., None] * d), axis=-1).min(1)


@pytest.mark.parametrize("reverse", [False, True])
@pytest.mark.parametrize("corners", [
    [[100.0, 100.0], [200.0, 98.9], [201.0, 200.0], [99.0, 201.0]],  # corners of 89.4-90.6 deg (a tilted square)
    [[100.0, 100.0], [220.0, 130.0], [140.0, 210.0]],                  # a triangle: every corner acute
    [[100.0, 100.0], [200.0, 100.0], [150.0, 140.0], [200.0, 200.0], [100.0, 200.0]],  # a reflex vertex
])
def test_sign_and_distance_everywhere_around_a_polygon(corners, reverse):
    poly = np.asarray(corners, float)[::-1 if reverse else 1]
    k = len(poly)
    dense = np.concatenate([np.linspace(poly[j], poly[(j + 1) % k], 300, endpoint=False) for j in range(k)])
    pts = np.random.default_rng(3).uniform(60.0, 260.0, (20000, 2))
    # on the extension of every side beyond its corners: where a tie between two chords decides the sign
    ext = np.concatenate([poly[j] + np.outer(np.linspace(0.5, 40.0, 80), poly[j] - poly[(j + 1) % k])
                          / np.linalg.norm(poly[j] - poly[(j + 1) % k]) + off
                          for j in range(k) for off in ([0.0, 0.0], [0.0, 0.3], [0.3, 0.0], [0.0, -0.3], [-0.3, 0.0])])
    pts = np.concatenate([pts, ext])
    d = closed_polyline_signed_distance(dense, pts[:, 0], pts[:, 1])
    exact = _segment_distance(poly, pts)
    assert np.allclose(np.abs(d), exact, atol=1e-9)
    clear = exact > 1e-9
    assert np.array_equal((d < 0)[clear], _inside(poly, pts)[clear])


def _numpy_chords(poly, x, y):
    """The numpy implementation the kernel replaced (stop 28), kept as its bit-for-bit specification."""
    from scipy.spatial import cKDTree

    poly = np.asarray(poly, float)
    q = np.column_stack([np.ravel(x), np.ravel(y)]).astype(float)
    n = len(poly)
    _, i = cKDTree(poly).query(q)
    area2 = np.sum(poly[:, 0] * np.roll(poly[:, 1], -1) - np.roll(poly[:, 0], -1) * poly[:, 1])
    orient = 1.0 if area2 > 0 else -1.0
    best, lever, sign = np.full(len(q), np.inf), np.zeros(len(q)), np.ones(len(q))
    for j0 in (i - 2, i - 1, i, i + 1):
        a, b = poly[j0 % n], poly[(j0 + 1) % n]
        d = b - a
        u = np.clip(((q - a) * d).sum(1) / np.maximum((d * d).sum(1), 1e-300), 0.0, 1.0)
        dist = np.linalg.norm(q - (a + u[:, None] * d), axis=1)
        cross = d[:, 0] * (q - a)[:, 1] - d[:, 1] * (q - a)[:, 0]
        line = np.abs(cross) / np.maximum(np.linalg.norm(d, axis=1), 1e-300)
        tie = np.abs(dist - best) <= 1e-12 * np.maximum(1.0, best)
        signed = (dist < best) & ~tie | tie & (line > lever)
        lever[signed] = line[signed]
        sign[signed] = np.where(cross * orient > 0, -1.0, 1.0)[signed]
        best = np.minimum(best, dist)
    return (sign * best).reshape(np.shape(x))


@pytest.mark.parametrize("shape", ["ellipse", "polygon", "repeated vertex"])
def test_kernel_gives_the_numpy_codes_bits(shape):
    """The compiled loop computes each point as the numpy code did, operation for operation: equal bits,
    on curves, corners, a zero-length chord, and points on the polyline itself."""
    rng = np.random.default_rng(7)
    if shape == "ellipse":
        t = np.linspace(0.0, 2.0 * np.pi, 777, endpoint=False)
        poly = np.column_stack([320.0 + 91.3 * np.cos(t), 240.0 + 57.1 * np.sin(t + 0.2)])
    else:
        corners = np.array([[100.0, 100.0], [220.0, 130.0], [150.0, 140.0], [140.0, 210.0]])
        poly = np.concatenate([np.linspace(corners[j], corners[(j + 1) % 4], 50, endpoint=False) for j in range(4)])
        if shape == "repeated vertex":
            poly = np.insert(poly, 60, poly[60], axis=0)
    pts = np.concatenate([rng.uniform(poly.min(0) - 20.0, poly.max(0) + 20.0, (5000, 2)), poly[::7],
                          poly[::5] + rng.normal(0.0, 1e-9, (len(poly[::5]), 2))])
    got = closed_polyline_signed_distance(poly, pts[:, 0], pts[:, 1])
    want = _numpy_chords(poly, pts[:, 0], pts[:, 1])
    assert got.shape == want.shape and np.array_equal(got.view(np.int64), want.view(np.int64))
    grid = closed_polyline_signed_distance(poly, pts[:100, 0].reshape(10, 10), pts[:100, 1].reshape(10, 10))
    assert grid.shape == (10, 10) and np.array_equal(grid.ravel(), want[:100])
