"""Cameras, poses and a spec template shared by the own-scene tests (tests/render/scene/test_shapes_truth.py,
test_scene_outline.py, test_texture.py, the clutter tests)."""
from __future__ import annotations

from edgetruth.render.optics.camera import Camera
from edgetruth.render.scene.pose import Pose

PINHOLE = Camera(width_px=320, height_px=240, pitch_um=20.0, focal_length_mm=8.0, f_number=0.0,
                 focus_distance_m=0.8)  # fx = 400 px, no distortion
DISTORTED = Camera(width_px=320, height_px=240, pitch_um=20.0, focal_length_mm=8.0, f_number=0.0,
                   focus_distance_m=0.8, distortion=(-0.25, 0.12, 1e-3, -8e-4, 0.0))
FRONTAL = Pose(0.8, 0.0, 0.0, 0.0, 0.0, 0.0)
TILTED = Pose(0.8, 0.02, -0.01, 12.0, -8.0, 20.0)
Z_M = 10e-6  # shape 0's stand-off from the board

#: a one-group spec; ``{extra}`` holds the group's own keys
GROUP_SPEC = """
[spec]
name = "x"
camera_scale = 16
edge_mode = "path"
board_mode = "path"
[[group]]
name = "g"
{extra}
"""


def polyline_region(poly, q):
    """(inside, distance in px) of the points ``q`` (N, 2) to the closed polyline ``poly``: the exact distance to
    every chord (not the k-d tree shortcut of ``closed_polyline_signed_distance``), for tests over whole images."""
    import numpy as np
    from matplotlib.path import Path

    p = np.asarray(poly, float)
    inside = Path(p).contains_points(q)
    a, b = p, np.roll(p, -1, axis=0)
    d = b - a
    t = np.clip(((q[:, None] - a) * d).sum(2) / (d * d).sum(1), 0, 1)
    return inside, np.min(np.linalg.norm(q[:, None] - (a + t[..., None] * d), axis=2), axis=1)
