"""The optical edge's JSON block is computed once per (outline, pose): the cells of a design slot
share it (issue 19 item 2), and a remembered block is the computed one, value for value."""
from __future__ import annotations

import numpy as np

from edgetruth.render.optics import optical_edge as oe
from edgetruth.render.optics.camera import load_camera
from edgetruth.render.scene.outline import OutlineCurve
from edgetruth.render.scene.pose import Pose


def test_memo_returns_the_computed_block_and_private_lists(monkeypatch):
    monkeypatch.setattr(oe, "_MEMO", {})
    cam = load_camera("quick")
    t = np.linspace(0.0, 1.0, 40, endpoint=False)
    curve = OutlineCurve(cam, Pose(0.6, 0.05, -0.03, 2.0, -1.0), "square", 0.13)  # defocused: offsets != 0
    calls = []
    block = oe._optical_edge_block
    monkeypatch.setattr(oe, "_optical_edge_block", lambda c, tt: calls.append(1) or block(c, tt))
    a = oe.optical_edge_ground_truth(curve, t)
    a["offset_50_px"][0] = 99.0  # the caller's list: the memo keeps its own
    b = oe.optical_edge_ground_truth(OutlineCurve(cam, Pose(0.6, 0.05, -0.03, 2.0, -1.0), "square", 0.13), t)
    assert len(calls) == 1  # an equal curve and t: no second quadrature
    assert b == block(curve, t) and b["offset_50_px"][0] != 99.0
    assert max(abs(v) for v in b["offset_50_px"]) > 1e-3
    oe.optical_edge_ground_truth(OutlineCurve(cam, Pose(0.6, 0.05, -0.03, 2.0, -1.0), "circle", 0.13), t)
    assert len(calls) == 2  # another outline: computed
    monkeypatch.setattr(oe, "_MEMO_SIZE", 1)
    for d in (0.7, 0.8, 0.9):
        oe.optical_edge_ground_truth(OutlineCurve(cam, Pose(d), "square", 0.13), t)
    assert len(oe._MEMO) == 1  # bounded
