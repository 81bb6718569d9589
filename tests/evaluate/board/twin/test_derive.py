"""A twin derived from chessboard photos (``twin.derive``): the scene a valid spec, and rendered, the twin's board
where the photos' is."""
from __future__ import annotations

import re

import cv2
import numpy as np
import pytest

from edgetruth.errors import InputError
from edgetruth.evaluate.board.detect import chessboard as cb
from edgetruth.evaluate.board.twin import derive as td
from edgetruth.evaluate.board.twin import measure as tm
from tests.evaluate.board.chessboard_images import write_views as views


def test_group_names():
    assert td.group_name("dir/left01.jpg") == "left01" and td.group_name("a b.c.png") == "a_b_c"
    assert td.group_name("_x.png") == "p_x" and td.safe_name("my twin") == "my_twin"


@pytest.mark.slow
def test_derived_twin_of_jpeg_views(tmp_path):
    """4 JPEG views (quality 75) of a known camera: the measured camera is it (fx 600 to 0.1 %), the output is the
    photos' JPEG quality, the tone linear (noise-free linear renders: power 1 within its interval), one group per
    photo with its white, and the spec loads."""
    from edgetruth.render.dataset.spec import load_spec

    paths, _ = views(tmp_path, ".jpg")
    m = tm.measure_chessboard(paths, (9, 6))
    assert abs(m["K"][0][0] - 600.0) < 0.6 and abs(m["K"][0][2] - 319.5) < 0.5
    assert m["tone"]["output_gamma"] == 1.0 and all(p["jpeg_quality"] == {"quality": 75, "exact": True}
                                                    for p in m["photos"])
    # what their JPEG adds to the ERF σ (blur_inverse.jpeg_blur_px; small at quality 75), taken off the twin's blur
    assert all(abs(p["jpeg_sigma_px"][k]) < 0.03 for p in m["photos"] for k in "xy")
    cam, scene = td.twin_texts(m, "t", "a test twin", "camera.toml", 0.03, "four test views")
    (tmp_path / "camera.toml").write_text(cam)
    (tmp_path / "twin.toml").write_text(scene)
    spec = load_spec(tmp_path / "twin.toml")
    assert spec.n_images == 4 and [g.name for g in spec.groups] == ["v0", "v1", "v2", "v3"]
    assert spec.sensor.output == "jpeg" and spec.sensor.jpeg_quality == 75 and spec.sensor.output_gamma == 1.0
    assert spec.camera.fx_px == pytest.approx(m["K"][0][0], abs=1e-4)
    assert max(len(ln) for ln in scene.splitlines() if ln.startswith("#")) <= 116


