"""Ground truth geometry of a posed board: target outlines, checkerboard corners and the squares of a
board of squares in pixels.

Points are projected with the camera's exact model (``Camera.project``), in OpenCV
pixel coordinates, both distorted (what the image shows) and undistorted (the ideal
pinhole image with the same K).  A target's outline also comes as a dense polyline of the
*distorted* curve (``edgetruth.render.scene.outline.OutlineCurve`` evaluates it exactly): under
distortion a square's sides are curves, not the chords between its corners.  With a moving
camera everything is at mid-exposure, plus the outline at the start and end of the exposure.
"""
from __future__ import annotations

import numpy as np

from edgetruth.render.optics.camera import Camera
from edgetruth.render.optics.optical_edge import optical_edge_ground_truth
from edgetruth.render.scene.outline import OutlineCurve, camera_points_at
from edgetruth.render.scene.targets import (BOARD_HALF_SIZE_M, BOARD_REFLECTANCE, TARGET_STANDOFF_M, TARGETS, Checkerboard,
                                      SquareBoard)
from edgetruth.render.scene.pose import Pose

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


def target_ground_truth(camera: Camera, pose: Pose, target, size_m: float, exposure_s: float = 0.0) -> dict:
    """The truth of a target image: ``target`` a preset id (T1..T4) or a ``TargetScene``."""
    from edgetruth.render.scene.target_scene import TargetScene

    if isinstance(target, TargetScene):
        return scene_ground_truth(camera, pose, target, exposure_s)
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
                                        "edgetruth.render.scene.outline.OutlineCurve evaluates exactly",
                    "polyline_chord_error_px": curve.chord_error_px(),
                    "optical_edge": optical_edge_ground_truth(curve, t)},
        "defocus_radius_px": float(camera.defocus_radius_px(centre_cam[0, 2])),
        **extra,
    }


def _bend_truth(bend, points_local: np.ndarray, sag_m: float | None) -> dict:
    """The truth's ``board_bend``: the bend and the height of each of the board's ``points_local``."""
    return {**bend.to_dict(), "heights_m": bend.height_m(points_local.reshape(-1, 3)).reshape(
                points_local.shape[:-1]).tolist(),
            "mesh_sag_m": sag_m, "mesh_meaning": "the rendered plate and squares are triangle meshes; "
                                                 "no chord leaves the surface by more than mesh_sag_m"}


def checker_ground_truth(camera: Camera, pose: Pose, board: Checkerboard, bend=None,
                         sag_m: float | None = None) -> dict:
    """The checkerboard's inner corners, on a board curled by ``bend`` (``render.scene.bend``; the
    object points stay the flat model's: the heights are in ``board_bend``)."""
    local = board.inner_corners_local(-TARGET_STANDOFF_M)
    corners = pose.to_camera(local if bend is None else bend.lift(local))
    out = {
        "checkerboard": {**board.to_dict(), "standoff_m": TARGET_STANDOFF_M},
        "corners": {"order": "row-major, x fastest (cv2.findChessboardCorners order for this orientation)",
                    "object_points_m": board.inner_corners_local(0.0).tolist(),
                    **_project_both(camera, corners)},
        "true_distance_m": float(pose.distance_m),
    }
    if bend is not None:
        out["board_bend"] = _bend_truth(bend, board.inner_corners_local(0.0), sag_m)
    return out


def model_pose(pose: Pose, board: SquareBoard) -> dict:
    """The pose of a squares board's *model* frame: X_cam = R X_model + t (the rendering's board frame
    is centred on the squares: X_model = X_board + c)."""
    r = pose.rotation
    t = pose.translation_m - r @ board.centre_model_m
    return {"R": r.tolist(), "t_m": t.tolist(), "t_model_unit": (t / board.model_unit_m).tolist(),
            "meaning": "X_cam = R X_model + t (model frame of squares.model_points_m; t_model_unit: t in the "
                       "model's unit, model_unit_m)"}


