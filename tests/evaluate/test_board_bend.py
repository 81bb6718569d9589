"""Does the board bend (``board_bend``)?  The projection is OpenCV's; a bend put into analytic views is found at its
depth, a flat board is not called bent, and OpenCV's photos bend (``edgetruth calibrate``)."""
from __future__ import annotations

import json
import re
from pathlib import Path

import cv2
import numpy as np
import pytest

from edgetruth.evaluate.board_bend import bend_check, project, reading
from edgetruth.evaluate.calibration import DIST_MODELS, free_dist
from edgetruth.render.dataset.spec import load_spec
from tests.evaluate.bent_views import DIST_TRUE, K_TRUE, view_poses, curled_views

ROOT = Path(__file__).resolve().parents[2]

def test_projection_is_opencvs():
    """``project`` reproduces cv2.projectPoints (5-term Brown-Conrady) to 1e-9 px on points off the board plane."""
    rng = np.random.default_rng(0)
    pts = np.c_[rng.uniform(-0.1, 0.1, (50, 2)), rng.uniform(-0.002, 0.002, 50)]
    (r, t), = view_poses(1, rng)
    ref, _ = cv2.projectPoints(pts, r, t, K_TRUE, DIST_TRUE)
    mine = project(pts, np.zeros(50, int), np.r_[r, t][None], (530.0, 531.0, 330.0, 245.0), DIST_TRUE)
    assert np.abs(mine - ref[:, 0]).max() < 1e-9


def test_a_curled_board_is_found_at_its_depth():
    """Each view curled about one axis by 0.2-0.6 mm (ŷ² at the edge) under 0.01 px of noise per axis: the
    quadratic bend takes most of the flat fit's residual energy (measured 0.87-0.92 over seeds), p is tiny, each
    view's fitted depth is its true depth within 0.06 mm (measured <= 0.04), every height is within 3.5 of its
    standard errors of the truth, and the bent fit's focal length is closer to the truth than the flat one's
    (measured 0.005 px against 0.92 px off)."""
    rng = np.random.default_rng(7)
    curl = np.c_[rng.uniform(-0.1, 0.1, 13), rng.uniform(-0.1, 0.1, 13), rng.uniform(0.2, 0.6, 13)]
    xy, img, K, dist, rv, tv, terms, s = curled_views(curl, 0.01)
    b = bend_check(xy, img, K, dist, rv, tv)
    q = b["quadratic"]
    true_depth = [np.ptp(terms @ c) for c in curl]  # mm: terms are dimensionless
    assert q["bend_share"] > 0.8 and q["p_value"] < 1e-12 and q["bend_excess"] > 0.8
    assert np.abs(np.array(q["depth_mm"]) - true_depth).max() < 0.06
    assert np.abs((np.array(q["coefficients_mm"]) - curl) / q["coefficients_se_mm"]).max() < 3.5
    assert q["rms_bent_px"] == pytest.approx(0.01 * np.sqrt(2), rel=0.1)  # the 2-D RMS of the noise
    assert q["rms_flat_px"] == pytest.approx(
        np.sqrt(np.mean(np.concatenate([np.sum((i - cv2.projectPoints(np.c_[o, np.zeros(len(o))], r, t, K, dist)[0]
                                                [:, 0]) ** 2, 1) for o, i, r, t in zip(xy, img, rv, tv)]))), rel=1e-6)
    assert abs(q["intrinsics_bent"]["fx_px"] - 530.0) < abs(K[0, 0] - 530.0)
    assert "the board bends" in reading(b)


def test_a_warp_common_to_every_view_is_found_to_micrometres():
    """Every view curled the same way (a rigid, warped board: x̂² 0.1, x̂ŷ -0.05, ŷ² 0.4 mm) under 0.05 px of noise:
    the common fit reads the shape within 3.5 of its standard errors, which are under 0.35 of the per-view fits'
    (measured 0.27-0.30, about 1/√13; 3-7 µm on the rendered calibration boards), and takes about as much of the
    residual as 13 per-view fits with 13 times its terms (measured 0.24 against 0.27); where each view curls its own
    way, it takes a fraction of what they do (measured 0.004 against 0.21)."""
    same = np.tile([0.1, -0.05, 0.4], (13, 1))
    xy, img, K, dist, rv, tv, _, _ = curled_views(same, 0.05)
    b = bend_check(xy, img, K, dist, rv, tv)
    c, q = b["common"], b["quadratic"]
    assert c["terms"] == 3 and c["extra_parameters"] == 3 and q["extra_parameters"] == 39
    assert np.abs((np.array(c["coefficients_mm"]) - same[0]) / c["coefficients_se_mm"]).max() < 3.5
    assert np.all(np.array(c["coefficients_se_mm"]) < 0.35 * np.median(q["coefficients_se_mm"], axis=0))
    assert c["bend_share"] > q["bend_share"] - 0.05 and c["p_value"] < 1e-12 and c["depth_mm"] > 0.2
    rng = np.random.default_rng(5)
    own = np.c_[np.zeros(13), np.zeros(13), rng.uniform(-0.5, 0.5, 13)]
    b2 = bend_check(*curled_views(own, 0.05)[:6])
    assert b2["common"]["bend_share"] < 0.2 * b2["quadratic"]["bend_share"]


