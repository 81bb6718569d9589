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