def squares_ground_truth(camera: Camera, pose: Pose, board: SquareBoard, bend=None,
                         sag_m: float | None = None) -> dict:
    """Every square's corners (model order), in the image and undistorted, and its exact distorted
    outline as a dense polyline; the model points and the model frame's pose.  On a board curled by
    ``bend`` (``render.scene.bend``) the corners and outlines lie on the curled surface; the model points
    stay flat (the print's), each corner's height is in ``board_bend``."""
    quads = board.quads_local(-TARGET_STANDOFF_M)  # the printed squares (flush: 10 um in front of the plate)
    n = len(quads)
    cam_pts = pose.to_camera((quads if bend is None else bend.lift(quads)).reshape(-1, 3))
    dist = camera.project(cam_pts, distorted=True).reshape(n, 4, 2)
    und = camera.project(cam_pts, distorted=False).reshape(n, 4, 2)
    from edgetruth.conventions import inside_image

    in_view = inside_image(dist[..., 0], dist[..., 1], camera.shape).all(axis=1) & (cam_pts[:, 2].reshape(n, 4) > 0).all(1)
    polylines, params, chord = [], [], 0.0
    for q in quads:
        curve = OutlineCurve.polygon(camera, pose, q, bend=bend)
        t = curve.parameters()
        polylines.append(curve.points(t).tolist())
        params.append(t.tolist())
        chord = max(chord, curve.chord_error_px())
    out = {
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
                                        "edgetruth.render.scene.outline.OutlineCurve.polygon evaluates it exactly",
                    "polyline_chord_error_px": chord},
        "true_distance_m": float(pose.translation_m[2]),
    }
    if bend is not None:
        out["board_bend"] = _bend_truth(bend, board.quads_local(0.0), sag_m)
    return out


def _board_corners(half_size_m=BOARD_HALF_SIZE_M) -> np.ndarray:
    hx, hy = half_size_m
    return np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])


def outline_in_view(camera: Camera, pts_cam: np.ndarray, margin_px: float) -> bool:
    """All points in front of the camera and inside the image with ``margin_px`` to spare."""
    from edgetruth.conventions import inside_image

    if np.any(pts_cam[:, 2] <= 0):
        return False
    px = camera.project(pts_cam)
    return bool(np.all(inside_image(px[:, 0], px[:, 1], camera.shape, margin_px)))


# --- the shape catalogue ------------------------------------------------------------------------------
def view_outline_local(target, size_m: float, paired: bool = False) -> np.ndarray:
    """Board points that must stay in view when a pose is drawn: a preset's outline (paired design slots:
    the square, which bounds the circle, so every cell draws the same pose), or a ``TargetScene``'s shapes'
    outlines (plus that square when paired)."""
    from edgetruth.render.scene.target_scene import TargetScene

    if not isinstance(target, TargetScene):
        return target_outline_local("square" if paired else TARGETS[target]["shape"], size_m)
    xy = target.sample_points()
    pts = np.column_stack([xy, np.full(len(xy), -TARGET_STANDOFF_M)])
    return np.concatenate([target_outline_local("square", size_m), pts]) if paired else pts


def shape_outline_truth(camera: Camera, pose: Pose, scene, k: int) -> list[dict]:
    """Every outline of shape ``k`` of ``scene``: its exact distorted curve (dense polyline, parameters,
    chord error), its corners, and the parts of it that later shapes and clutter leave visible."""
    shape = scene.shapes[k]
    standoff = (k + 1) * TARGET_STANDOFF_M
    occluders = list(scene.shapes[k + 1:]) + raised_covers(pose, scene, standoff)
    return outline_truth(camera, pose, shape.outlines(), standoff, occluders)



def raised_covers(pose: Pose, scene, source_height_m: float, skip: int | None = None) -> list:
    """The clutter items that can hide points ``source_height_m`` in front of the board (as occluders): the
    planar items held higher, and every box (the segment to the eye decides); ``skip``: an item's index to
    leave out (a box's own silhouette)."""
    from edgetruth.render.scene.clutter import BoxCover, RaisedCover

    eye = tuple(_eye_board(pose))
    return [BoxCover(c.shape, eye, source_height_m) if c.is_box else RaisedCover(c, eye, source_height_m)
            for i, c in enumerate(getattr(scene, "clutter", ()))
            if i != skip and (c.is_box or c.raised_m > source_height_m)]


def _eye_board(pose: Pose) -> np.ndarray:
    """The camera centre in the board frame."""
    return pose.rotation.T @ (-pose.translation_m)


def outline_truth(camera: Camera, pose: Pose, outlines, standoff: float, occluders: list) -> list[dict]:
    """Per outline (at ``standoff`` in front of the board): its exact distorted curve, the parts no occluder
    hides, their polylines and ends, and its corners."""
    from edgetruth.render.scene.shapes import visible_intervals

    out = []
    for o in outlines:
        curve = OutlineCurve.of(camera, pose, o, standoff)
        t = curve.parameters()
        vis = visible_intervals(o, occluders)
        pieces = []
        tt = np.concatenate([t, t + 1.0])  # the full polyline's parameters, unwrapped: corners included
        for t0, t1 in vis:
            inner = tt[(tt > t0 + 1e-12) & (tt < t1 - 1e-12)]
            pieces.append(curve.points(np.concatenate([[t0], inner, [t1]])).tolist())
        ends = [e for iv in vis for e in iv] if vis != [[0.0, 1.0]] else []
        d = {"name": o.name, "curve": o.kind,
             "polyline_distorted_px": curve.points(t).tolist(), "polyline_parameter": t.tolist(),
             "polyline_chord_error_px": curve.chord_error_px(),
             "visible_intervals": vis,
             "visible_polylines_distorted_px": pieces,
             "occlusion_points_distorted_px": curve.points(np.mod(ends, 1.0)).tolist() if ends else []}
        if o.kind == "polygon":
            tc = o.corner_parameters()
            d["corners_distorted_px"] = curve.points(tc).tolist()
            d["corners_undistorted_px"] = curve.points(tc, distorted=False).tolist()
            d["corners_visible"] = [any(a - 1e-12 <= tt <= b + 1e-12 or a - 1e-12 <= tt + 1 <= b + 1e-12
                                        for a, b in vis) for tt in tc]
        else:
            d["conic_board_m"] = dict(zip(("cx", "cy", "a", "b", "theta_rad"), o.conic))
        out.append(d)
    return out