def test_a_flat_board_is_not_called_bent():
    """A flat board under 0.1 px of noise per axis: the bend takes its chance share (within 0.03), p is not small
    (seeded), every fitted height is within 3.5 standard errors of 0 and at most 15 % beyond 2 (measured 3-5 %),
    and the line reads no bend."""
    xy, img, K, dist, rv, tv, _, _ = curled_views(np.zeros((13, 3)), 0.1)
    b = bend_check(xy, img, K, dist, rv, tv)
    for m in b.values():
        assert abs(m["bend_share"] - m["bend_share_chance"]) < 0.03 and m["p_value"] > 0.01
    z = np.abs(np.array(b["quadratic"]["coefficients_mm"]) / b["quadratic"]["coefficients_se_mm"])
    assert z.max() < 3.5 and np.mean(z > 2) <= 0.15
    assert "no bend found" in reading(b)


def test_fixed_distortion_terms_stay_fixed():
    """With the k1, k2 model, p1, p2 and k3 stay at 0 in the bent fit."""
    assert free_dist(DIST_MODELS["k1k2"][0]) == (True, True, False, False, False)
    assert free_dist(DIST_MODELS["k1k2p1p2"][0]) == (True, True, True, True, False)
    assert free_dist(0) == (True,) * 5
    xy, img, K, dist, rv, tv, _, _ = curled_views(np.zeros((5, 3)), 0.05)
    b = bend_check(xy, img, K, np.r_[dist[:2], 0, 0, 0], rv, tv, free_dist(DIST_MODELS["k1k2"][0]))
    assert b["quadratic"]["intrinsics_bent"]["dist_coeffs_opencv"][2:] == [0.0, 0.0, 0.0]


def test_a_lens_term_left_out_can_look_like_a_bend():
    """A flat board seen through a lens with tangential distortion (p1 = 0.002) and calibrated with k1, k2 only:
    a bend per view stands in for the missing term (the share far above chance), and the line says a lens term
    may be the cause; calibrated with the full model, the same views show no bend."""
    xy, img, _, _, _, _, _, _ = curled_views(np.zeros((13, 3)), 0.01)
    flags = DIST_MODELS["k1k2"][0]
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 200, 1e-12)
    obj = [np.c_[x, np.zeros(len(x))].astype(np.float32) for x in xy]
    _, K, dist, rv, tv = cv2.calibrateCamera(obj, img, (640, 480), None, None, flags=flags, criteria=crit)
    partial = bend_check(xy, img, K, dist.ravel(), rv, tv, free_dist(flags))
    assert partial["quadratic"]["bend_excess"] > 0.1 and partial["quadratic"]["p_value"] < 1e-6
    assert "lens has terms" in reading(partial, full_lens=False)
    _, K, dist, rv, tv = cv2.calibrateCamera(obj, img, (640, 480), None, None, criteria=crit)
    assert "no bend found" in reading(bend_check(xy, img, K, dist.ravel(), rv, tv))


def test_too_few_corners():
    """Views of fewer than MIN_CORNERS corners sit out (they would fit their own bend exactly); none left: {}."""
    xy, img, K, dist, rv, tv, _, _ = curled_views(np.zeros((4, 3)), 0.05)
    few = bend_check([x[:6] for x in xy], [i[:6] for i in img], K, dist, rv, tv)
    assert few == {} and "too few corners" in reading(few)
    some = bend_check([xy[0][:6], *xy[1:]], [img[0][:6], *img[1:]], K, dist, rv, tv)
    assert some["quadratic"]["views"] == 3 and some["quadratic"]["points"] == 3 * 54
    assert len(some["cubic"]["depth_mm"]) == 3