@pytest.mark.slow
def test_rendered_twin_puts_the_board_where_the_photos_have_it(fast_variant, tmp_path):
    """The twin of 4 PNG views (8-bit PNG out), rendered at 4 spp: every inner corner of its truth lies within
    0.05 px of the view's true corner (measured: mean 0.006, max 0.010 px): the calibration, the poses and the
    chessboard model's frame carry the board into the twin."""
    from edgetruth.render.dataset.driver import render_spec
    from edgetruth.render.dataset.reader import open_dataset
    from edgetruth.render.dataset.spec import load_spec

    paths, truth = views(tmp_path, ".png")
    m = tm.measure_chessboard(paths, (9, 6))
    cam, scene = td.twin_texts(m, "t", "a test twin", "camera.toml", 0.03, "four test views")
    assert 'output = "srgb8"' in scene and "jpeg_quality" not in scene
    assert all(p["jpeg_sigma_px"] is None for p in m["photos"])
    (tmp_path / "camera.toml").write_text(cam)
    (tmp_path / "twin.toml").write_text(scene.replace("\nspp = 256\n", "\nspp = 4\n", 1))
    spec = load_spec(tmp_path / "twin.toml")
    render_spec(spec, tmp_path / "r", progress=False, announce=lambda s: None)
    samples = sorted(open_dataset(tmp_path / "r").square_boards(), key=lambda s: s.index)
    err = []
    for s, t in zip(samples, truth):
        c = np.asarray(s.truth["squares"]["corners_distorted_px"], float).reshape(-1, 2)
        d = np.linalg.norm(t[:, None, :] - c[None, :, :], axis=2).min(axis=1)
        err.append(d)
    err = np.concatenate(err)
    print(f"twin corners vs the views': mean {err.mean():.4f}, max {err.max():.4f} px")
    assert err.max() < 0.05
    # the blur: the twin's edges read the views' ERF σ (blur_inverse; the pixel and the Airy core taken off in
    # quadrature instead left them 0.05 px wider)
    from edgetruth.evaluate.board.tone.photo_model import measure_photo

    model = cb.chessboard_model((9, 6), 1.0)
    gap = []
    for s, p in zip(samples, paths):
        png = s.dataset.path / s.dataset.manifest["images"][s.name]["files"]["png"]["path"]
        view, twin = (measure_photo(cv2.imread(str(f), cv2.IMREAD_GRAYSCALE).astype(float), model)["blur"]
                      for f in (p, png))
        gap += [twin[k]["sigma_px"] - view[k]["sigma_px"] for k in ("vertical", "horizontal")]
    print(f"twin ERF sigma - the views': {np.round(gap, 3)}")
    assert max(np.abs(gap)) < 0.03


@pytest.mark.slow
def test_a_tone_curve_is_measured_and_rendered(fast_variant, tmp_path):
    """Views stored through a power curve (s = 255 (v/255)^(1/1.6), dark 40 and white 210 linear: 80 and 226
    stored): the derivation measures the power (output_gamma within 0.1 of 1.6) and takes levels, contrast and noise
    back through it, so that the rendered twin (4 spp) has the views' dark and white levels within 4 DN (measured:
    the same medians; with the stored levels taken as linear, as before this test, 20 and 29 DN off)."""
    from edgetruth.evaluate.board.detect import chessboard as cb
    from edgetruth.evaluate.board.detect.levels import square_levels
    from edgetruth.render.dataset.driver import render_spec
    from edgetruth.render.dataset.reader import open_dataset
    from edgetruth.render.dataset.spec import load_spec

    paths, _ = views(tmp_path, ".png", noise_dn=1.0)
    for p in paths:  # the linear views through the curve
        lin = cv2.imread(str(p), cv2.IMREAD_GRAYSCALE).astype(float)
        cv2.imwrite(str(p), np.round(255.0 * (lin / 255.0) ** (1 / 1.6)).astype(np.uint8))
    m = tm.measure_chessboard(paths, (9, 6))
    assert abs(m["tone"]["output_gamma"] - 1.6) < 0.1
    cam, scene = td.twin_texts(m, "g", "a twin through a curve", "camera.toml", 0.03, "four curved views")
    (tmp_path / "camera.toml").write_text(cam)
    (tmp_path / "twin.toml").write_text(scene.replace("\nspp = 256\n", "\nspp = 4\n", 1))
    render_spec(load_spec(tmp_path / "twin.toml"), tmp_path / "r", progress=False, announce=lambda s: None)
    samples = sorted(open_dataset(tmp_path / "r").square_boards(), key=lambda s: s.index)
    model = cb.chessboard_model((9, 6), 1.0)
    diff = []
    for s, p in zip(samples, paths):
        png = s.dataset.path / s.dataset.manifest["images"][s.name]["files"]["png"]["path"]
        for path in (p, png):
            img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
            lev = square_levels(img, cb.find_squares(img, model).squares.corners)
            diff.append((lev.dark, lev.white))
    d = np.abs(np.diff(np.array(diff).reshape(-1, 2, 2), axis=1)).reshape(-1, 2)
    print(f"twin vs views: dark within {d[:, 0].max():.1f}, white within {d[:, 1].max():.1f} DN")
    assert d.max() <= 4.0


