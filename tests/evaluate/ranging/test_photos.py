"""Ranging on real photos (``edgetruth evaluate --photos``) on "photos" of known geometry.

The photos are analytic: a known pinhole camera (fx = fy = 800 px, principal point at the image
centre, no distortion; the test writes its calibration.json) sees fronto-parallel targets at known
depths Z, so each target's image is exact: a square of side S has side l = fx·S/Z px (whatever its
roll and lateral offset), a circle of diameter D a circle of diameter fx·D/Z.  Edges are a Gaussian
blur (sigma 0.8 px) of the geometric outline, integrated over each pixel (separable closed form for
no roll; Gauss-Legendre over the pixel otherwise; ``edgetruth.render.synthetic.analytic.step_image`` for the
circle), under a gentle illumination gradient, with 1 DN of Gaussian noise, rounded to 8-bit PNG.
Three kinds: dark squares on a light board, dark circles, light rectangles (an A5 sheet) on a darker
wall.  The CSV holds the true depths.

Tolerance, from the geometry: an error of 0.05 px in l moves Z by Z·0.05/l (= Z²·0.05/(fx·S)), so
the reference method's |Z_hat − Z| must stay below 100·Z·0.05/l cm on every photo (0.02 cm at 60 cm,
0.33 cm at 260 cm for the 13 cm square).
"""
from __future__ import annotations

import csv
import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from scipy.special import ndtr

from edgetruth.cli import main

W, H, FX = 640, 480, 800.0
CX, CY = (W - 1) / 2.0, (H - 1) / 2.0
BLUR_PX = 0.8
SIZE_TOL_PX = 0.05  # the stated tolerance on l (px); ranging error tolerance Z·SIZE_TOL_PX/l
#: (name, shape, polarity, size_m, height_m, Z_m, lateral X_m, lateral Y_m, roll_deg, group)
PHOTOS = [
    ("sq_060.png", "square", "dark", 0.13, None, 0.60, 0.010, -0.005, 0.0, "squares"),
    ("sq_095.png", "square", "dark", 0.13, None, 0.95, -0.040, 0.020, 4.0, "squares"),
    ("sq_140.png", "square", "dark", 0.13, None, 1.40, 0.100, 0.050, -7.0, "squares"),
    ("sq_185.png", "square", "dark", 0.13, None, 1.85, -0.120, -0.080, 11.0, "squares"),
    ("sq_230.png", "square", "dark", 0.13, None, 2.30, 0.200, 0.100, 2.5, "squares"),
    ("sq_275.png", "square", "dark", 0.13, None, 2.75, -0.250, 0.150, -3.0, "squares"),
    ("ci_080.png", "circle", "dark", 0.13, None, 0.80, 0.030, 0.020, 0.0, "circles"),
    ("ci_160.png", "circle", "dark", 0.13, None, 1.60, -0.150, 0.060, 0.0, "circles"),
    ("ci_240.png", "circle", "dark", 0.13, None, 2.40, 0.180, -0.120, 0.0, "circles"),
    ("re_110.png", "rectangle", "light", 0.21, 0.148, 1.10, 0.020, 0.010, 3.0, "light sheets"),
    ("re_170.png", "rectangle", "light", 0.21, 0.148, 1.70, -0.150, 0.050, -5.0, "light sheets"),
    ("re_250.png", "rectangle", "light", 0.21, 0.148, 2.50, 0.200, -0.100, 1.5, "light sheets"),
]
METHODS = None  # all of them


def _pixel_mean_box_1d(c, lo, hi, s):
    """Mean over the pixel [c - 1/2, c + 1/2] of Phi((t - lo)/s) - Phi((t - hi)/s) (blurred 1-D box)."""
    def g1(u):  # antiderivative of Phi
        return u * ndtr(u) + np.exp(-0.5 * u * u) / np.sqrt(2 * np.pi)

    def mean_phi(a):
        return s * (g1((c + 0.5 - a) / s) - g1((c - 0.5 - a) / s))

    return mean_phi(lo) - mean_phi(hi)


