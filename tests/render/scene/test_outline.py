"""Exact outline ground truth under distortion: the distorted curve, not the chords between corners."""
from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from edgetruth.render.optics.camera import load_camera
from edgetruth.render.scene.outline import OutlineCurve
from edgetruth.render.scene.pose import Pose

POSES = [Pose(0.6, 0.12, 0.09, 3.0, -2.0, 8.0), Pose(1.5, -0.2, 0.1), Pose(2.8, 0.3, -0.25, 1.0, 1.0, -5.0)]


def _chord_miss_px(cam, pose):
    """Largest distance of the distorted sides from the straight chords between the distorted corners."""
    c = OutlineCurve(cam, pose, "square", 0.13)
    t = np.linspace(0, 1, 4001)[:-1]
    pts = c.points(t)
    corners = c.points(np.array([0, 0.25, 0.5, 0.75]))
    side = np.minimum((4 * t).astype(int), 3)
    a, b = corners[side], corners[(side + 1) % 4]
    d = b - a
    n = np.column_stack([-d[:, 1], d[:, 0]]) / np.linalg.norm(d, axis=1, keepdims=True)
    return float(np.max(np.abs(((pts - a) * n).sum(1))))


@pytest.mark.parametrize("shape", ["square", "circle"])
@pytest.mark.parametrize("pose", POSES)
def test_polyline_lies_on_the_projected_outline(shape, pose):
    cam = load_camera()
    c = OutlineCurve(cam, pose, shape, 0.13)
    t = c.parameters()
    poly = c.polyline()
    rvec, _ = cv2.Rodrigues(pose.rotation)
    ref, _ = cv2.projectPoints(c.local(t), rvec, pose.translation_m, cam.K, cam.dist_coeffs)
    np.testing.assert_allclose(poly, ref.reshape(-1, 2), atol=1e-6)
    steps = np.linalg.norm(np.diff(np.vstack([poly, poly[:1]]), axis=0), axis=1)
    assert steps.max() <= 2.0 + 1e-9
    assert c.chord_error_px() < 1e-3
    if shape == "square":  # the corners are vertices of the polyline
        corners = c.points(np.array([0, 0.25, 0.5, 0.75]))
        assert all(np.min(np.linalg.norm(poly - k, axis=1)) < 1e-9 for k in corners)


def test_chords_between_corners_miss_the_distorted_sides():
    """Why 4 corners are not enough: the default lens bows a side ~0.3 px at 0.6 m; a strong lens by pixels."""
    cam = load_camera()
    near = Pose(0.6, 0.2, 0.15)
    default_miss = _chord_miss_px(cam, near)
    strong_miss = _chord_miss_px(replace(cam, distortion=(-0.3, 0.12, 0.0, 0.0, 0.0)), near)
    quick_miss = _chord_miss_px(cam.scaled(2), Pose(1.2, 0.15, 0.1))
    print(f"chord misses: default lens at 0.6 m {default_miss:.3f} px, strong lens {strong_miss:.3f} px, "
          f"quick camera at 1.2 m {quick_miss:.3f} px")
    assert default_miss > 0.2 and strong_miss > 1.0 and quick_miss > 0.02


def test_signed_distance_to_the_curve():
    cam = replace(load_camera(), distortion=(-0.3, 0.12, 0.001, -0.001, 0.0))
    c = OutlineCurve(cam, Pose(0.7, 0.1, 0.08, 5, 3, 20), "square", 0.13)
    rng = np.random.default_rng(1)
    dense = c.points(np.linspace(0, 1, 200001)[:-1])
    centre = dense.mean(0)
    q = centre + rng.uniform(-1, 1, (400, 2)) * np.ptp(dense, axis=0)
    sd = c.signed_distance(q[:, 0], q[:, 1])
    brute = np.min(np.linalg.norm(q[:, None, :] - dense[None, ::5, :], axis=2), axis=1)
    ring = np.ascontiguousarray(dense[::50], dtype=np.float32)
    inside = cv2.pointPolygonTest(ring, (float(centre[0]), float(centre[1])), False) > 0
    assert inside and c.signed_distance(*centre) < 0  # negative inside (the dark target), positive outside
    np.testing.assert_allclose(np.abs(sd), brute, atol=2e-3)  # brute force on a 0.02 px polyline
    sign = np.array([cv2.pointPolygonTest(ring, (float(x), float(y)), False) for x, y in q])
    far = np.abs(sd) > 0.1
    assert np.all(np.sign(sd[far]) == -np.sign(sign[far]))