def raw_photos(tmp_path, fast_variant):
    """16-bit 'photos' of a known raw sensor (12-bit, K 0.5 DN/e-, 15 e- read noise, black 200 DN, PRNU 1 %) behind a
    lens of known shading (1 - 0.3 h² + 0.1 h⁴): the twin of the 4 PNG views with that camera, at exposures 0.7,
    0.42, 0.98 and 0.56 of the views' (the third clips at 4095), rendered at 256 spp without Monte-Carlo noise
    (``board_mode = "frame"``: path-traced at 64 spp, the noise in the darks moved the black level found by
    ~40 DN).  -> their paths."""
    import re

    from edgetruth.render.dataset.driver import render_spec
    from edgetruth.render.dataset.reader import open_dataset
    from edgetruth.render.dataset.spec import load_spec

    paths, _ = views(tmp_path, ".png")
    cam, scene = td.twin_texts(tm.measure_chessboard(paths, (9, 6)), "truth", "a raw camera", "camera.toml", 0.03,
                               "four test views")
    sensor = re.search(r"\[sensor\]\n.*?\n\n", scene, re.S).group(0)
    scene = scene.replace(sensor, '[sensor]\noutput = "raw"\nbits = 12\nk0_dn_per_e = 0.5\ndark_offset_dn = 200\n'
                                  'dark_noise_e = 15\nfull_well_e = 100000\nprnu_pct = 1.0\n\n')
    exposure = iter((0.7, 0.42, 0.98, 0.56))
    scene = re.sub(r"irradiance_w_m2 = ([0-9.]+)", lambda m: f"irradiance_w_m2 = {float(m[1]) * next(exposure):.4f}",
                   scene).replace("\nspp = 256\n", "\nspp = 256\n", 1)
    cam = re.sub(r"\nshading_a2 = \S+\nshading_a4 = \S+\n", "\nshading_a2 = -0.3\nshading_a4 = 0.1\n", cam)
    assert "shading_a2 = -0.3" in cam
    (tmp_path / "camera.toml").write_text(cam)
    (tmp_path / "truth.toml").write_text(scene)
    render_spec(load_spec(tmp_path / "truth.toml"), tmp_path / "raw", progress=False, announce=lambda s: None)
    return rendered_pngs(tmp_path / "raw")


def rendered_pngs(root):
    from edgetruth.render.dataset.reader import open_dataset

    samples = sorted(open_dataset(root).square_boards(), key=lambda s: s.index)
    return [s.dataset.path / s.dataset.manifest["images"][s.name]["files"]["png"]["path"] for s in samples]