def test_zhangs_board_barely_bends():
    """A finding, measured (docs/board.md): Zhang's own corners of his five photos (k1 k2): a quadratic bend takes
    2 % of the residual energy against 1 % by chance -- significant over 1,280 corners, but mostly noise
    (excess 0.01), unlike OpenCV's photos."""
    from edgetruth.evaluate.board.calibrate.zhang import _views as board_views
    from edgetruth.evaluate.board.calibrate.zhang import calibrate
    from edgetruth.evaluate.board.inputs import resolve_inputs

    inp = resolve_inputs(["zhang1998"])
    cal = calibrate(inp.model.corners, inp.reference_corners, (640, 480))
    views = board_views(inp.model.corners, inp.reference_corners)
    b = bend_check([o[:, :2] for _, o, _ in views], [i for _, _, i in views], cal.K, cal.dist, cal.rvecs,
                   cal.tvecs, free_dist(DIST_MODELS["k1k2"][0]), unit_m=0.0254)
    q = b["quadratic"]
    assert q["bend_excess"] < 0.05 and q["rms_flat_px"] - q["rms_bent_px"] < 0.01
    assert "mostly noise" in reading(b) or "no bend found" in reading(b)


@pytest.mark.slow
def test_opencv_photos_bend(tmp_path, capsys):
    """A finding, measured (docs/board.md): OpenCV's photos (54 line corners, 5-term model) bend: a quadratic bend
    per view takes 30 % of the residual energy (3 % by chance), RMS 0.155 -> 0.130 px, 0.3-1.0 mm deep, curled the
    same way in all 13 photos (ŷ² > 0: the long rows nearer the camera than the outer ones)."""
    from edgetruth.cli import main

    out = tmp_path / "cal.json"
    assert main(["calibrate", "opencv_left", "--pattern", "9x6", "--square-m", "0.025", "--corners", "lines",
                 "-o", str(out), "--no-progress"]) == 0
    b = json.loads(out.read_text())["board_bend"]
    q = b["quadratic"]
    assert 0.25 < q["bend_share"] < 0.4 and q["p_value"] < 1e-20 and q["rms_bent_px"] < 0.135
    assert all(0.2 < d < 1.2 for d in q["depth_mm"]) and all(h[2] > 0.1 for h in q["coefficients_mm"])
    assert b["cubic"]["bend_share"] > q["bend_share"] and "the board bends" in capsys.readouterr().out


@pytest.mark.slow
def test_a_rendered_curl_reads_back(fast_variant, tmp_path, capsys):
    """The closed loop: OpenCV's twin rendered with each photo's own curl (``scenes/opencv_left_twin_bent.toml``,
    16 spp) and calibrated from its PNGs as the photos are (line corners, 5-term model): the check finds the bend
    and every view's coefficients at those the spec renders (rescaled to the check's s), within 0.1 mm (the
    photos' standard errors are 0.06-0.11 mm); the bent fit leaves the flat twin's RMS (0.020 px at 256 spp).
    Measured at 256 spp (docs/board.md, "A bent twin"): flat RMS 0.086 px, 94 % to the bend, bent 0.020 px;
    read-back error 0.008-0.018 mm RMS per term, at most 0.043 mm."""
    from edgetruth.cli import main
    from edgetruth.render.dataset.driver import render_spec
    from edgetruth.render.scene.bend import BoardBend

    text = (ROOT / "scenes" / "opencv_left_twin_bent.toml").read_text()
    p = tmp_path / "bent.toml"
    p.write_text(re.sub(r"(?m)^spp = \d+", "spp = 16", text))
    spec = load_spec(p)
    render_spec(spec, tmp_path / "r", progress=False, announce=lambda s: None)
    out = tmp_path / "cal.json"
    assert main(["calibrate", str(tmp_path / "r" / "*.png"), "--pattern", "9x6", "--square-m", "0.025",
                 "--corners", "lines", "-o", str(out), "--no-progress"]) == 0
    q = json.loads(out.read_text())["board_bend"]["quadratic"]
    s_render = BoardBend.of((0, 0, 0), spec.squares.black_quads_local(0.0)).scale_m * 1e3
    given = np.array([g.board_bend_mm for g in spec.groups]) * (np.array(q["scale_mm"])[:, None] / s_render) ** 2
    err = np.array(q["coefficients_mm"]) - given
    assert "the board bends" in capsys.readouterr().out
    with capsys.disabled():
        print(f"read-back error: RMS {np.sqrt((err ** 2).mean(0)).round(3)} mm, max {np.abs(err).max():.3f}; "
              f"RMS {q['rms_flat_px']:.3f} -> {q['rms_bent_px']:.3f} px, share {q['bend_share']:.2f}")
    assert q["views"] == 13 and np.abs(err).max() < 0.1
    assert q["rms_bent_px"] < 0.035 < 0.07 < q["rms_flat_px"] and q["bend_share"] > 0.8