def texture_placement(camera: Camera, pose: Pose, corners_xy, z_m: float, material) -> dict:
    """Where a printed texture lies: its image's four corners on the board (board frame, at z = ``z_m``) and
    in the image (distorted and undistorted px)."""
    from pathlib import Path

    from edgetruth.render.scene.materials import texture_levels

    h, w = texture_levels(material.texture, material.texture_sha256).shape
    xy = np.asarray(corners_xy, float)
    cam = pose.to_camera(np.column_stack([xy, np.full(len(xy), z_m)]))
    return {"file": Path(material.texture).name, "sha256": material.texture_sha256, "size_px": [w, h],
            "filter": "nearest", "corners_board_m": xy.tolist(), **{f"corners_{k}": v for k, v in
                                                                   _project_both(camera, cam).items()},
            "order": "the image's top-left, top-right, bottom-right, bottom-left corners (the outer corners of its "
                     "corner pixels)",
            "meaning": "texel (row i, column j) of the W x H image is printed on the quad between the corners at "
                       "bilinear parameters u in [j, j + 1] / W (top-left -> top-right), v in [i, i + 1] / H "
                       "(top-left -> bottom-left), with reflectance albedo x its gray level / full scale; the quad is "
                       "the shape's bounding box in its own frame (edgetruth.render.scene.shapes.Shape.texture_frame), "
                       "the print shows only inside the shape's outline (not in a ring's hole)"}