@pytest.mark.slow  # two renders of 4 frames at 64 spp: ~20 s on 2 cores
def test_a_twin_of_raw_photos(fast_variant, tmp_path):
    """16-bit photos of a known raw sensor behind a shaded lens (``raw_photos``): the twin renders raw at 12 bits with
    the sensor's gain, black level and PRNU from the photon transfer with the PRNU term (K to 5 %: measured 0.5102
    against 0.5; the black level from the assumed 15 e- to 40 DN: measured 213.2 against 200, 179.8 from path-traced
    photos, whose darks' Monte-Carlo noise lowered it; PRNU to 0.3 % points: measured 0.972 against 1 %), in
    half-square patches about their planes,
    none within 4 SD of the clip (before the PRNU term and the PRNU in these photos: K 0.4996; 5x5 patches at the
    squares' centres, as the 8-bit levels, 0.4497; half squares with the patches near the clip, 0.4715); given the
    black level, the read noise comes back (to 2 e-); the lens shading to 0.01 over the light squares' field heights
    (measured 0.002).  Rendered at 64 spp, the twin reads the photos' dark and white levels to 1.5 % (measured
    0.95 %), their noise SDs in those patches to 8 % (measured -2.9 to +0.3 %) and their ERF σ to 0.02 px (measured
    0.005), the clipped photo's white at 4095 too.  The photos' tone reads linear (power to 0.02: measured 0.997)."""
    from edgetruth.render.dataset.driver import render_spec
    from edgetruth.render.dataset.spec import load_spec

    photos = raw_photos(tmp_path, fast_variant)
    m = tm.measure_chessboard(photos, (9, 6))
    assert m["full_scale"] == 65535.0 and m["max_value"] == 4095 and m["value_step"] == 1
    assert [p["white_saturated"] for p in m["photos"]] == [False, False, True, False]
    print(f"raw photos' tone power {m['tone']['power']:.4f} (95 % {m['tone']['ci'][0]:.4f}-{m['tone']['ci'][1]:.4f})")
    assert abs(m["tone"]["power"] - 1.0) < 0.02 and m["tone"]["output_gamma"] == 1.0  # rendered raw: linear
    cam, scene = td.twin_texts(m, "rawtwin", "a raw twin", "camera.toml", 0.03, "four raw views")
    (tmp_path / "t").mkdir()
    (tmp_path / "t" / "camera.toml").write_text(cam)
    (tmp_path / "t" / "twin.toml").write_text(scene.replace("\nspp = 256\n", "\nspp = 64\n", 1))
    spec = load_spec(tmp_path / "t" / "twin.toml")
    s, c = spec.sensor, spec.camera
    print(f"raw twin: K {s.k0_dn_per_e:.4f} DN/e-, black {s.dark_offset_dn:.1f} DN, read {s.dark_noise_e} e-, PRNU "
          f"{s.prnu_pct:.3f} %; shading {c.shading_a2:.4f}, {c.shading_a4:.4f}")
    assert abs(s.prnu_pct - 1.0) < 0.3
    # the lens shading, over the field heights the light squares span (0 to ~0.4)
    from edgetruth.evaluate.board.twin.shading import lens_shading

    hs = np.linspace(0.0, 0.4, 9)
    assert np.abs(lens_shading(hs, c.shading_a2, c.shading_a4) - lens_shading(hs, -0.3, 0.1)).max() < 0.01
    assert s.output == "raw" and s.bits == 12 and s.dark_noise_e == td.DARK_NOISE_E
    assert abs(s.k0_dn_per_e / 0.5 - 1) < 0.05 and abs(s.dark_offset_dn - 200.0) < 40.0
    _, given = td.twin_texts(m, "g", "a raw twin", "camera.toml", 0.03, "four raw views",
                             td.TwinAssumptions(black_dn=200.0))
    read = float(re.search(r"\ndark_noise_e = (\S+)\n", given)[1])
    assert "dark_offset_dn = 200.00" in given and abs(read - 15.0) < 2.0
    render_spec(spec, tmp_path / "t" / "r", progress=False, announce=lambda s: None)
    twin = tm.measure_chessboard(rendered_pngs(tmp_path / "t" / "r"), (9, 6))
    level, sd, sigma = [], [], []
    for p, q in zip(m["photos"], twin["photos"]):
        level += [q[k] / p[k] - 1 for k in ("dark", "white")]
        sd += [q["flat_noise"][k] / p["flat_noise"][k] - 1 for k in ("dark_sd", "white_sd")
               if not (k == "white_sd" and p["white_saturated"])]
        sigma += [q[k] - p[k] for k in ("sigma_x_px", "sigma_y_px")]
    print(f"twin vs photos: levels {np.round(level, 4)}, SDs {np.round(sd, 3)}, sigma {np.round(sigma, 4)} px")
    assert max(np.abs(level)) < 0.015 and max(np.abs(sd)) < 0.08 and max(np.abs(sigma)) < 0.02
    assert twin["photos"][2]["white"] == 4095.0


