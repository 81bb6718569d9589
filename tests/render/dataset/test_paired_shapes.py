"""Paired design cells that show different shapes share each slot's pose: the view check of a paired slot
uses the union of every cell's shapes."""
from __future__ import annotations

import numpy as np

from edgetruth.render.testing import TINY_CAMERA

DESIGN = """
[spec]
name = "paired_shapes"
camera = "cam.toml"
spp = 4
edge_spp = 16

[design]
distance_range_cm = [60, 90]
count = 6
lateral_fraction = 1.0
tilt_max_deg = 10

[[design.factor]]
name = "layout"
levels = [
  { name = "small", irradiance_w_m2 = 0.0044, shapes = [{ type = "circle", diameter_m = 0.03 }] },
  { name = "wide", irradiance_w_m2 = 0.0044, shapes = [{ type = "circle", diameter_m = 0.03 },
    { type = "rectangle", offset_m = [0.09, 0.02], width_m = 0.04, height_m = 0.02 }] },
  { name = "preset", irradiance_w_m2 = 0.0044, target = "T1" },
]
"""


def test_cells_with_different_shapes_draw_the_same_pose_per_slot(tmp_path):
    from edgetruth.render.dataset.image import job_pose, paired_view_outline, target_pose
    from edgetruth.render.scene.ground_truth import outline_in_view, view_outline_local
    from edgetruth.render.dataset.spec import load_spec

    (tmp_path / "cam.toml").write_text(TINY_CAMERA)
    (tmp_path / "s.toml").write_text(DESIGN)
    spec = load_spec(tmp_path / "s.toml")
    jobs = [j for j in spec.jobs if j.slot is not None]
    assert len(jobs) == 18 and len({j.group for j in jobs}) == 3
    union = paired_view_outline(spec, spec.target_size_m)
    by_slot: dict = {}
    for j in jobs:
        pose = target_pose(spec, j, j.camera)
        by_slot.setdefault(j.slot, []).append(pose)
        # every cell's own shapes are inside the image at the shared pose
        assert outline_in_view(j.camera, pose.to_camera(view_outline_local(j.target, spec.target_size_m)), 0.0)
    assert all(p == ps[0] for ps in by_slot.values() for p in ps)
    # the union bounds every cell: the wide cell's rectangle reaches 0.11 m from the centre (T1: 0.065 m)
    assert np.isclose(np.max(np.abs(union[:, :2])), 0.11)
    # the check is needed: each cell's own view points draw a different pose for some slot
    own: dict = {}
    for j in jobs:
        own.setdefault(j.group, []).append(
            job_pose(j, j.camera, view_outline_local(j.target, spec.target_size_m, paired=True)))
    small, wide, preset = own.values()
    assert any(p != q for p, q in zip(small, wide))
    assert small == preset  # the bounding square alone bounds a small centred circle: no change there