def scene_ground_truth(camera: Camera, pose: Pose, scene, exposure_s: float = 0.0) -> dict:
    """The truth of a ``TargetScene`` image.  ``target`` and ``outline`` describe shape 0 (the ranged
    target) as for a preset, so the evaluation reads either; ``shapes`` lists every shape with every
    outline (a ring: outer and inner), its corners and its visible parts."""
    p = scene.primary
    standoff = TARGET_STANDOFF_M
    centre_cam = pose.to_camera(np.array([[p.offset_m[0], p.offset_m[1], -standoff]]))
    o = p.outlines()[0]
    curve = OutlineCurve.of(camera, pose, o, standoff)
    t = curve.parameters()
    square = p.type == "rectangle" and p.width_m == p.height_m
    circle = p.type == "circle"
    if o.kind == "polygon":
        corners_xy = np.asarray(o.vertices, float)
        kind, order = "corners", "the polygon's vertices in order (rectangle: top-left, top-right, bottom-right, " \
                                 "bottom-left of the unturned shape, board frame)"
    else:
        corners_xy = o.local_xy(np.arange(CIRCLE_OUTLINE_POINTS) / CIRCLE_OUTLINE_POINTS)
        kind, order = "points", "angle 2*pi*k/n from the conic's turned +x axis towards +y"
    pts_cam = pose.to_camera(np.column_stack([corners_xy, np.full(len(corners_xy), -standoff)]))
    m = p.material
    size = {"rectangle": p.width_m, "circle": p.diameter_m, "ring": p.outer_diameter_m, "ellipse": max(p.axes_m),
            "grid": (p.cols - 1) * p.pitch_m[0] + p.element_size_m, "checkerboard": p.cols * p.square_m}.get(
        p.type, float(2 * np.max(np.linalg.norm(corners_xy - p.offset_m, axis=1))))
    extra = {}
    if camera.moving:
        extra["motion"] = motion_ground_truth(camera, exposure_s, pts_cam, centre_cam)
    return {
        "target": {"id": scene.id, "shape": "square" if square else ("circle" if circle else p.type),
                   "type": p.type, "material": m.label or m.type, "material_params": m.to_dict(),
                   "size_m": size,
                   "size_meaning": {"rectangle": "width", "circle": "diameter", "ring": "outer diameter",
                                    "ellipse": "longer axis", "grid": "width along its x (outer element edges)",
                                    "checkerboard": "width along its x (cols x square_m)"
                                    }.get(p.type, "largest extent"),
                   "reflectance": m.albedo if m.type != "roughconductor" else None, "standoff_m": standoff,
                   "offset_m": list(p.offset_m), "rotation_deg": p.rotation_deg,
                   **({"ggx_alpha": m.alpha, "ior": m.eta} if m.type == "roughplastic" else {})},
        "board": {"material": scene.board.label or scene.board.type, "material_params": scene.board.to_dict(),
                  "reflectance": scene.board.albedo, "half_size_m": list(scene.board_half_size_m),
                  **({"texture": texture_placement(camera, pose, _board_corners(scene.board_half_size_m), 0.0,
                                                   scene.board)} if scene.board.texture else {}),
                  **({"outline": board_outline_truth(camera, pose, scene)}
                     if tuple(scene.board_half_size_m) != BOARD_HALF_SIZE_M else {})},
        "true_distance_m": float(centre_cam[0, 2]),
        "true_range_m": float(np.linalg.norm(centre_cam)),
        "centre": _project_both(camera, centre_cam),
        "outline": {"kind": kind, "order": order, **_project_both(camera, pts_cam),
                    "polyline_distorted_px": curve.points(t).tolist(), "polyline_parameter": t.tolist(),
                    "polyline_meaning": "dense points ON shape 0's exact distorted outline (polygon: side floor(n t) "
                                        "from vertex floor(n t); conic: angle 2*pi*t); the full outline, whether or "
                                        "not later shapes cover part of it (shapes[0] says which parts are visible)",
                    "polyline_chord_error_px": curve.chord_error_px(),
                    "optical_edge": optical_edge_ground_truth(curve, t)},
        "shapes": [{"index": k, **s.to_dict(), "standoff_m": (k + 1) * TARGET_STANDOFF_M,
                    "centre": _project_both(camera, pose.to_camera(
                        np.array([[s.offset_m[0], s.offset_m[1], -(k + 1) * TARGET_STANDOFF_M]]))),
                    "outlines": shape_outline_truth(camera, pose, scene, k),
                    **({"texture": texture_placement(camera, pose, s.texture_corners(),
                                                     -(k + 1) * TARGET_STANDOFF_M, s.material)}
                       if s.material.texture else {}),
                    **({"inner_corners": checker_inner_corners_truth(camera, pose, scene, k)}
                       if s.type == "checkerboard" else {})} for k, s in enumerate(scene.shapes)],
        "shapes_meaning": "shape k lies (k + 1) x 10 um in front of the board and covers shapes 0..k-1 (a ring covers "
                          "its whole outer disk: its hole shows the board); per outline: the exact distorted curve "
                          "(edgetruth.render.scene.outline.OutlineCurve.of), visible_intervals [t0, t1] of its parameter "
                          "not covered by later shapes (t1 > 1 wraps), their polylines, and the points where a "
                          "covering shape cuts it (corners of the visible region)",
        "defocus_radius_px": float(camera.defocus_radius_px(centre_cam[0, 2])),
        **({"clutter": clutter_truth(camera, pose, scene)} if getattr(scene, "clutter", ()) else {}),
        **extra,
    }


def checker_inner_corners_truth(camera: Camera, pose: Pose, scene, k: int) -> dict:
    """The inner corners of checkerboard shape ``k`` (where four of its squares meet; two dark squares touch
    there): board frame, distorted and undistorted px, and whether each is visible (no later shape or
    clutter covers it)."""
    shape = scene.shapes[k]
    standoff = (k + 1) * TARGET_STANDOFF_M
    xy = shape.inner_corners()
    cam = pose.to_camera(np.column_stack([xy, np.full(len(xy), -standoff)]))
    hidden = np.zeros(len(xy), bool)
    for occ in list(scene.shapes[k + 1:]) + raised_covers(pose, scene, standoff):
        hidden |= occ.covers(xy)
    return {"order": "row-major, x fastest along the board's (turned) x: cv2.findChessboardCorners' order for an "
                     "untilted, unturned board; pattern_size [cols - 1, rows - 1]",
            "pattern_size": [shape.cols - 1, shape.rows - 1],
            "board_m": xy.tolist(), **_project_both(camera, cam), "visible": (~hidden).tolist(),
            "meaning": "each inner corner is where two dark squares touch at a corner; their outlines (r<row>c<col>, "
                       "one closed outline per dark square) both pass through it, so the outline is split there per "
                       "square: each dark square's 4 corners are its outline's corners"}


