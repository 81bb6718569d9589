"""The "which pattern?" study (evaluate/board/which_pattern): a chessboard, a circle grid and a ChArUco board
rendered on the same poses, each calibrated with each detector against the exact truth; the report, its paired
tests and the circle-centre bias; a second run resumes from what the first measured."""
from __future__ import annotations

import json

import numpy as np
import pytest

from edgetruth.evaluate.board.which_pattern.measure import distortion_field_error_px, point_errors_px

#: a small size: the study's boards and design at half the default camera's pixels (light / 4: the same signal
#: per pixel), 3 slots, one focus, one light
SPEC = """
[spec]
name = "which_pattern_ci"
camera = "default"
camera_scale = 2
spp = 16
edge_spp = 0
board_mode = "frame"
sampler = "multijitter"
checkerboard = { cols = 10, rows = 7, square_m = 0.03, margin_m = 0.03 }
circles_grid = { cols = 4, rows = 11, spacing_m = 0.02, diameter_m = 0.016, asymmetric = true, margin_m = 0.02 }
charuco = { cols = 10, rows = 7, square_m = 0.03, marker_m = 0.022, dictionary = "DICT_4X4_50" }

[design]
kind = "checkerboard"
mode = "full"
distance_range_cm = [55, 80]
count = 3
lateral_fraction = 0.5
tilt_max_deg = 35
roll_max_deg = 10

[[design.factor]]
name = "pattern"
levels = [ { name = "chessboard" }, { name = "circles", kind = "circles_grid" }, { name = "charuco", kind = "charuco" } ]

[[design.factor]]
name = "light"
levels = [ { name = "bright", irradiance_w_m2 = 0.3 } ]
"""


def test_distortion_field_error_is_zero_for_the_true_lens_and_grows_with_k1():
    K = np.array([[400.0, 0, 319.5], [0, 400.0, 239.5], [0, 0, 1]])
    d = np.array([-0.1, 0.02, 0.0, 0.0, 0.0])
    assert distortion_field_error_px(K, d, K, d, (640, 480)) == {"rms": 0.0, "max": 0.0}
    e1 = distortion_field_error_px(K, d + [0.001, 0, 0, 0, 0], K, d, (640, 480))
    e2 = distortion_field_error_px(K, d + [0.002, 0, 0, 0, 0], K, d, (640, 480))
    # first order at the corner: undistort moves by f dk1 r_u^3 / (dr_d/dr_u), r_u the corner's undistorted radius
    from scipy.optimize import brentq

    k1, k2 = d[0], d[1]
    r_d = np.hypot(319.5, 239.5) / 400.0
    r_u = brentq(lambda r: r * (1 + k1 * r ** 2 + k2 * r ** 4) - r_d, r_d, 2 * r_d)
    predicted = 400.0 * 0.001 * r_u ** 3 / (1 + 3 * k1 * r_u ** 2 + 5 * k2 * r_u ** 4)
    assert e1["max"] == pytest.approx(predicted, rel=0.02)
    assert e2["max"] == pytest.approx(2 * e1["max"], rel=0.02)
    assert 0 < e1["rms"] < e1["max"]


def test_point_errors_take_the_nearest_true_point():
    truth = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]])
    got = point_errors_px([[10.1, 0.0], [0.0, 9.8], [np.nan, np.nan]], truth)
    np.testing.assert_allclose(got, [0.1, 0.2], atol=1e-12)


@pytest.fixture(scope="module")
def study(tmp_path_factory, fast_variant):
    from edgetruth.evaluate.board.which_pattern.study import run_pattern_study

    tmp = tmp_path_factory.mktemp("which_pattern")
    spec = tmp / "which_pattern_ci.toml"
    spec.write_text(SPEC)
    out = tmp / "run"
    report = run_pattern_study(out, str(spec), progress=False, workers=1)
    return spec, out, report


@pytest.mark.slow  # the fixture renders 9 boards at 640 x 512: ~90 s on 2 cores
def test_every_pattern_is_calibrated_with_every_detector_on_the_same_poses(study):
    _, out, report = study
    res = json.loads((out / "results.json").read_text())
    rows = {(r["pattern"], r["detector"]): r for r in res["rows"]}
    assert set(rows) == {("chessboard", "subpix"), ("chessboard", "lines"), ("circle grid", "blobs"),
                         ("circle grid", "conic"), ("circle grid", "corrected"), ("ChArUco", "subpix"),
                         ("ChArUco", "lines")}
    for key, r in rows.items():
        assert not r.get("failed") and r["n_views"] == 3, key
        assert abs(r["fx_pct"]) < 1.0 and abs(r["fy_pct"]) < 1.0, key  # 3 views, 320 x 256: loose, but a calibration
    poses = {}
    for f in sorted((out / "renders").glob("*.json")):
        t = json.loads(f.read_text())
        if "pose" in t:
            poses.setdefault(t["design"]["slot"], []).append(t["pose"]["t_cam_from_board_m"])
    for slot, ts in poses.items():
        assert len(ts) == 3 and np.ptp(np.array(ts), axis=0).max() == 0.0, slot
    text = report.read_text()
    for part in ("## Which wins where (as measured)", "## Paired tests over the pose slots",
                 "## The circle-centre bias against tilt", "figures/focal_errors.png", "figures/circle_bias.png"):
        assert part in text
    assert (out / "figures" / "focal_errors.png").stat().st_size > 1000


@pytest.mark.slow
def test_corrected_circle_centres_lie_on_the_truth_and_conic_ones_carry_the_closed_form_bias(study):
    _, out, _ = study
    res = json.loads((out / "results.json").read_text())
    circ = {r["detector"]: r for r in res["rows"] if r["kind"] == "circles_grid"}
    # the perspective bias is removed by the correction: closer to the true centre images than the ellipse centres
    assert circ["corrected"]["point_rms_px"] < circ["conic"]["point_rms_px"]
    offsets = np.array([c["offset_px"] for c in circ["conic"]["circles"]])
    closed = np.array([c["closed_form_bias_px"] for c in circ["conic"]["circles"]])
    assert len(offsets) == 3 * 44
    # the ellipse centres sit about the closed form's distance from the truth (plus the edge points' own error)
    assert 0.5 < np.median(offsets) / np.median(closed) < 2.0


@pytest.mark.slow
def test_a_second_run_resumes_from_the_measured_cells(study):
    from edgetruth.evaluate.board.which_pattern.study import run_pattern_study

    spec, out, report = study
    before = {f.name: f.stat().st_mtime_ns for f in (out / "measured").glob("*.json")}
    first = json.loads((out / "results.json").read_text())["rows"]
    run_pattern_study(out, str(spec), progress=False, workers=1)
    assert {f.name: f.stat().st_mtime_ns for f in (out / "measured").glob("*.json")} == before
    again = json.loads((out / "results.json").read_text())["rows"]
    assert [r["fx_pct"] for r in again] == [r["fx_pct"] for r in first]
