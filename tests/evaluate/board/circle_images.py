"""Synthetic views of an asymmetric circle grid whose every pixel is the exact lens-weighted coverage of the
circles (``board_frame``'s composite with the shading flat; no Mitsuba), and their exact truth (test support, not a
test module): used by the tests of ``evaluate.board.circles`` and of the board study on circle grids."""
from __future__ import annotations

import numpy as np

#: the grid's spacing (m): OpenCV's squareSize of ``GRID``
SPACING_M = 0.012
PATTERN = "circles:4x5:asymmetric"


def views():
    """(camera, CirclesGrid, [(name, image)] six views (3000 at white), [circles truth per view])."""
    from edgetruth.render.optics.camera import camera_from_dict
    from edgetruth.render.scene import board_frame as bf
    from edgetruth.render.scene.circles_grid import CirclesGrid
    from edgetruth.render.scene.circles_truth import circles_ground_truth
    from edgetruth.render.scene.edge_band import band_width_px
    from edgetruth.render.scene.pose import Pose

    cam = camera_from_dict({"width_px": 320, "height_px": 240, "pitch_um": 12.0, "focal_length_mm": 8.0,
                            "f_number": 8.0, "focus_distance_m": 0.4, "distortion": {"k1": -0.12, "k2": 0.05}})
    grid = CirclesGrid(cols=4, rows=5, spacing_m=SPACING_M, diameter_m=0.009, asymmetric=True, margin_m=0.01)
    reach = band_width_px(cam, 1.0)
    dark = 1.0 - grid.circle_reflectance / grid.board_reflectance
    out, truths = [], []
    poses = [Pose(0.42, 0.0, 0.0, 0.0, 0.0, 0.0), Pose(0.4, 0.03, 0.02, 30.0, 5.0, 8.0),
             Pose(0.45, -0.03, -0.02, -25.0, 20.0, -6.0), Pose(0.38, 0.02, 0.01, 10.0, -30.0, 12.0),
             Pose(0.44, -0.02, 0.03, -15.0, -25.0, 3.0), Pose(0.4, 0.0, 0.0, 35.0, 30.0, -10.0)]
    for k, pose in enumerate(poses):
        c = np.ones(cam.shape)
        for curve, ext in bf._dark_outlines(cam, pose, grid):
            x0, y0, x1, y1 = bf._box(ext, reach + 2.0, (0, 0, cam.width_px, cam.height_px))
            c[y0:y1, x0:x1] -= dark * bf.polygon_coverage(cam, curve, x0, y0, x1 - x0, y1 - y0, reach)
        out.append((f"v{k}", 3000.0 * c))
        truths.append(circles_ground_truth(cam, pose, grid)["circles"])
    return cam, grid, out, truths


def write_views(folder) -> tuple:
    """``views`` written as 16-bit PNGs ``v0.png`` ... into ``folder`` -> (camera, [paths], [circles truth per
    view])."""
    import cv2

    cam, _, vs, truths = views()
    paths = []
    for name, img in vs:
        p = folder / f"{name}.png"
        cv2.imwrite(str(p), np.clip(np.rint(img), 0, 65535).astype(np.uint16))
        paths.append(p)
    return cam, paths, truths
