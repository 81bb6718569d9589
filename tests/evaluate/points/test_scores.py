"""Per-point truth on renders: the outline in the JSON is the exact curve, scoring follows one stated
rule for every method, and the per-point statistics and tests pair images."""
from __future__ import annotations

import numpy as np
import pytest

from edgetruth.evaluate.points import scores as rp
from edgetruth.evaluate.points import report as rpr
from edgetruth.render.optics.camera import load_camera
from edgetruth.render.edge_truth import OutlineEdge
from edgetruth.render.scene.ground_truth import target_ground_truth
from edgetruth.render.scene.outline import OutlineCurve
from edgetruth.render.scene.pose import Pose


def _gt(shape="square", pose=Pose(0.7, 0.12, -0.08, 2.5, -2.0, 7.0), scale=4):
    cam = load_camera("default")
    if scale != 1:
        cam = cam.scaled(scale)
    target = "T1" if shape == "square" else "T2"
    out = target_ground_truth(cam, pose, target, 0.13)
    gt = {"target": {"shape": shape, "size_m": 0.13, "id": target}, **out}
    return cam, pose, gt


@pytest.mark.parametrize("shape", ["square", "circle"])
def test_the_json_outline_is_the_exact_distorted_curve(shape):
    cam, pose, gt = _gt(shape, scale=1)
    truth = OutlineEdge.from_ground_truth(gt)
    curve = OutlineCurve(cam, pose, shape, 0.13)
    rng = np.random.default_rng(1)
    t = rng.random(400)
    on = curve.points(t)
    normal = rng.normal(size=(400, 2))
    q = on + rng.uniform(-1.5, 1.5, (400, 1)) * normal / np.linalg.norm(normal, axis=1, keepdims=True)
    if shape == "square":  # near a corner the two sides compete: the rule excludes those points anyway
        far = truth.corner_distance(q[:, 0], q[:, 1]) > rp.CORNER_EXCLUSION_PX
        q = q[far]
    d_json = truth.signed_distance(q[:, 0], q[:, 1])
    d_exact = curve.signed_distance(q[:, 0], q[:, 1], step_px=0.02)
    assert np.max(np.abs(d_json - d_exact)) < 2e-3  # the polyline's chords: <= 1e-3 px from the curve
    assert np.all(np.abs(truth.signed_distance(on[:, 0], on[:, 1])) < 2e-3)
    cx, cy = gt["centre"]["distorted_px"][0]
    assert truth.signed_distance(np.array([cx]), np.array([cy]))[0] < 0  # inside the (dark) target: < 0


def _render_exact(gt, shape=(256, 320), ss=8, blur_px=0.8, noise=6.0, seed=0):
    """Area-sampled image of the JSON outline (dark target 400 DN on a 3000 DN board), Gaussian blur."""
    from matplotlib.path import Path
    from scipy.ndimage import gaussian_filter

    h, w = shape
    # pixel (r, c) centre is at x = c: sub-sample k of pixel c sits at c - 1/2 + (k + 1/2)/ss
    ys, xs = (np.arange(h * ss) + 0.5) / ss - 0.5, (np.arange(w * ss) + 0.5) / ss - 0.5
    xx, yy = np.meshgrid(xs, ys)
    inside = Path(np.asarray(gt["outline"]["polyline_distorted_px"])).contains_points(
        np.column_stack([xx.ravel(), yy.ravel()])).reshape(xx.shape)
    big = np.where(inside, 400.0, 3000.0)
    img = gaussian_filter(big, blur_px * ss).reshape(h, ss, w, ss).mean(axis=(1, 3))
    return img + np.random.default_rng(seed).normal(0, noise, img.shape)


def test_scoring_separates_pixel_and_subpixel_methods_and_follows_the_rule():
    _, _, gt = _gt("square")
    img = _render_exact(gt)
    methods = ["canny_pixel", "erf4p_fixed11", "dynamic_erf_4p"]
    sc = rp.score_image(img, gt, methods)
    truth = OutlineEdge.from_ground_truth(gt)
    n = len(sc.candidate_distance)
    assert n > 100 and n < sc.n_candidates  # corners and off-edge candidates dropped
    assert np.all(np.abs(sc.candidate_distance) <= rp.MATCH_RADIUS_PX)
    rmse = {m: float(np.sqrt(np.mean(sc.errors[m] ** 2))) for m in methods}
    assert abs(np.mean(sc.errors["erf4p_fixed11"])) < 0.01  # no convention offset between image and truth
    assert rmse["erf4p_fixed11"] < 0.03  # area-sampled exact outline: a subpixel fit lands on it
    assert rmse["canny_pixel"] > 0.15  # pixel centres: ~ 1/sqrt(12) px
    assert set(np.unique(sc.windows["dynamic_erf_4p"])) <= {5, 7, 9, 11}
    assert "erf4p_fixed11" not in sc.windows
    # the scored candidates are the ones the rule keeps
    assert truth.corner_distance(*np.array(gt["outline"]["distorted_px"])[:1].T)[0] == 0.0


