"""Ground truth geometry of a posed board: target outlines and checkerboard corners in pixels.

Points are projected with the camera's exact model (``Camera.project``), in OpenCV
pixel coordinates, both distorted (what the image shows) and undistorted (the ideal
pinhole image with the same K).
"""
from __future__ import annotations

import numpy as np

from edgetruth.render.camera import Camera
from edgetruth.render.targets import TARGET_STANDOFF_M, TARGETS, Checkerboard
from edgetruth.render.pose import Pose

CIRCLE_OUTLINE_POINTS = 720


def _project_both(camera: Camera, pts_cam: np.ndarray) -> dict:
    return {"distorted_px": camera.project(pts_cam, distorted=True).tolist(),
            "undistorted_px": camera.project(pts_cam, distorted=False).tolist()}


def target_outline_local(shape: str, size_m: float, n_circle: int = CIRCLE_OUTLINE_POINTS) -> np.ndarray:
    """Outline points in the board frame at the target's plane (z = −stand-off).

    Square: 4 corners, order top-left, top-right, bottom-right, bottom-left (image orientation
    for an untilted board).  Circle: ``n_circle`` points at angles 2πk/n from local +x towards +y.
    """
    h = size_m / 2.0
    z = -TARGET_STANDOFF_M
    if shape == "square":
        return np.array([[-h, -h, z], [h, -h, z], [h, h, z], [-h, h, z]])
    t = 2.0 * np.pi * np.arange(n_circle) / n_circle
    return np.stack([h * np.cos(t), h * np.sin(t), np.full_like(t, z)], axis=1)


def target_ground_truth(camera: Camera, pose: Pose, target: str, size_m: float) -> dict:
    spec = TARGETS[target]
    centre_cam = pose.to_camera(np.array([[0.0, 0.0, -TARGET_STANDOFF_M]]))
    outline = pose.to_camera(target_outline_local(spec["shape"], size_m))
    return {
        "target": {"id": target, "shape": spec["shape"], "material": spec["material"],
                   "size_m": size_m, "size_meaning": "side" if spec["shape"] == "square" else "diameter",
                   "reflectance": spec["reflectance"], "standoff_m": TARGET_STANDOFF_M,
                   **({"ggx_alpha": spec["alpha"], "ior": spec["eta"]} if "alpha" in spec else {})},
        "true_distance_m": float(centre_cam[0, 2]),  # Z of the target centre (the ranging quantity)
        "true_range_m": float(np.linalg.norm(centre_cam)),
        "centre": _project_both(camera, centre_cam),
        "outline": {"kind": "corners" if spec["shape"] == "square" else "points",
                    "order": ("top-left, top-right, bottom-right, bottom-left (board frame)"
                              if spec["shape"] == "square" else "angle 2*pi*k/n from board +x towards +y"),
                    **_project_both(camera, outline)},
        "defocus_radius_px": float(camera.defocus_radius_px(centre_cam[0, 2])),
    }


def checker_ground_truth(camera: Camera, pose: Pose, board: Checkerboard) -> dict:
    corners = pose.to_camera(board.inner_corners_local(-TARGET_STANDOFF_M))
    return {
        "checkerboard": {**board.to_dict(), "standoff_m": TARGET_STANDOFF_M},
        "corners": {"order": "row-major, x fastest (cv2.findChessboardCorners order for this orientation)",
                    "object_points_m": board.inner_corners_local(0.0).tolist(),
                    **_project_both(camera, corners)},
        "true_distance_m": float(pose.distance_m),
    }


def outline_in_view(camera: Camera, pts_cam: np.ndarray, margin_px: float) -> bool:
    """All points in front of the camera and inside the image with ``margin_px`` to spare."""
    from edgetruth.conventions import inside_image

    if np.any(pts_cam[:, 2] <= 0):
        return False
    px = camera.project(pts_cam)
    return bool(np.all(inside_image(px[:, 0], px[:, 1], camera.shape, margin_px)))
