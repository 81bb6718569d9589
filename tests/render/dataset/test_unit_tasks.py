"""How a paired design's images go to the workers (``driver.unit_tasks``): one task per radiance unit, and the units
of a design slot whose preset targets share an outline in one task, so the worker computes their exact coverage
once (``edge_band.band_coverage`` keeps its last results: the same inputs, the same bits)."""
from __future__ import annotations

import numpy as np

from edgetruth.render.dataset.driver import unit_tasks
from edgetruth.render.dataset.spec import load_spec


def test_quick_slots_share_one_task_per_outline():
    spec = load_spec("quick")
    tasks = unit_tasks(spec, np.arange(spec.n_images))
    flat = [i for t in tasks for i in t]
    assert sorted(flat) == list(range(spec.n_images))
    rank = {i: u for u, unit in enumerate(spec.units()) for i in unit}
    shapes = {"T1": "square", "T2": "circle", "T3": "square", "T4": "square"}
    for t in tasks:
        jobs = [spec.jobs[i] for i in t]
        ranks = [rank[i] for i in t]
        assert ranks == sorted(ranks)  # a unit's images together, units in order
        if jobs[0].kind != "target":
            assert len(t) == 1
            continue
        assert len({j.slot for j in jobs}) == 1 and len({shapes[j.target] for j in jobs}) == 1
        assert len(t) == (6 if shapes[jobs[0].target] == "square" else 1)  # G1-G4 on T1, T3, T4; or T2
    # only the units change their grouping: a path-traced design keeps one task per unit
    path = load_spec("sweep_albedo_light_gloss")
    assert [list(t) for t in unit_tasks(path, np.arange(path.n_images))] == [sorted(u) for u in path.units()]


def test_coverage_of_a_shared_outline_is_computed_once_and_is_the_same_bits(fast_variant):
    from edgetruth.render.optics.camera import load_camera
    from edgetruth.render.scene import edge_band as eb
    from edgetruth.render.scene.outline import OutlineCurve
    from edgetruth.render.scene.pose import Pose

    cam = load_camera("quick")
    pose = Pose(1.2, 0.02, -0.01, 2.0, -1.5, roll_deg=7.0)
    frame = (0, 0, cam.width_px, cam.height_px)
    poly = OutlineCurve(cam, pose, "square", 0.13).polyline()
    tiles = eb.band_tiles([poly], frame, 3.0, eb.ANALYTIC_TILE_PX)[:2]
    eb._COVERAGE_CACHE.clear()
    a = eb.band_coverage(cam, "T1", pose, 0.13, frame, tiles, eb.ANALYTIC_TILE_PX)
    b = eb.band_coverage(cam, "T3", pose, 0.13, frame, tiles, eb.ANALYTIC_TILE_PX)  # the same square
    assert all(x is y for x, y in zip(a, b)) and not a[2].flags.writeable
    circle = eb.band_coverage(cam, "T2", pose, 0.13, frame, tiles, eb.ANALYTIC_TILE_PX)
    assert circle[2] is not a[2] and not np.array_equal(circle[2], a[2])
    eb._COVERAGE_CACHE.clear()
    fresh = eb.band_coverage(cam, "T4", pose, 0.13, frame, tiles, eb.ANALYTIC_TILE_PX)
    assert all(np.array_equal(x, y) for x, y in zip(a, fresh)) and np.any((a[2] > 0.0) & (a[2] < 1.0))
    for k in range(eb.COVERAGE_CACHE_SIZE + 2):  # bounded
        eb.band_coverage(cam, "T1", Pose(1.2 + 0.01 * k, 0.0, 0.0, 0.0, 0.0), 0.13, frame, tiles[:1],
                         eb.ANALYTIC_TILE_PX)
    assert len(eb._COVERAGE_CACHE) == eb.COVERAGE_CACHE_SIZE