def board_outline_truth(camera: Camera, pose: Pose, scene) -> list[dict]:
    """The board's own outline (a group's ``board_size_m``): the edge between the board and the dark
    background beyond it, its exact distorted curve, the parts clutter leaves visible."""
    from edgetruth.render.scene.shapes import Outline

    o = Outline("board", "polygon", vertices=tuple(map(tuple, _board_corners(scene.board_half_size_m))))
    return outline_truth(camera, pose, [o], 0.0, raised_covers(pose, scene, 0.0))


def clutter_truth(camera: Camera, pose: Pose, scene) -> list[dict]:
    """Per clutter item: its outlines (exact distorted curves, the parts no nearer item hides) and, per
    light, its shadow on the board: exact for point and spot lights (a planar item's: the outline scaled by
    D / (D - h) about the light's foot; a box's: the convex hull of its corners' central projections), an
    area light's from its centre (the penumbra widens it by about side x h / (D - h) on each side) plus its
    exact umbra and penumbra (``area_shadow_regions``; the irradiance between: ``clutter_shadow_irradiance``).  A
    box's outline is its silhouette from the camera (``Box.silhouette``: a polygon of its corners, each side
    a straight 3-D edge through the lens), which nearer items may hide; its internal edges between faces
    are not recorded (they do not bound the board)."""
    from edgetruth.render.scene.clutter import FootprintCover, SpaceOutline, shadow_outline
    from edgetruth.render.scene.shapes import Outline

    out = []
    for c, item in enumerate(scene.clutter):
        if item.is_box:
            sil = item.shape.silhouette(_eye_board(pose))
            occ = raised_covers(pose, scene, 0.0, skip=c)  # other items; the prints lie under it
            outs = outline_truth(camera, pose, [SpaceOutline("silhouette", tuple(map(tuple, sil)))], 0.0, occ)
            outs[0]["vertices_board_m"] = sil.tolist()
            d = {"index": c, **item.to_dict(), "outlines": outs, "shadows": []}
        else:
            occ = raised_covers(pose, scene, item.raised_m)
            d = {"index": c, **item.to_dict(),
                 "outlines": outline_truth(camera, pose, item.shape.outlines(), item.raised_m, occ), "shadows": []}
        for i, lt in enumerate(scene.lights):
            lb = pose.rotation.T @ (np.asarray(lt.position_m, float) - pose.translation_m)  # board frame
            if item.is_box:
                poly = item.shape.shadow_polygon(lb)
                sh = [None] if poly is None else [Outline("outline", "polygon", vertices=tuple(map(tuple, poly)))]
                height = item.top_m
            else:
                sh = [shadow_outline(o, item.raised_m, lb) for o in item.shape.outlines()]
                height = item.raised_m
            if any(s is None for s in sh):
                d["shadows"].append({"light": i, "cast": False})
                continue
            dist = -float(lb[2])
            # what hides the shadow's edge in the image: the shapes on the board and every clutter item (a
            # box's own shadow also runs along its base, where the image shows the box: left out there)
            hide = list(scene.shapes) + raised_covers(pose, scene, 0.0)
            if item.is_box:
                hide.append(FootprintCover(item.shape, 2.0 * item.shape.base_m))
            rec = {"light": i, "cast": True, "exact": lt.type != "area", "light_board_m": lb.tolist()}
            if not item.is_box:
                rec["scale"] = dist / (dist - item.raised_m)
            rec["outlines"] = outline_truth(camera, pose, sh, 0.0, hide)
            if lt.type == "area":
                rec["penumbra_half_width_m"] = lt.size_m * height / (dist - height) / 2
                rec.update(area_shadow_regions(camera, pose, item, lt, hide))
            d["shadows"].append(rec)
        out.append(d)
    return out


#: vertices of the polygon standing in for a conic in the umbra and penumbra outlines (chords within
#: r (1 - cos(pi / 256)) = 7.5e-5 r of the exact curves)
REGION_CONIC_VERTICES = 256


