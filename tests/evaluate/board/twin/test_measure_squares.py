"""A twin of photos of a board of separate squares (``twin.measure_squares``, ``derive.twin_texts`` with a model):
on Zhang's five photos, his camera and poses come back; rendered, the twin's board is where the photos' is and its
levels and noise are theirs; and noise through a tone curve is split as it was made (``derive.curve_noise``)."""
from __future__ import annotations

import math
import shutil

import cv2
import numpy as np
import pytest

from edgetruth.errors import InputError
from edgetruth.evaluate.board.model import read_model
from edgetruth.evaluate.board.reference import read_zhang_calibration, shipped_set
from edgetruth.evaluate.board.twin import derive as td
from edgetruth.evaluate.board.twin import measure_squares as ms


@pytest.fixture(scope="module")
def zhang():
    """(photos, model, Zhang's published calibration, the measurements)."""
    s = shipped_set("zhang1998")
    model = read_model(s["model"])
    return s["photos"], model, read_zhang_calibration(s["calibration"]), ms.measure_squares(s["photos"], model)


def test_gap_points_lie_on_the_white_between_the_squares(zhang):
    """Zhang's 8 x 8 squares (side 0.5, pitch 0.889 in): 7 x 8 gaps between row neighbours, 8 x 7 between column
    neighbours and 7 x 7 where four squares' corners face each other: 161 points, each at least 0.15 of a side
    clear of every square (the gap is 0.389 in: measured 0.19 in, 0.39 of a side, at the nearest)."""
    _, model, _, _ = zhang
    g = ms.gap_points(model.corners)
    assert g.shape == (7 * 8 + 8 * 7 + 7 * 7, 2)
    lo, hi = model.corners.min(axis=1), model.corners.max(axis=1)  # Zhang's squares are axis-aligned
    dx = np.maximum(np.maximum(lo[None, :, 0] - g[:, None, 0], g[:, None, 0] - hi[None, :, 0]), 0.0)
    dy = np.maximum(np.maximum(lo[None, :, 1] - g[:, None, 1], g[:, None, 1] - hi[None, :, 1]), 0.0)
    clear = np.hypot(dx, dy).min(axis=1)
    assert clear.min() >= ms.GAP_CLEARANCE * 0.5 and len(np.unique(np.round(g, 6), axis=0)) == len(g)


def test_zhangs_camera_and_poses_come_back(zhang):
    """On his 5 photos, Zhang's calibration on the side lines' corners gives his published camera (fx, fy to 0.2 %:
    measured 831.92 against 832.50; the principal point to 0.5 px: measured 0.26 and 0.35 px off; k1, k2 to 0.01)
    and each photo's pose (t to 0.03 in: measured at most 0.011 in; R to 0.1 degrees); CalibIm1 and CalibIm3 are
    the photos whose whites are clipped (45 % and 96 % of the ring's pixels at their top)."""
    _, _, pub, m = zhang
    K = np.asarray(m["K"])
    assert K[0, 0] == pytest.approx(pub["fx"], rel=2e-3) and K[1, 1] == pytest.approx(pub["fy"], rel=2e-3)
    assert abs(K[0, 2] - pub["cx"]) < 0.5 and abs(K[1, 2] - pub["cy"]) < 0.5
    assert abs(m["dist"][0] - pub["k1"]) < 0.01 and abs(m["dist"][1] - pub["k2"]) < 0.01
    assert [p["photo"] for p in m["photos"]] == [f"CalibIm{i}.png" for i in range(1, 6)] and not m["left_out"]
    for p, (R, t) in zip(m["photos"], pub["poses"]):
        assert np.abs(np.asarray(p["t_model"]) - t).max() < 0.03
        angle = math.degrees(np.linalg.norm(cv2.Rodrigues(np.asarray(p["R"]) @ R.T)[0]))
        assert angle < 0.1, (p["photo"], angle)
    assert [p["white_saturated"] for p in m["photos"]] == [True, False, True, False, False]
    assert m["tone"]["output_gamma"] == 2.2 and m["tone"]["power"] is None and "no junctions" in m["tone"]["note"]
    assert m["full_scale"] == 255.0 and len(m["light_points"]) == 161


