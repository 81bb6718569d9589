"""Emissive shapes on black: scenes whose exact image is known analytically.

With radiance 1 and no other light, a pixel's value is the fraction of its area
(and of the aperture, under defocus) covered by the shape's image, so sums and
moments of the rendered image can be compared with projected geometry.  Used by
the accuracy tests and ``edgetruth verify``.
"""
from __future__ import annotations

import numpy as np

from edgetruth.render.optics.camera import Camera
from edgetruth.render.optics.lens_sensor import sensor_dict
from edgetruth.render.scene.pose import Pose
from edgetruth.render.scene.sample_passes import render_in_passes


def _facing_camera(local_scale: tuple[float, float], pose: Pose) -> np.ndarray:
    m = np.diag([local_scale[0], -local_scale[1], -1.0, 1.0])  # normal towards the camera
    return pose.matrix @ m


def render_emissive(camera: Camera, shapes: list[tuple[str, float, Pose]], spp: int = 256,
                    sampler: str = "multijitter", seed: int = 0, crop=None, exposure_s: float = 0.0) -> np.ndarray:
    """Render emissive ``(kind, half_size_m, pose)`` shapes (kind: 'square' or 'disk') on black.

    Returns the radiance (H, W) float64 — each pixel's covered fraction (times the lens's
    relative illumination).  ``exposure_s``: the shutter time of a moving camera.  Loads a new
    scene per call: meant for tests, not batch rendering.
    """
    import mitsuba as mi

    scene = {"type": "scene", "integrator": {"type": "direct"},
             "sensor": sensor_dict(camera, {"type": sampler, "sample_count": spp}, crop, exposure_s=exposure_s)}
    for i, (kind, half, pose) in enumerate(shapes):
        scene[f"s{i}"] = {"type": "rectangle" if kind == "square" else "disk",
                          "to_world": mi.ScalarTransform4f(_facing_camera((half, half), pose).tolist()),
                          "emitter": {"type": "area", "radiance": {"type": "uniform", "value": 1.0}}}
    loaded = mi.load_dict(scene)
    return render_in_passes(lambda s, n: np.asarray(mi.render(loaded, seed=s, spp=n))[..., 1], seed, spp,
                            mi.variant(), sampler).astype(np.float64)


def centroid(img: np.ndarray, x0: int = 0, y0: int = 0) -> tuple[float, float]:
    """Intensity centroid in OpenCV pixel coordinates (``x0, y0``: offset of ``img`` in the frame)."""
    h, w = img.shape
    ys, xs = np.mgrid[0:h, 0:w]
    s = img.sum()
    return float((xs * img).sum() / s + x0), float((ys * img).sum() / s + y0)


def second_moments(img: np.ndarray) -> tuple[float, float]:
    """Variance of the intensity distribution along x and y (pixels²)."""
    cx, cy = centroid(img)
    h, w = img.shape
    ys, xs = np.mgrid[0:h, 0:w]
    s = img.sum()
    return float(((xs - cx) ** 2 * img).sum() / s), float(((ys - cy) ** 2 * img).sum() / s)