def area_shadow_regions(camera: Camera, pose: Pose, item, light, hide: list) -> dict:
    """An area light's umbra and penumbra of a clutter item on the board.  For a convex occluder O (each
    outline of a planar item -- a rectangle, a convex polygon, a conic, a grid's element -- or a box) and
    the light's square: a board point is in the umbra iff every light point is blocked, iff its 4 corners
    are (the blocked part of the light is convex), so the umbra is the intersection of the 4 corners'
    shadows; the penumbra (the points any light point's shadow covers) is their convex hull (the shadow of
    O from a point p of the light moves by a linear-fractional map of p, so it stays in the hull of the
    corners' shadows, and the union is convex).  Conics: ``REGION_CONIC_VERTICES``-gons.  A non-convex
    polygon, or a light corner not further from the board than the item: not given (``regions_given``
    false).  The irradiance between them: ``clutter_shadow_irradiance``."""
    from edgetruth.render.scene.lights import area_corners_board
    from edgetruth.render.scene.polygons import convex_hull, convex_intersection
    from edgetruth.render.scene.shapes import Outline

    lc = area_corners_board(light, pose)
    if np.any(-lc[:, 2] <= item.top_m):
        return {"regions_given": False, "regions_meaning": "a corner of the light is not further from the board "
                "than the item's top: no bounded shadow from it"}
    if item.is_box:
        pieces = [("silhouette", [item.shape.shadow_polygon(c) for c in lc])]
        exact = True
    else:
        pieces, exact = [], True
        for o in item.shape.outlines():
            if o.kind == "ellipse":
                v = o.local_xy(np.arange(REGION_CONIC_VERTICES) / REGION_CONIC_VERTICES)
                exact = False
            else:
                v = np.asarray(o.vertices, float)
                if len(convex_hull(v)) != len(v):
                    return {"regions_given": False, "regions_meaning": "a non-convex polygon's umbra and penumbra are "
                            "not given; edgetruth.render.scene.ground_truth.clutter_shadow_irradiance gives the "
                            "irradiance"}
            h = item.raised_m
            pieces.append((o.name, [c[:2] + (-c[2] / (-c[2] - h)) * (v - c[:2]) for c in lc]))
    umbra, penumbra = [], []
    for name, shadows in pieces:
        pts = np.concatenate(shadows)
        penumbra.append(Outline(name, "polygon", vertices=tuple(map(tuple, pts[convex_hull(pts)]))))
        u = shadows[0]
        for sh in shadows[1:]:
            u = convex_intersection(u, sh)
        if len(u) >= 3 and abs(float(np.sum(u[:, 0] * np.roll(u[:, 1], -1) - np.roll(u[:, 0], -1) * u[:, 1]))) > 1e-18:
            umbra.append(Outline(name, "polygon", vertices=tuple(map(tuple, u))))
    return {"regions_given": True, "regions_exact": exact,
            "umbra": outline_truth(camera, pose, umbra, 0.0, hide),
            "penumbra": outline_truth(camera, pose, penumbra, 0.0, hide),
            "regions_meaning": "umbra: board points no part of the light reaches past this item (the intersection of "
                               "the shadows cast from the light's 4 corners; an outline per convex piece, none where "
                               "the light is too large to be hidden); penumbra: points some part of it is hidden "
                               "from (their convex hull); both exact for straight-sided items (regions_exact), "
                               f"conics as {REGION_CONIC_VERTICES}-gons; visible parts as for outlines"}


def clutter_shadow_irradiance(pose: Pose, scene, item_index: int, light_index: int, irradiance_w_m2: float,
                              points_board: np.ndarray) -> np.ndarray:
    """Irradiance (W/m^2) that light ``light_index`` gives at board points (N, 2) (z = 0) with clutter item
    ``item_index`` in its way (the others ignored).  Point and spot lights: 0 inside the item's exact shadow.
    Area lights and planar items: exact (``lights.unit_irradiance_occluded``: the light's projected solid
    angle minus its blocked part; conics as ``clutter.CONIC_POLYGON_VERTICES``-gons); boxes too (exact: the
    faces that face the point tile the blocked part)."""
    from edgetruth.render.scene.lights import unit_irradiance_occluded
    from edgetruth.render.scene.clutter import occluder_polygons, shadow_outline
    from edgetruth.render.scene.polygons import point_in_polygon

    item, lt = scene.clutter[item_index], scene.lights[light_index]
    xy = np.atleast_2d(np.asarray(points_board, float))
    if lt.type == "area":
        if item.is_box:  # a convex solid: its faces that face the point tile its projection
            return lt.emission_for(irradiance_w_m2, pose) * unit_irradiance_occluded(
                lt, pose, xy, [], item.top_m, faces_3d=list(item.shape.quads()))
        polys, _ = occluder_polygons(item.shape)
        return lt.emission_for(irradiance_w_m2, pose) * unit_irradiance_occluded(lt, pose, xy, polys, item.raised_m)
    e = lt.irradiance_at(irradiance_w_m2, pose, pose.to_camera(np.column_stack([xy, np.zeros(len(xy))])))
    lb = pose.rotation.T @ (np.asarray(lt.position_m, float) - pose.translation_m)
    if item.is_box:
        poly = item.shape.shadow_polygon(lb)
        inside = point_in_polygon(poly, xy) if poly is not None else np.zeros(len(xy), bool)
    else:
        inside = np.zeros(len(xy), bool)
        for o in item.shape.outlines():
            sh = shadow_outline(o, item.raised_m, lb)
            if sh is not None:
                inside |= (point_in_polygon(np.asarray(sh.vertices, float), xy) if sh.kind == "polygon" else
                           np.hypot(*((xy - sh.conic[:2]) @ _rot2(sh.conic[4]) / [sh.conic[2], sh.conic[3]]).T) < 1)
    return np.where(inside, 0.0, e)


