"""A [design] whose levels name board kinds compares boards on the same pose slots: slot k of the chessboard, the
circle grid and the ChArUco board has the same board-centre pose; a level's board kind beside target cells is
refused."""
from __future__ import annotations

import numpy as np
import pytest

from edgetruth.errors import InputError
from edgetruth.render.dataset.image import job_pose, view_points
from edgetruth.render.dataset.spec import load_spec

SPEC = """
[spec]
name = "boards_paired"
camera = "default"
camera_scale = 4
board_mode = "frame"
edge_spp = 0
checkerboard = {{ cols = 10, rows = 7, square_m = 0.03, margin_m = 0.03 }}
circles_grid = {{ cols = 4, rows = 11, spacing_m = 0.02, diameter_m = 0.016, asymmetric = true, margin_m = 0.02 }}
charuco = {{ cols = 10, rows = 7, square_m = 0.03, marker_m = 0.022, dictionary = "DICT_4X4_50" }}

[design]
kind = "{kind}"
mode = "full"
distance_range_cm = [55, 120]
count = 6
lateral_fraction = 0.9
tilt_max_deg = 35
roll_max_deg = 10

[[design.factor]]
name = "pattern"
levels = [ {{ name = "chess" }}, {{ name = "circles", kind = "circles_grid" }}, {{ name = "charuco", kind = "charuco" }} ]
"""


def _spec(tmp_path, kind="checkerboard"):
    p = tmp_path / "boards.toml"
    p.write_text(SPEC.format(kind=kind))
    return load_spec(p)


def test_board_cells_draw_one_pose_per_slot(tmp_path):
    spec = _spec(tmp_path)
    assert [g.kind for g in spec.groups] == ["checkerboard", "circles_grid", "charuco"]
    poses = {}
    for job in spec.jobs:
        pose = job_pose(job, job.camera, view_points(spec, job))
        poses.setdefault(job.slot, []).append(np.array([pose.distance_m, pose.lateral_x_m, pose.lateral_y_m,
                                                        pose.tilt_x_deg, pose.tilt_y_deg, pose.roll_deg]))
    assert len(poses) == 6
    for slot, ps in poses.items():
        assert len(ps) == 3
        np.testing.assert_array_equal(ps[0], ps[1], err_msg=f"slot {slot}")
        np.testing.assert_array_equal(ps[0], ps[2], err_msg=f"slot {slot}")
    # the slots differ from each other (a draw, not one pose)
    assert len({round(float(p[0][3]), 6) for p in poses.values()}) == 6


def test_the_view_check_holds_every_cells_board(tmp_path):
    spec = _spec(tmp_path)
    pts = view_points(spec, spec.jobs[0])
    plates = [spec.checkerboard, spec.circles_grid, spec.charuco.squares]
    assert len(pts) == sum(len(b.plate_corners_local()) for b in plates)


def test_a_board_kind_beside_target_cells_is_refused(tmp_path):
    with pytest.raises(InputError, match="every cell must be a board"):
        _spec(tmp_path, kind="target")
