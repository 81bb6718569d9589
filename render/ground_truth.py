"""Ground truth geometry of a posed board: target outlines, checkerboard corners and the squares of a
board of squares in pixels.

Points are projected with the camera's exact model (``Camera.project``), in OpenCV
pixel coordinates, both distorted (what the image shows) and undistorted (the ideal
pinhole image with the same K).  A target's outline also comes as a dense polyline of the
*distorted* curve (``edgetruth.render.outline.OutlineCurve`` evaluates it exactly): under
distortion a square's sides are curves, not the chords between its corners.  With a moving
camera everything is at mid-exposure, plus the outline at the start and end of the exposure.
"""
from __future__ import annotations

import numpy as np

from edgetruth.render.camera import Camera
from edgetruth.render.optical_edge import optical_edge_ground_truth
from edgetruth.render.outline import OutlineCurve, camera_points_at
from edgetruth.render.targets import (BOARD_HALF_SIZE_M, BOARD_REFLECTANCE, TARGET_STANDOFF_M, TARGETS, Checkerboard,
                                      SquareBoard)
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


def motion_ground_truth(camera: Camera, exposure_s: float, points_cam: np.ndarray, centre_cam: np.ndarray) -> dict:
    """Where the outline points and the centre are at the start and end of the exposure (τ = ∓T/2)."""
    half = 0.5 * exposure_s
    taus = np.linspace(-half, half, 9)
    return {"velocity_m_s": list(camera.velocity_m_s), "angular_velocity_deg_s": list(camera.angular_velocity_deg_s),
            "exposure_s": exposure_s, "reference": "outline, centre and pose are at mid-exposure",
            "camera_motion": "at time tau from mid-exposure the camera sits at v*tau, rotated by omega*tau",
            "outline_start_distorted_px": camera.project(camera_points_at(camera, points_cam, -half)).tolist(),
            "outline_end_distorted_px": camera.project(camera_points_at(camera, points_cam, half)).tolist(),
            "centre_track_tau_s": taus.tolist(),
            "centre_track_distorted_px": [camera.project(camera_points_at(camera, centre_cam, t))[0].tolist()
                                          for t in taus]}