def _rot2(theta: float) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


def _clutter_top(c: dict) -> float:
    """How far a clutter item's truth puts its nearest point in front of the board (a box: base + height)."""
    return float(c["raised_m"]) if "raised_m" in c else float(c["base_m"]) + float(c["size_m"][2])


class SceneOutline:
    """Every visible edge of a ``TargetScene`` image, read from its ground truth (``shapes``, ``clutter``):
    the parts of each shape's outlines that no later shape and no clutter hides, and the clutter's own
    outlines (clutter item c is layer ``len(shapes) + c`` in ``outlines``, ``edge_shape`` and ``shape_at``).

    - ``signed_distance(x, y)``: px to the nearest visible edge, > 0 on that outline's board side (outside
      its shape, inside a ring's hole);
    - ``edge_index(x, y)``: which outline that is (an index into ``outlines``, (shape index, outline name)
      pairs; a ``board_size_m`` board's own edge is (-1, "board")); ``edge_shape(x, y)``: its shape index;
    - ``corner_distance(x, y)``: px to the nearest corner of the visible edges (``corners_px``: the visible
      polygon corners and the points where a covering shape cuts an outline);
    - ``shape_at(x, y)``: which shape the image shows at the point (-1: the board, a ring's hole included).

    Distances come from the dense polylines (chords within ``polyline_chord_error_px`` <= 1e-3 px of the
    exact curves): the nearest of the segments next to the ``K_NEAREST`` nearest polyline vertices."""

    K_NEAREST = 8  # vertices whose segments are measured: far more than the 2 needed at <= 2 px spacing

    def __init__(self, gt: dict):
        self.outlines, self._full, self._pieces, self._flip = [], [], [], []
        corners = []
        n = len(gt["shapes"])
        # clutter item c is layer n + c, above every shape; nearer items (higher) hide further ones
        layers = [(s, int(s["index"])) for s in gt["shapes"]] + \
            [(c, n + int(c["index"])) for c in gt.get("clutter", [])]
        if gt.get("board", {}).get("outline"):  # a board_size_m board: its edge against the background, layer -1
            layers.append(({"outlines": gt["board"]["outline"]}, -1))
        self._top_first = [n + int(c["index"]) for c in sorted(gt.get("clutter", []), key=lambda c: -_clutter_top(c))] \
            + list(range(n - 1, -1, -1))
        for s, layer in layers:
            for o in s["outlines"]:
                self.outlines.append((layer, o["name"]))
                self._full.append(np.asarray(o["polyline_distorted_px"], float))
                self._pieces.append([np.asarray(p, float).reshape(-1, 2) for p in o["visible_polylines_distorted_px"]])
                # a ring's hole and the board's own outline: the board is inside
                self._flip.append(o["name"] == "inner" or layer == -1)
                if "corners_distorted_px" in o:
                    corners += [c for c, v in zip(o["corners_distorted_px"], o["corners_visible"]) if v]
                corners += list(o.get("occlusion_points_distorted_px", []))
        self.corners_px = np.asarray(corners, float).reshape(-1, 2)
        self.n_shapes = n
        # every visible piece as segments a -> b, with the outline each belongs to
        a, b, owner = [], [], []
        for i, pieces in enumerate(self._pieces):
            for p in pieces:
                if len(p) >= 2:
                    a.append(p[:-1])
                    b.append(p[1:])
                    owner.append(np.full(len(p) - 1, i))
        if a:
            self._a, self._b, self._owner = np.concatenate(a), np.concatenate(b), np.concatenate(owner)
        else:
            self._a = self._b = np.zeros((0, 2))
            self._owner = np.zeros(0, int)

    @classmethod
    def from_ground_truth(cls, gt: dict) -> "SceneOutline":
        return cls(gt)

    @property
    def shape(self) -> str:
        return "scene"

    def _nearest(self, x, y):
        """(distance px, outline index, query points (N, 2)) to the nearest visible segment."""
        from scipy.spatial import cKDTree

        q = np.column_stack([np.ravel(x), np.ravel(y)]).astype(float)
        m = len(self._a)
        if not m or not len(q):
            return np.full(len(q), np.inf), np.full(len(q), -1), q
        # segment k starts at vertex k; a vertex near q has its own segment (k) and the one ending at it
        # (k - 1 where segment k - 1 ends where k starts; else k is a piece's first vertex)
        k = min(self.K_NEAREST, m)
        tree = cKDTree(self._a)
        best, seg = np.empty(len(q)), np.empty(len(q), dtype=int)
        for s0 in range(0, len(q), 65536):  # blocks: memory ~ 65536 x 2k segments
            qq = q[s0:s0 + 65536]
            idx = np.asarray(tree.query(qq, k=k)[1]).reshape(len(qq), k)
            cand = np.concatenate([idx, np.maximum(idx - 1, 0)], axis=1)
            a, b = self._a[cand], self._b[cand]  # (n, 2k, 2)
            d = b - a
            u = np.clip(np.sum((qq[:, None] - a) * d, axis=2) / np.maximum(np.sum(d * d, axis=2), 1e-300), 0.0, 1.0)
            dist = np.linalg.norm(qq[:, None] - (a + u[..., None] * d), axis=2)
            j = np.argmin(dist, axis=1)
            r = np.arange(len(qq))
            best[s0:s0 + len(qq)], seg[s0:s0 + len(qq)] = dist[r, j], cand[r, j]
        return best, self._owner[seg], q

    def visible_points_px(self) -> np.ndarray:
        """(N, 2) the vertices of every visible piece of every outline (px)."""
        return np.concatenate([self._a, self._b]) if len(self._a) else np.zeros((0, 2))

    def edge_index(self, x, y) -> np.ndarray:
        """Index into ``outlines`` of the nearest visible edge of each point (-1: the scene shows none)."""
        return self._nearest(x, y)[1].reshape(np.shape(x))

    def edge_shape(self, x, y) -> np.ndarray:
        """Shape index of the nearest visible edge of each point."""
        i = self._nearest(x, y)[1]
        shp = np.array([s for s, _ in self.outlines] + [-1])
        return shp[i].reshape(np.shape(x))

    def signed_distance(self, x, y) -> np.ndarray:
        """px to the nearest visible edge, > 0 on its board side."""
        from edgetruth.render.edge_truth import closed_polyline_signed_distance

        dist, idx, q = self._nearest(x, y)
        out = np.array(dist)
        for i in np.unique(idx[idx >= 0]):
            sel = idx == i
            sign = np.sign(closed_polyline_signed_distance(self._full[i], q[sel, 0], q[sel, 1]))
            sign[sign == 0] = 1.0
            out[sel] = (-sign if self._flip[i] else sign) * dist[sel]
        return out.reshape(np.shape(x))

    def corner_distance(self, x, y) -> np.ndarray:
        """px to the nearest corner of the visible edges (inf where there is none: e.g. uncovered conics)."""
        x, y = np.asarray(x, float), np.asarray(y, float)
        shape = np.broadcast(x, y).shape
        if not len(self.corners_px):
            return np.full(shape, np.inf)
        from scipy.spatial import cKDTree

        q = np.column_stack([np.ravel(np.broadcast_to(x, shape)), np.ravel(np.broadcast_to(y, shape))])
        return cKDTree(self.corners_px).query(q)[0].reshape(shape)

    def shape_at(self, x, y) -> np.ndarray:
        """Index of the shape the image shows at each point (the topmost shape whose outer outline -- a
        grid: any element's -- holds it), -1 on the board (a ring's hole shows the board)."""
        from matplotlib.path import Path as _Path

        x, y = np.asarray(x, float), np.asarray(y, float)
        shape = np.broadcast(x, y).shape
        q = np.column_stack([np.ravel(np.broadcast_to(x, shape)), np.ravel(np.broadcast_to(y, shape))])
        out = np.full(len(q), -1)
        todo = np.ones(len(q), bool)
        for k in self._top_first:
            mine = [i for i, (s, _) in enumerate(self.outlines) if s == k]
            outer = [i for i in mine if not self._flip[i]]
            inner = [i for i in mine if self._flip[i]]
            inside = np.zeros(len(q), bool)
            for i in outer:  # a grid: any of its elements
                inside[todo] |= _Path(self._full[i]).contains_points(q[todo])
            hole = np.zeros(len(q), bool)
            if inner and inside.any():
                hole[inside] = _Path(self._full[inner[0]]).contains_points(q[inside])
            out[inside & ~hole] = k
            todo &= ~inside  # the shape (or its hole, showing the board) hides everything below
        return out.reshape(shape)


def image_outline(gt: dict):
    """The exact distorted truth of every visible edge of a target image's JSON: ``OutlineEdge`` (shape 0's outline)
    where the image shows one outline (a preset T1-T4, a scene of one shape), ``SceneOutline`` where it shows several
    (shapes, a ring's two edges, clutter).  Both give ``signed_distance`` (> 0 on the bright board) and
    ``corner_distance`` in px."""
    from edgetruth.render.edge_truth import OutlineEdge

    if sum(len(s.get("outlines", ())) for s in gt.get("shapes", []) + gt.get("clutter", [])) > 1:
        return SceneOutline.from_ground_truth(gt)
    return OutlineEdge.from_ground_truth(gt)