def target_coverage(shape, u, v, half_w, half_h, roll_deg):
    """Pixel means (H, W) of the blurred target indicator (1 inside), centre (u, v) px."""
    if shape == "circle":
        from edgetruth.render.synthetic.analytic import StepProfile, step_image
        from edgetruth.render.edge_truth import CircleEdge

        return step_image((H, W), CircleEdge(u, v, half_w, bright_inside=True), StepProfile(BLUR_PX, BLUR_PX))
    if roll_deg == 0.0:  # separable, closed form
        ys, xs = np.arange(H, dtype=float), np.arange(W, dtype=float)
        return np.outer(_pixel_mean_box_1d(ys, v - half_h, v + half_h, BLUR_PX),
                        _pixel_mean_box_1d(xs, u - half_w, u + half_w, BLUR_PX))
    from edgetruth.render.synthetic.analytic import gauss_legendre_pixel_mean

    c, s = np.cos(np.radians(roll_deg)), np.sin(np.radians(roll_deg))

    def blurred(x, y):  # a Gaussian-blurred rotated rectangle is separable in its own axes
        a, b = c * (x - u) + s * (y - v), -s * (x - u) + c * (y - v)
        return ((ndtr((a + half_w) / BLUR_PX) - ndtr((a - half_w) / BLUR_PX))
                * (ndtr((b + half_h) / BLUR_PX) - ndtr((b - half_h) / BLUR_PX)))

    out = np.zeros((H, W))
    r = int(np.hypot(half_w, half_h) + 6 * BLUR_PX + 3)
    y0, y1, x0, x1 = max(0, int(v) - r), min(H, int(v) + r + 1), max(0, int(u) - r), min(W, int(u) + r + 1)
    yy, xx = np.mgrid[y0:y1, x0:x1].astype(float)
    out[y0:y1, x0:x1] = gauss_legendre_pixel_mean(blurred, xx, yy, nodes=6)
    return out


def make_photo(shape, polarity, size_m, height_m, z_m, x_m, y_m, roll_deg, seed):
    u, v = CX + FX * x_m / z_m, CY + FX * y_m / z_m
    half_w = FX * size_m / z_m / 2.0
    half_h = FX * (height_m if height_m else size_m) / z_m / 2.0
    inside = target_coverage(shape, u, v, half_w, half_h, roll_deg)
    back, target = (200.0, 25.0) if polarity == "dark" else (70.0, 215.0)
    light = 1.0 - 0.10 * np.arange(W)[None, :] / W - 0.05 * np.arange(H)[:, None] / H
    img = light * (back + (target - back) * inside)
    img += np.random.default_rng(seed).normal(0.0, 1.0, img.shape)
    return np.clip(np.round(img), 0, 255).astype(np.uint8)


@pytest.fixture(scope="module")
def photo_set(tmp_path_factory):
    root = tmp_path_factory.mktemp("photos")
    photos = root / "photos"
    photos.mkdir()
    for k, (name, shape, pol, size, height, z, x, y, roll, _) in enumerate(PHOTOS):
        cv2.imwrite(str(photos / name), make_photo(shape, pol, size, height, z, x, y, roll, seed=k))
    K = [[FX, 0.0, CX], [0.0, FX, CY], [0.0, 0.0, 1.0]]
    cal = root / "calibration.json"
    cal.write_text(json.dumps({"K": K, "dist_coeffs_opencv": [0.0] * 5, "image_size": [W, H]}))
    table = root / "distances.csv"
    with open(table, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["image", "distance_cm", "size_m", "height_m", "shape", "group", "polarity"])
        for k, (name, shape, pol, size, height, z, *_, group) in enumerate(PHOTOS):
            # the light sheets' polarity is left to auto; the squares say theirs
            w.writerow([name, f"{100 * z:g}", size, height or "", shape, group,
                        "dark" if shape == "square" else ""])
    return root, photos, table, cal


def _args(photo_set, out, table=None):
    root, photos, tab, cal = photo_set
    return ["evaluate", "--photos", str(photos), "--distances", str(table or tab), "--calibration", str(cal),
            "-o", str(out), "-j", "1", "--no-progress"]


@pytest.fixture(scope="module")
def evaluated(photo_set):
    root = photo_set[0]
    out = root / "report"
    assert main(_args(photo_set, out)) == 0
    return out