def test_curve_noise_splits_noise_before_and_after_a_curve():
    """Dark and white SDs made by shot noise (q per electron, 15 e- of read noise) before a power curve of 2.2 and a
    constant SD after it, at three exposures: the fit returns q and the SD after the curve (to 1e-6 relative); all
    before or all after, the other comes back as none."""
    g, full = 2.2, 255.0 * 1.6

    def lin(s):
        return full * (s / full) ** g

    def dlin(s):
        return g * (s / full) ** (g - 1.0)

    for q, o in ((0.05, 0.0), (0.05, 3.0), (0.0, 6.0), (0.2, 1.0)):
        def sd(v):
            return math.sqrt((q * lin(v) + (15.0 * q) ** 2) / dlin(v) ** 2 + o ** 2 + 1.0 / 12.0)

        photos = [{"dark": d, "white": w, "dark_sd": sd(d), "white_sd": sd(w)} for d, w in ((40, 210), (35, 190),
                                                                                            (45, 230))]
        f = td.curve_noise(photos, lin, dlin, 15.0, lin(220.0), q_min=1e-9)
        assert f["q"] == pytest.approx(max(q, 1e-9), rel=1e-6, abs=1e-9) and f["output_dn"] == pytest.approx(
            o, abs=1e-5), (q, o, f)
        assert f["rms_rel"] < 1e-6 and f["levels"] == 6


def test_a_model_twin_needs_its_model_file_and_no_bend(zhang):
    _, _, _, m = zhang
    with pytest.raises(InputError, match="model"):
        td.twin_texts(m, "z", "x", "camera.toml", 0.0254, "x")
    with pytest.raises(InputError, match="--bend"):
        td.twin_texts(m, "z", "x", "camera.toml", 0.0254, "x", bend=True, model_ref="model.txt")


