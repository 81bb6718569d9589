"""Paired factorial designs: every cell renders the same pose slots; cells that differ only in light
power and sensor settings reuse one radiance render, which equals a direct render of each level
(bit-exact for power-of-two light steps)."""
from __future__ import annotations

import numpy as np
import pytest

from edgetruth.render.testing import TINY_CAMERA

DESIGN = """
[spec]
name = "paired"
camera = "cam.toml"
spp = 4
edge_spp = 16             # the band around the targets is part of a unit's radiance
edge_mode = "path"
board_mode = "path"

[design]
mode = "{mode}"
distance_range_cm = [60, 90]
count = 2
lateral_fraction = 0.5
tilt_max_deg = 5

[[design.factor]]
name = "light"
levels = [
  {{ name = "L1", irradiance_w_m2 = 0.0044 }},
  {{ name = "L2", irradiance_w_m2 = 0.0022, sensor = {{ gain_db = 6.0206 }} }},
]

[[design.factor]]
name = "target"
levels = [ {{ name = "T1", target = "T1" }}, {{ name = "T2", target = "T2" }} ]

[[group]]
name = "boards"
kind = "checkerboard"
distance_range_cm = [70, 90]
count = 1
tilt_max_deg = 20
irradiance_w_m2 = 0.0044
"""


def _spec(tmp_path, mode="one_at_a_time"):
    (tmp_path / "cam.toml").write_text(TINY_CAMERA)
    p = tmp_path / "paired.toml"
    p.write_text(DESIGN.format(mode=mode))
    return p


def test_cells_share_the_pose_slots(tmp_path):
    from edgetruth.render.dataset.spec import load_spec

    spec = load_spec(_spec(tmp_path))
    cells = [g for g in spec.groups if g.paired]
    assert [g.name for g in cells] == ["L1_T1", "L2_T1", "L1_T2"]  # base, then one factor at a time
    assert [g.levels for g in cells][1] == {"light": "L2", "target": "T1"}
    assert all(g.distances_cm == cells[0].distances_cm for g in cells)
    jobs = [j for j in spec.jobs if j.slot is not None]
    by_slot = {}
    for j in jobs:
        by_slot.setdefault(j.slot, set()).add(j.pose_seed)
    assert all(len(s) == 1 for s in by_slot.values()) and len(by_slot) == 2
    assert len({j.seed for j in jobs}) == len(jobs)  # sensor noise stays independent per image
    # radiance units: the light levels of T1 share one; T2 has its own
    assert cells[0].radiance_unit == cells[1].radiance_unit != cells[2].radiance_unit
    assert spec.units() == [[0], [1, 3], [2, 4], [5], [6]]  # the board, then (unit, slot)
    (tmp_path / "f").mkdir()
    full = load_spec(_spec(tmp_path / "f", mode="full"))
    assert len([g for g in full.groups if g.paired]) == 4


@pytest.mark.slow
def test_reused_radiance_equals_a_direct_render_bit_for_bit(tmp_path, fast_variant):
    from edgetruth.render import open_dataset
    from edgetruth.render.dataset.image import get_rig, job_pose
    from edgetruth.render.dataset.driver import render_spec
    from edgetruth.render.scene.edge_band import render_edge_band
    from edgetruth.render.scene.ground_truth import target_ground_truth, target_outline_local
    from edgetruth.render.dataset.spec import load_spec

    spec = load_spec(_spec(tmp_path))
    out = tmp_path / "data"
    timings: dict = {}
    render_spec(spec, out, progress=False, announce=lambda s: None, timings=timings)
    ds = open_dataset(out)
    assert timings["reused"] == 2  # L2_T1 reused L1_T1's radiance in both slots
    for slot in (0, 1):
        a, b, c = (ds[f"{i:04d}_{n}"] for i, n in ((1 + slot, "L1_T1"), (3 + slot, "L2_T1"), (5 + slot, "L1_T2")))
        assert a.truth["pose"] == b.truth["pose"] == c.truth["pose"]
        assert b.truth["design"]["radiance_scale"] == 0.5 and b.truth["design"]["slot"] == slot
        # a direct render of the L2 level with the same sampler seed: exactly half of L1 (power of two)
        job = spec.jobs[b.index]
        rig = get_rig("target", job.camera, spec.render, spec.target_size_m)
        pose = job_pose(job, job.camera, target_outline_local("square", spec.target_size_m))
        rig.set_state("T1", pose, job.irradiance_w_m2)
        direct = rig.render(job.render_seed)
        gt = target_ground_truth(job.camera, pose, "T1", spec.target_size_m)  # and its edge band, as render_job does
        render_edge_band(direct, job.camera, spec.render, job, pose, gt, None, job.irradiance_w_m2)
        assert np.array_equal(direct, b.radiance)
        assert np.array_equal(a.radiance * np.float32(0.5), b.radiance)
        assert not np.array_equal(a.image, b.image)  # independent sensor noise per level
    # two pool workers: one task per radiance unit, so the reuse survives, and the bytes are the same
    pooled, t2 = tmp_path / "pooled", {}
    render_spec(spec, pooled, progress=False, announce=lambda s: None, timings=t2, workers=2)
    assert t2["reused"] == 2
    for f in sorted(out.glob("*.png")) + sorted(out.glob("*.exr")):
        assert (pooled / f.name).read_bytes() == f.read_bytes(), f.name
    # a second render of the same spec is byte-identical (reuse does not depend on order or workers)
    out2 = tmp_path / "data2"
    render_spec(spec, out2, progress=False, announce=lambda s: None, only=[4, 1])
    for n in ("0001_L1_T1", "0004_L2_T1"):
        assert (out / f"{n}.exr").read_bytes() == (out2 / f"{n}.exr").read_bytes()
        assert (out / f"{n}.png").read_bytes() == (out2 / f"{n}.png").read_bytes()


def test_duplicate_factor_names_are_one_line_errors(tmp_path):
    from edgetruth.errors import InputError
    from edgetruth.render.dataset.spec import load_spec

    p = _spec(tmp_path)
    p.write_text(p.read_text().replace('name = "light"', 'name = "target"'))
    with pytest.raises(InputError, match="unique"):
        load_spec(p)


def test_two_factors_setting_one_key_is_refused(tmp_path):
    from edgetruth.errors import InputError
    from edgetruth.render.dataset.spec import load_spec

    p = _spec(tmp_path)
    p.write_text(p.read_text().replace('{ name = "T2", target = "T2" }', '{ name = "T2", target = "T2", '
                                       'irradiance_w_m2 = 0.001 }'))
    with pytest.raises(InputError, match="two factors"):
        load_spec(p)