def _rows(out):
    with open(out / "ranging_rows.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def test_report_has_the_ranging_tables_and_verdicts(evaluated):
    from edgetruth import locate

    text = (evaluated / "report.md").read_text()
    for heading in ("Table 13 ", "Table 13b", "Table 14", "Table 15", "Tables 16–17 — per group",
                    "Claim-by-claim verdict", "Paired comparisons", "## Photos"):
        assert heading in text, heading
    assert "No per-point tables" in text and "No render truth" in text
    assert "E1" not in text  # the render-only per-point tables
    for group in ("squares", "circles", "light sheets"):
        assert f"| {group} |" in text
    rows = _rows(evaluated)
    free = locate.registry.camera_free()  # photos have no camera model: patch_esf_fit is left out
    assert len(free) == len(locate.METHODS) - 1 and "patch_esf_fit" not in free
    assert len(rows) == len(PHOTOS) * len(free)
    assert {(r["image"], r["method"]) for r in rows} == {(p[0], m) for p in PHOTOS for m in free}
    assert all(r["status"] == "ok" for r in rows), {r["status"] for r in rows}
    summary = json.loads((evaluated / "ranging_summary.json").read_text())
    assert summary["verdicts"] and "dynamic_erf_4p" in summary["per_method"]


def test_polarity_and_shape_found_as_declared(evaluated):
    images = {p["image"]: p for p in json.loads((evaluated / "ranging_images.json").read_text())}
    for name, shape, pol, *_ in PHOTOS:
        rec = images[name]
        assert rec["polarity"] == pol, name
        assert rec["shape_guess"] == shape, name
        assert rec["error"] == ""
    assert images["re_110.png"]["polarity_requested"] == "auto"
    by = images["re_110.png"]["contrast_by_polarity"]  # Michelson contrast of the sheet against the wall
    assert by["light"] == pytest.approx((215 - 70) / (215 + 70), abs=0.02)
    assert not by["dark"] >= 0.05  # no dark region (nan) or one with little contrast


def test_the_reference_method_ranges_within_the_geometric_tolerance(evaluated):
    """|Z_hat - Z| <= Z·0.05/l for dynamic_erf_4p on every photo (l = fx·S/Z, the true image size)."""
    truth = {p[0]: p for p in PHOTOS}
    worst = []
    for r in _rows(evaluated):
        if r["method"] != "dynamic_erf_4p":
            continue
        _, shape, _, size, _, z, *_ = truth[r["image"]]
        l_px = FX * size / z
        tol_cm = 100 * z * SIZE_TOL_PX / l_px
        err = float(r["error_cm"])
        size_err_px = float(r["size_px"]) - l_px
        worst.append((r["image"], err, tol_cm, size_err_px))
        assert abs(err) <= tol_cm, (r["image"], err, tol_cm, size_err_px)
        assert float(r["z_pose_m"]) == pytest.approx(z, rel=0.01)
    assert len(worst) == len(PHOTOS)


def _snapshot(folder: Path) -> dict:
    return {p.relative_to(folder): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


BAD_ROWS = [
    ("missing file", "nothere.png,150,0.13,,square,g,", "not found"),
    ("bad number", "sq_060.png,1.5m,0.13,,square,g,", "distance_cm"),
    ("zero size", "sq_060.png,60,0,,square,g,", "size_m"),
    ("centimetres", "sq_060.png,60,13,,square,g,", "13 cm = 0.13"),
    ("unknown shape", "sq_060.png,60,0.13,,triangle,g,", "shape"),
    ("height on a square", "sq_060.png,60,0.13,0.1,square,g,", "rectangles only"),
    ("unknown polarity", "sq_060.png,60,0.13,,square,g,grey", "polarity"),
    ("no group", "sq_060.png,60,0.13,,square,,", "group"),
    ("short row", "sq_060.png,60", "fewer fields"),
]


@pytest.mark.parametrize("what,row,words", BAD_ROWS, ids=[b[0] for b in BAD_ROWS])
def test_a_bad_row_is_one_line_naming_it_and_writes_nothing(photo_set, evaluated, capsys, tmp_path, what, row, words):
    table = tmp_path / "bad.csv"
    table.write_text("image,distance_cm,size_m,height_m,shape,group,polarity\n"
                     "sq_095.png,95,0.13,,square,g,dark\n" + row + "\n")
    before = _snapshot(evaluated)
    capsys.readouterr()
    assert main(_args(photo_set, evaluated, table)) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "line 3" in err and words in err, err
    assert _snapshot(evaluated) == before
    assert main(_args(photo_set, tmp_path / "new", table)) == 2
    assert not (tmp_path / "new").exists()


def test_duplicates_columns_and_sizes_are_checked_first(photo_set, capsys, tmp_path):
    root, photos, _, cal = photo_set
    cases = [
        ("image,distance_cm,size_m,shape,group\nsq_060.png,60,0.13,square,g\n./sq_060.png,60,0.13,square,g\n",
         ["line 3", "same photo as line 2"]),
        ("image,distance,size_m,shape,group\nsq_060.png,60,0.13,square,g\n", ["line 1", "distance_cm"]),
        ("image,distance_cm,size_m,shape,group\n", ["no rows"]),
    ]
    small = photos.parent / "small"
    small.mkdir(exist_ok=True)
    cv2.imwrite(str(small / "tiny.png"), np.full((48, 64), 200, np.uint8))
    cases.append((f"image,distance_cm,size_m,shape,group\n{small / 'tiny.png'},60,0.13,square,g\n",
                  ["line 2", "64 x 48 px", "640 x 480"]))
    for k, (text, words) in enumerate(cases):
        table = tmp_path / f"t{k}.csv"
        table.write_text(text)
        capsys.readouterr()
        assert main(_args(photo_set, tmp_path / "out", table)) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and all(w in err for w in words), err
        assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("argv,words", [
    (["evaluate", "--no-progress"], "no input"),
    (["evaluate", "somedata", "--photos", "{P}", "--distances", "{T}", "--calibration", "{C}"], "not both"),
    (["evaluate", "--photos", "{P}", "--distances", "{T}"], "--calibration"),
    (["evaluate", "--photos", "{P}", "--calibration", "{C}"], "--distances"),
    (["evaluate", "--distances", "{T}", "--calibration", "{C}"], "--photos"),
])
def test_photos_or_datasets_exactly_one(photo_set, capsys, tmp_path, argv, words):
    root, photos, table, cal = photo_set
    argv = [a.format(P=photos, T=table, C=cal) for a in argv] + ["-o", str(tmp_path / "out")]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and words in err, err
    assert not (tmp_path / "out").exists()


def test_undistorting_the_points_of_distortion_free_photos_changes_no_row(photo_set, evaluated):
    """``--undistort points`` (refine the raw photo, undistort the points): with a distortion-free
    calibration the remap is the identity, so every row but its time is the default's (to 1e-6: undistorting
    a point normalises it with K and projects it back, exact only to rounding, which the circle's iterative
    pose carries to ~1e-10 of the distance), and the report says which undistortion ran."""
    out = photo_set[0] / "report_points"  # beside the default's: the rows' dataset paths match
    assert main(_args(photo_set, out) + ["--undistort", "points"]) == 0
    a, b = _rows(evaluated), _rows(out)
    assert len(a) == len(b) > 0
    for ra, rb in zip(a, b):
        for k, va in ra.items():
            if k == "time_s":
                continue
            try:
                fa, fb = float(va), float(rb[k])
            except ValueError:
                assert va == rb[k], (ra["image"], ra["method"], k)
                continue
            # errors are differences (cm, px): 1e-6 absolute is ~1e-10 of a distance
            assert fb == pytest.approx(fa, rel=1e-6, abs=1e-6, nan_ok=True), (ra["image"], ra["method"], k)
    assert "every method refines the raw image" in (out / "report.md").read_text()
    assert "bilinear remap" in (evaluated / "report.md").read_text()


def test_every_photo_has_an_overlay_linked_from_the_photos_table(evaluated):
    """One overlay PNG per photo in figures/, linked from the report; its green outline is the found one."""
    from edgetruth.evaluate.ranging.overlays import OUTLINE
    from edgetruth.evaluate.ranging.target_finder import _segment_distance

    text = (evaluated / "report.md").read_text()
    assert "Target finding per photo" in text and "runners-up" in text
    images = json.loads((evaluated / "ranging_images.json").read_text())
    assert len(images) == len(PHOTOS)
    for p in images:
        png = evaluated / p["overlay"]
        assert png.is_file() and f"]({p['overlay']})" in text, p["image"]
        rgb = cv2.imread(str(png))[:, :, ::-1]
        ys, xs = np.nonzero(np.all(rgb == np.array(OUTLINE, np.uint8), axis=2))
        outline = np.asarray(p["finder"]["outline_px"], float)
        assert xs.size > 0.9 * len(outline)
        assert _segment_distance(np.column_stack([xs, ys]).astype(float), outline).max() <= 1.0, p["image"]