def test_raw_and_8_bit_options_are_refused_on_the_other(tmp_path):
    """--black-dn on 8-bit photos and --white-noise-dn on 16-bit ones: one InputError naming the option."""
    paths, _ = views(tmp_path, ".png")
    m = tm.measure_chessboard(paths, (9, 6))
    with pytest.raises(InputError, match="--black-dn: for 16-bit"):
        td.twin_texts(m, "t", "x", "camera.toml", 0.03, "x", td.TwinAssumptions(black_dn=10.0))
    with pytest.raises(InputError, match="--white-noise-dn: for 8-bit"):
        td.twin_texts({**m, "full_scale": 65535.0, "max_value": 4095}, "t", "x", "camera.toml", 0.03, "x",
                      td.TwinAssumptions(white_noise_dn=3.0))


@pytest.mark.slow
def test_sharpened_views_give_a_sharpened_twin(fast_variant, tmp_path):
    """4 PNG views sharpened as the renderer sharpens (unsharp mask along both axes, amount 1.5, σ 1 px, on the stored
    values): their sides overshoot by 9 % of the step, so the twin renders a mask along both axes (its amount
    within 0.5 of 1.5: measured 1.54-1.75) with the blur fitted with it; rendered at 4 spp, its sides read the views'
    ERF σ within 0.08 px (measured 0.049) and their overshoot within 5 points (measured 3.4).  The fit models each
    orientation's sides as axis-aligned (a 1-D mask on the pixel grid along the normal), and these views tilt their
    sides by up to 0.4 rad: sharpened along x alone, their horizontal sides, which the x mask reaches when tilted,
    read 4.1 % in the twin against 0.3 % in the views (docs/board.md, *Sharpening*)."""
    from edgetruth.evaluate.board.tone.photo_model import blur, board_lines
    from edgetruth.render.dataset.driver import render_spec
    from edgetruth.render.dataset.spec import load_spec
    from edgetruth.render.sensor.pipeline import sharpen

    paths, _ = views(tmp_path, ".png", noise_dn=1.0)
    for p in paths:
        img = cv2.imread(str(p), cv2.IMREAD_GRAYSCALE).astype(float) / 255.0
        cv2.imwrite(str(p), np.clip(np.round(255.0 * sharpen(img, 1.5, 1.0, "xy")), 0, 255).astype(np.uint8))
    m = tm.measure_chessboard(paths, (9, 6))
    assert all(p["overshoot_pct"][axis] > 5.0 for p in m["photos"] for axis in "xy")
    cam, scene = td.twin_texts(m, "s", "a sharpened twin", "camera.toml", 0.03, "four sharpened views")
    amounts = [float(v) for v in re.findall(r"sharpen_amount = ([0-9.]+)", scene)]
    print(f"views' overshoot x {[round(p['overshoot_pct']['x'], 1) for p in m['photos']]}, fitted amounts {amounts}")
    assert 'sharpen_axis = "xy"' in scene and len(amounts) == 4 and all(abs(a - 1.5) < 0.5 for a in amounts)
    (tmp_path / "camera.toml").write_text(cam)
    (tmp_path / "twin.toml").write_text(scene.replace("\nspp = 256\n", "\nspp = 4\n", 1))
    render_spec(load_spec(tmp_path / "twin.toml"), tmp_path / "r", progress=False, announce=lambda s: None)
    model = cb.chessboard_model((9, 6), 1.0)
    worst_sigma, worst_over = 0.0, 0.0
    for path, p in zip(rendered_pngs(tmp_path / "r"), m["photos"]):
        img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE).astype(float)
        b = blur(img, board_lines(img, model))
        for axis, name in (("x", "vertical"), ("y", "horizontal")):
            worst_sigma = max(worst_sigma, abs(b[name]["sigma_px"] - p[f"sigma_{axis}_px"]))
            worst_over = max(worst_over, abs(max(b[name]["overshoot_pct"], b[name]["undershoot_pct"])
                                             - p["overshoot_pct"][axis]))
    print(f"twin vs views: sigma within {worst_sigma:.3f} px, overshoot within {worst_over:.1f} points; views' y "
          f"overshoot {[round(p['overshoot_pct']['y'], 1) for p in m['photos']]}")
    assert worst_sigma < 0.08 and worst_over < 5.0