@pytest.mark.slow
def test_rendered_twin_of_zhangs_photos(zhang, fast_variant, tmp_path):
    """The twin ``edgetruth twin --model`` writes of Zhang's photos, rendered at 64 spp (~10 s): each image's exact
    square corners are the model carried by its photo's measured pose and camera (to 1e-3 px, the squares at the
    renderer's 10 um standoff: the model frame, its unit and the pose reach the renderer as measured).  The photo
    model on the renders reads, on the unsaturated photos: the dark and white levels to 3 DN (measured within 1.2; 2.2
    with one print contrast for all, before each photo's dark offset), and on every photo the dark level to 3 DN
    (measured 1.2; the clipped photos' darks were 7.5 and 12.4 DN off without the offsets), the white SDs to 10 %
    (measured 3.3 %: the noise split, mostly after the curve and the mask), the ERF σ to 0.08 px (measured 0.034; the
    y axis's blur inverse at the median contrast) and the vertical sides' overshoot, the sharpening fitted with the
    blur, to 3 points (measured 1.5; none rendered, 10-14.5 points off); on the clipped photos the share of the ring at
    its top to 15 points (measured 6.0: 51 against 45 %, 96 against 96 %); on every photo the darks' SD to 10 %
    (measured 2.6 %): the twin renders its board without Monte-Carlo noise (``board_mode = "frame"``), so the darks'
    noise is the split's alone (path-traced, the render's noise there, amplified by the mask, added up to 74 % at 64
    spp)."""
    from edgetruth.evaluate.board.tone.photo_model import blur, board_lines, noise
    from edgetruth.render.dataset.driver import render_spec
    from edgetruth.render.dataset.spec import load_spec
    from tests.evaluate.board.twin.test_derive import rendered_pngs

    photos, model, _, m = zhang
    cam, scene = td.twin_texts(m, "z", "Zhang's twin", "camera.toml", 0.0254, "Zhang's photos", model_ref="model.txt")
    assert "output_noise_dn = " in scene and 'model = "model.txt"' in scene and "pose_unit_m = 0.0254" in scene
    assert 'sharpen_axis = "x"' in scene and scene.count("sharpen_amount = ") == 5 and 'board_mode = "frame"' in scene
    (tmp_path / "camera.toml").write_text(cam)
    (tmp_path / "twin.toml").write_text(scene.replace("\nspp = 256\n", "\nspp = 64\n", 1))
    shutil.copyfile(shipped_set("zhang1998")["model"], tmp_path / "model.txt")
    spec = load_spec(tmp_path / "twin.toml")
    assert spec.n_images == 5 and [g.name for g in spec.groups] == [f"CalibIm{i}" for i in range(1, 6)]
    render_spec(spec, tmp_path / "r", progress=False, announce=lambda s: None)
    from edgetruth.render.dataset.reader import open_dataset

    samples = sorted(open_dataset(tmp_path / "r").square_boards(), key=lambda s: s.index)
    K, dist = np.asarray(m["K"]), np.asarray(m["dist"])
    # the squares lie the renderer's standoff in front of the plate (z < 0 in the board frame, z into the board)
    standoff = samples[0].truth["squares"]["standoff_m"] / 0.0254
    obj = np.c_[model.corners.reshape(-1, 2), np.full(4 * len(model), -standoff)]
    for s, p in zip(samples, m["photos"]):
        uv, _ = cv2.projectPoints(obj, cv2.Rodrigues(np.asarray(p["R"]))[0], np.asarray(p["t_model"]), K, dist)
        truth = np.asarray(s.truth["squares"]["corners_distorted_px"], float).reshape(-1, 2)
        assert np.abs(truth - uv.reshape(-1, 2)).max() < 1e-3, p["photo"]
    worst = {"level": 0.0, "sd": 0.0, "clipped": 0.0, "sigma": 0.0, "over": 0.0, "dark_sd": 0.0, "dark": 0.0}
    for path, p in zip(rendered_pngs(tmp_path / "r"), m["photos"]):
        img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE).astype(float)
        lines = board_lines(img, model)
        nz = noise(img, lines)
        if not p["white_saturated"]:  # the edges' shape: the ERF σ and the vertical sides' overshoot
            b = blur(img, lines)
            worst["sigma"] = max(worst["sigma"], abs(b["vertical"]["sigma_px"] - p["sigma_x_px"]),
                                 abs(b["horizontal"]["sigma_px"] - p["sigma_y_px"]))
            over = max(b["vertical"]["overshoot_pct"], b["vertical"]["undershoot_pct"])
            worst["over"] = max(worst["over"], abs(over - p["overshoot_pct"]["x"]))
        worst["dark_sd"] = max(worst["dark_sd"], abs(nz["black"]["sd"] / p["dark_sd"] - 1.0))
        worst["dark"] = max(worst["dark"], abs(nz["black"]["mean"] - p["dark"]))
        if p["white_saturated"]:  # clipped where the photo is, about as much
            worst["clipped"] = max(worst["clipped"], abs(nz["white"]["at_max_fraction"] - p["white_at_max"]))
            continue
        worst["sd"] = max(worst["sd"], abs(nz["white"]["sd"] / p["white_sd"] - 1.0))
        for key, region in (("dark", "black"), ("white", "white")):
            worst["level"] = max(worst["level"], abs(nz[region]["mean"] - p[key]))
    print(f"twin vs photos: unsaturated levels within {worst['level']:.2f} DN, every dark within {worst['dark']:.2f} "
          f"DN, white SDs within "
          f"{100 * worst['sd']:.1f} %, dark SDs within {100 * worst['dark_sd']:.1f} %, "
          f"clipped shares within {100 * worst['clipped']:.1f} points, ERF sigma within {worst['sigma']:.3f} px, "
          f"overshoot along x within {worst['over']:.1f} points")
    assert worst["level"] < 3.0 and worst["dark"] < 3.0 and worst["sd"] < 0.1 and worst["clipped"] < 0.15
    assert worst["sigma"] < 0.08 and worst["over"] < 3.0 and worst["dark_sd"] < 0.1