def test_gaussian_equivalent_blur_of_a_gaussian_lens_and_a_defocus_disk():
    gt = {"camera": {"pitch_um": 4.0, "f_number": 4.0,
                     "optics": {"psf": {"aberration_sigma_um": 2.0, "aberration_sigma_growth": 0.5,
                                        "diffraction_wavelength_nm": 0.0}}},
          "optics_at_target": {"field_height": 1.0}, "defocus_radius_px": 0.0}
    assert rp.gaussian_equivalent_blur_px(gt) == pytest.approx(2.0 * 1.5 / 4.0)
    gt["defocus_radius_px"] = 2.0
    assert rp.gaussian_equivalent_blur_px(gt) == pytest.approx(np.hypot(0.75, 1.0))  # a disk of radius R: R/2


def test_point_bound_falls_with_the_light():
    """More photons on the same edge: the bound falls (shot noise ~ 1/sqrt(light) at high light)."""
    _, _, gt = _gt("square")
    gt.update(photons_per_radiance=1000.0, defocus_radius_px=0.0,
              sensor={"qe": 0.5, "gain_dn_per_e": 0.4, "dark_noise_e": 1.0},
              camera={"pitch_um": 19.2, "f_number": 4.0, "optics": {"psf": {"aberration_sigma_um": 4.8}}})
    truth = OutlineEdge.from_ground_truth(gt)
    rad = _render_exact(gt, noise=0.0) / 3000.0
    b1, b4 = rp.point_bound_px(gt, rad, truth), rp.point_bound_px(gt, 16 * rad, truth)
    assert 0 < b4 < b1 and b1 / b4 == pytest.approx(4.0, rel=0.1)


def _table(errors_by_method, n_img=12, per=40, seed=0):
    rng = np.random.default_rng(seed)
    images = [{"image": f"{k:04d}", "spec": "s", "levels": "snr=G1;target=T1", "off_base": "", "interval": "100-150",
               "bound_px": 0.01} for k in range(n_img)]
    image = np.repeat(np.arange(n_img), per)
    errs = {m: rng.normal(0, sd, image.size) for m, sd in errors_by_method.items()}
    conv = {m: np.ones(image.size, bool) for m in errs}
    bounds = {m: np.full(image.size, 0.01) for m in errs}  # the exact per-point bound of every point
    return rp.PointTable(images, image, errs, conv, {}, bounds=bounds)


def test_image_paired_comparison_finds_a_real_difference_and_not_a_null_one():
    t = _table({"dynamic_erf_4p": 0.02, "worse": 0.04, "same": 0.02})
    comp = {c["method"]: c for c in rpr.image_comparisons(t, ["dynamic_erf_4p", "worse", "same"])}
    assert comp["worse"]["significant"] and comp["worse"]["rank_biserial"] < -0.9
    lo, hi = comp["worse"]["rmse_difference_ci"]
    assert lo < -0.015 < hi < 0
    assert not comp["same"]["significant"]
    s = rpr.point_stats(t, "worse", np.array([r["bound_px"] for r in t.images]))
    assert s["rmse"] == pytest.approx(0.04, rel=0.1) and s["rmse_over_bound"] == pytest.approx(4.0, rel=0.1)
    assert s["rmse_over_row_bound"] == pytest.approx(s["rmse_over_bound"])  # the reference: 0.01 px per image too
    lo, hi = s["rmse_ci"]
    assert lo < s["rmse"] < hi and hi - lo < 0.01  # 12 images x 40 points: a narrow interval around it


def test_points_file_round_trip(tmp_path):
    t = _table({"a": 0.02, "b": 0.03})
    t.windows["a"] = np.full(len(t.image), 7, np.int8)
    rp.write_points(tmp_path / rp.POINTS_FILE, t)
    back = rp.read_points(tmp_path / rp.POINTS_FILE)
    assert back.images == t.images and np.array_equal(back.image, t.image)
    assert np.allclose(back.errors["b"], t.errors["b"], atol=1e-7) and np.all(back.windows["a"] == 7)
    assert np.allclose(back.bounds["a"], 0.01) and set(back.bounds) == {"a", "b"}