def target_ground_truth(camera: Camera, pose: Pose, target: str, size_m: float, exposure_s: float = 0.0) -> dict:
    spec = TARGETS[target]
    centre_cam = pose.to_camera(np.array([[0.0, 0.0, -TARGET_STANDOFF_M]]))
    outline = pose.to_camera(target_outline_local(spec["shape"], size_m))
    curve = OutlineCurve(camera, pose, spec["shape"], size_m)
    t = curve.parameters()
    extra = {}
    if camera.moving:
        extra["motion"] = motion_ground_truth(camera, exposure_s, outline, centre_cam)
    return {
        "target": {"id": target, "shape": spec["shape"], "material": spec["material"],
                   "size_m": size_m, "size_meaning": "side" if spec["shape"] == "square" else "diameter",
                   "reflectance": spec["reflectance"], "standoff_m": TARGET_STANDOFF_M,
                   **({"ggx_alpha": spec["alpha"], "ior": spec["eta"]} if "alpha" in spec else {})},
        "board": {"material": "white_matte", "reflectance": BOARD_REFLECTANCE,
                  "half_size_m": list(BOARD_HALF_SIZE_M)},
        "true_distance_m": float(centre_cam[0, 2]),  # Z of the target centre (the ranging quantity)
        "true_range_m": float(np.linalg.norm(centre_cam)),
        "centre": _project_both(camera, centre_cam),
        "outline": {"kind": "corners" if spec["shape"] == "square" else "points",
                    "order": ("top-left, top-right, bottom-right, bottom-left (board frame)"
                              if spec["shape"] == "square" else "angle 2*pi*k/n from board +x towards +y"),
                    **_project_both(camera, outline),
                    "polyline_distorted_px": curve.points(t).tolist(),
                    "polyline_parameter": t.tolist(),
                    "polyline_meaning": "dense points ON the distorted outline curve (square: clockwise from the "
                                        "top-left corner, parameter t in [0, 1): side floor(4t); circle: angle "
                                        "2*pi*t); chords stay within polyline_chord_error_px of the curve, which "
                                        "edgetruth.render.outline.OutlineCurve evaluates exactly",
                    "polyline_chord_error_px": curve.chord_error_px(),
                    "optical_edge": optical_edge_ground_truth(curve, t)},
        "defocus_radius_px": float(camera.defocus_radius_px(centre_cam[0, 2])),
        **extra,
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


def model_pose(pose: Pose, board: SquareBoard) -> dict:
    """The pose of a squares board's *model* frame: X_cam = R X_model + t (the rendering's board frame
    is centred on the squares: X_model = X_board + c)."""
    r = pose.rotation
    t = pose.translation_m - r @ board.centre_model_m
    return {"R": r.tolist(), "t_m": t.tolist(), "t_model_unit": (t / board.model_unit_m).tolist(),
            "meaning": "X_cam = R X_model + t (model frame of squares.model_points_m; t_model_unit: t in the "
                       "model's unit, model_unit_m)"}


def squares_ground_truth(camera: Camera, pose: Pose, board: SquareBoard) -> dict:
    """Every square's corners (model order), in the image and undistorted, and its exact distorted
    outline as a dense polyline; the model points and the model frame's pose."""
    quads = board.quads_local(-TARGET_STANDOFF_M)  # the printed squares (flush: 10 um in front of the plate)
    n = len(quads)
    cam_pts = pose.to_camera(quads.reshape(-1, 3))
    dist = camera.project(cam_pts, distorted=True).reshape(n, 4, 2)
    und = camera.project(cam_pts, distorted=False).reshape(n, 4, 2)
    from edgetruth.conventions import inside_image

    in_view = inside_image(dist[..., 0], dist[..., 1], camera.shape).all(axis=1) & (cam_pts[:, 2].reshape(n, 4) > 0).all(1)
    polylines, params, chord = [], [], 0.0
    for q in quads:
        curve = OutlineCurve.polygon(camera, pose, q)
        t = curve.parameters()
        polylines.append(curve.points(t).tolist())
        params.append(t.tolist())
        chord = max(chord, curve.chord_error_px())
    return {
        "squares": {**board.to_dict(), "standoff_m": TARGET_STANDOFF_M, "count": n,
                    "order": "model order (the model file's lines, or a pattern row-major from the top-left "
                             "square); each square's corners in the model's order (a pattern: top-left, top-right, "
                             "bottom-right, bottom-left)",
                    "model_points_m": board.model_points(0.0).tolist(),
                    "pose_model": model_pose(pose, board),
                    "corners_distorted_px": dist.tolist(),
                    "corners_undistorted_px": und.tolist(),
                    "in_view": in_view.tolist(),
                    "polylines_distorted_px": polylines,
                    "polylines_parameter": params,
                    "polyline_meaning": "per square, dense points ON its exact distorted outline (its straight "
                                        "sides through the lens), from corner 0 in the model's corner order; "
                                        "parameter t in [0, 1): side floor(4t) from corner floor(4t) to the next; "
                                        "edgetruth.render.outline.OutlineCurve.polygon evaluates it exactly",
                    "polyline_chord_error_px": chord},
        "true_distance_m": float(pose.translation_m[2]),
    }


def outline_in_view(camera: Camera, pts_cam: np.ndarray, margin_px: float) -> bool:
    """All points in front of the camera and inside the image with ``margin_px`` to spare."""
    from edgetruth.conventions import inside_image

    if np.any(pts_cam[:, 2] <= 0):
        return False
    px = camera.project(pts_cam)
    return bool(np.all(inside_image(px[:, 0], px[:, 1], camera.shape, margin_px)))
