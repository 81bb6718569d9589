"""The truth of a circle-grid image: per circle its exact distorted outline, the image of its centre and the
centre of its pinhole image ellipse (the perspective bias; ``render.scene.circle_conic``).

The circles are printed flush (``TARGET_STANDOFF_M`` in front of the plate): their centres, conics and outlines
lie on that plane; the object points are the print's (z = 0), as a calibration uses them.
"""
from __future__ import annotations

import numpy as np

from edgetruth.render.optics.camera import Camera
from edgetruth.render.scene import circle_conic as cc
from edgetruth.render.scene.circles_grid import CirclesGrid
from edgetruth.render.scene.pose import Pose
from edgetruth.render.scene.shapes import TARGET_STANDOFF_M


def model_pose(pose: Pose, grid: CirclesGrid) -> dict:
    """The pose of the object points' frame: X_cam = R X_model + t (X_board = X_model - centre_model_m)."""
    r = pose.rotation
    t = pose.translation_m - r @ grid.centre_model_m
    return {"R": r.tolist(), "t_m": t.tolist(),
            "meaning": "X_cam = R X_model + t (the frame of circles.object_points_m, circle 0 at its origin)"}


def circles_ground_truth(camera: Camera, pose: Pose, grid: CirclesGrid) -> dict:
    """The ``circles`` block of a circle-grid image's JSON (docs/formats.md)."""
    from edgetruth.conventions import inside_image

    z = -TARGET_STANDOFF_M
    centres = grid.centres_local(z)
    cam = pose.to_camera(centres)
    dist = camera.project(cam, distorted=True)
    und = camera.project(cam, distorted=False)
    R, t = pose.rotation, pose.translation_m
    conic_px = cc.conic_centre_px(camera.K, R, t, centres[:, :2], grid.radius_m, z)
    H = cc.plane_homography(camera.K, R, t, z)
    conics = cc.image_conic(H, cc.circle_conics(centres[:, :2], grid.radius_m))
    polylines, params, chord = [], [], 0.0
    for curve in grid.dark_curves(camera, pose, z):
        tt = curve.parameters()
        polylines.append(curve.points(tt).tolist())
        params.append(tt.tolist())
        chord = max(chord, curve.chord_error_px())
    in_view = inside_image(dist[:, 0], dist[:, 1], camera.shape) & (cam[:, 2] > 0)
    return {
        "circles": {
            **grid.to_dict(), "standoff_m": TARGET_STANDOFF_M, "count": grid.n_circles,
            "order": "row-major, column fastest: OpenCV's object points (cv2.findCirclesGrid's order for a board "
                     "seen upright)",
            "object_points_m": grid.object_points(0.0).tolist(),
            "pose_model": model_pose(pose, grid),
            "centres_local_m": centres.tolist(),
            "centre_distorted_px": dist.tolist(),
            "centre_undistorted_px": und.tolist(),
            "centre_meaning": "the image of each circle's 3-D centre: projected with the camera's exact model "
                              "(distorted: what the image shows; undistorted: the pinhole with the same K)",
            "conic_centre_undistorted_px": conic_px.tolist(),
            "bias_undistorted_px": (conic_px - und).tolist(),
            "conic_meaning": "the centre of the ellipse each circle images to under the pinhole (before "
                             "distortion): the pinhole image of the board point c - (r^2 / Z_c) (R20, R21) "
                             "(edgetruth.render.scene.circle_conic); bias = that centre minus the image of the "
                             "circle's centre (undistorted px)",
            "conics_undistorted": conics.tolist(),
            "conics_meaning": "per circle the 3x3 symmetric matrix Q (unit Frobenius norm) of its pinhole image: "
                              "(x, y, 1) Q (x, y, 1)^T = 0 in undistorted OpenCV pixels, Q = H^-T C H^-1",
            "in_view": in_view.tolist(),
            "polylines_distorted_px": polylines,
            "polylines_parameter": params,
            "polyline_meaning": "per circle, dense points ON its exact distorted outline (the circle through the "
                                "lens), parameter t in [0, 1) the angle 2 pi t from the board's +x towards +y; "
                                "edgetruth.render.scene.outline.OutlineCurve.ellipse evaluates it exactly",
            "polyline_chord_error_px": chord,
            "path_polygon_error_m": grid.polygon_error_m(),
            "path_polygon_meaning": "board_mode = path renders each circle as a regular polygon of the circle's "
                                    "area, within this of the circle; board_mode = frame covers the exact circle"},
        "true_distance_m": float(pose.translation_m[2]),
    }
