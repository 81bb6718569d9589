"""The ground truth of a ChArUco board image (``kind = "charuco"``): its ChArUco corners and its markers.

Per image: every inner (ChArUco) corner with its id, every marker's four corners with its id (both in
the image through the lens, and undistorted), whether each lies in the frame, the pose of OpenCV's board
frame, and the dark rectangles the render drew (board frame: their exact outlines through the lens are
``OutlineCurve.polygon(camera, pose, rect)``, as a board of squares' are).  On a board curled by ``bend``
the points lie on the curled surface; the object points stay the flat print's.
"""
from __future__ import annotations

import numpy as np

from edgetruth.conventions import inside_image
from edgetruth.render.optics.camera import Camera
from edgetruth.render.scene.charuco import CharucoBoard
from edgetruth.render.scene.pose import Pose
from edgetruth.render.scene.targets import TARGET_STANDOFF_M


def _image_points(camera: Camera, pose: Pose, board: CharucoBoard, model_pts: np.ndarray, bend) -> dict:
    """Board-frame points (..., 3) at the print's plane -> distorted and undistorted pixels, in view."""
    shape = model_pts.shape[:-1]
    local = model_pts.reshape(-1, 3) - board.squares.centre_model_m  # the rendering's board frame
    local[:, 2] = -TARGET_STANDOFF_M
    cam = pose.to_camera(local if bend is None else bend.lift(local))
    dist = camera.project(cam, distorted=True)
    und = camera.project(cam, distorted=False)
    view = inside_image(dist[:, 0], dist[:, 1], camera.shape) & (cam[:, 2] > 0)
    return {"distorted_px": dist.reshape(shape + (2,)), "undistorted_px": und.reshape(shape + (2,)),
            "in_view": view.reshape(shape)}


def charuco_ground_truth(camera: Camera, pose: Pose, board: CharucoBoard, bend=None,
                         sag_m: float | None = None) -> dict:
    """The truth's ``charuco`` block (with ``pose_model``, OpenCV's board frame) and ``true_distance_m``
    (and ``board_bend`` on a curled board: the height of each dark rectangle's corners)."""
    from edgetruth.render.scene.ground_truth import _bend_truth, model_pose

    corners = board.corner_object_points()
    markers = board.marker_object_points()
    c = _image_points(camera, pose, board, corners, bend)
    m = _image_points(camera, pose, board, markers, bend)
    quads = board.dark_quads_model()
    out = {
        "charuco": {
            **board.to_dict(), "standoff_m": TARGET_STANDOFF_M,
            "frame": "OpenCV's CharucoBoard frame: origin at the board's top-left outer corner, x right, y down, "
                     "z into the board, metres (board.getChessboardCorners / getObjPoints)",
            "pose_model": model_pose(pose, board.squares),
            "corners": {"ids": list(range(len(corners))),
                        "order": "ChArUco corner id k = r (cols - 1) + c at ((c + 1) square_m, (r + 1) square_m)",
                        "object_points_m": corners.tolist(),
                        "distorted_px": c["distorted_px"].tolist(), "undistorted_px": c["undistorted_px"].tolist(),
                        "in_view": c["in_view"].tolist()},
            "markers": {"ids": board.marker_ids.tolist(),
                        "order": "per marker its corners top-left, top-right, bottom-right, bottom-left of its "
                                 "bitmap (cv2.aruco's order)",
                        "object_points_m": markers.tolist(),
                        "corners_distorted_px": m["distorted_px"].tolist(),
                        "corners_undistorted_px": m["undistorted_px"].tolist(),
                        "in_view": m["in_view"].all(axis=1).tolist()},
            "dark_rectangles_m": quads.tolist(),
            "dark_rectangles_meaning": "every dark rectangle rendered (board frame, corners top-left, top-right, "
                                       "bottom-right, bottom-left): the chessboard's dark squares, then each "
                                       "marker's dark cells merged; exact outlines through the lens: "
                                       "edgetruth.render.scene.outline.OutlineCurve.polygon(camera, pose, "
                                       "rect - plate centre, at z = -standoff_m)",
        },
        "true_distance_m": float(pose.translation_m[2]),
    }
    if bend is not None:
        out["board_bend"] = _bend_truth(bend, board.squares.quads_local(0.0), sag_m)
    return out
