"""Fixed-pattern noise (EMVA 1288 release 4.0 spatial non-uniformity): DSNU, PRNU, hot and dead
pixels, fixed per camera seed.

The sensor model is applied to flat irradiance fields directly (no render): dark and bright stacks
as EMVA 1288's photon-transfer and spatial measurements take them.  The reference implementation
(the ``emva1288`` package, a test-only dependency) measures K, σd, DSNU and PRNU from them; an
analytic check of the DSNU needs nothing else.
"""
from __future__ import annotations

import numpy as np
import pytest

from edgetruth.errors import InputError
from edgetruth.render.sensor.linear_model import SensorModel, make_rng, sensor_from_dict

SHAPE = (256, 256)
FPN = dict(dsnu_e=6.0, prnu_pct=1.2, fpn_seed=7)


def _saturation_e(s: SensorModel) -> float:
    """Mean electrons at which the DN reaches full scale (or the well fills)."""
    return min(s.full_well_e, (s.max_dn - s.dark_offset_dn) / s.gain_dn_per_e)


def _frames(s: SensorModel, mean_e: float, n: int, seed: int, shape=SHAPE) -> np.ndarray:
    """``n`` frames of a flat field of ``mean_e`` electrons, one image seed each (as a dataset's images)."""
    field = np.full(shape, float(mean_e))
    return np.stack([s.expose_electrons(field, make_rng(seed + i, 2)) for i in range(n)])


# --- off by default: the shipped images do not change ------------------------------------------------
def _reference_expose(s: SensorModel, mean_e: np.ndarray, rng) -> np.ndarray:
    """The sensor model as it was before fixed-pattern noise (the per-image draws: Poisson, then normal)."""
    e = np.minimum(rng.poisson(np.clip(mean_e, 0.0, None)).astype(np.float64), s.full_well_e)
    e += rng.normal(0.0, s.dark_noise_e, size=e.shape) if s.dark_noise_e > 0 else 0.0
    return np.clip(np.rint(s.gain_dn_per_e * e + s.dark_offset_dn), 0, s.max_dn).astype(np.uint16)


@pytest.mark.parametrize("kw", [{}, {"gain_db": 18.0618, "fpn_seed": 99, "hot_pixel_current_e_s": 1e6}])
def test_fpn_off_draws_exactly_the_old_numbers(kw):
    """All FPN keys at 0 (the default; the seed and the hot current alone change nothing): the same
    bytes as the pre-FPN model and the per-image generator left in the same state."""
    s = SensorModel(**kw)
    assert not s.has_fixed_pattern and s.fixed_pattern(SHAPE) is None
    mean_e = np.random.default_rng(0).uniform(0, 1.2 * s.full_well_e, (64, 80))
    a, b = make_rng(5, 2), make_rng(5, 2)
    assert s.expose_electrons(mean_e, a).tobytes() == _reference_expose(s, mean_e, b).tobytes()
    assert a.bit_generator.state == b.bit_generator.state


def test_the_pattern_never_draws_from_the_per_image_generator():
    """DSNU and dead pixels leave the Poisson means alone: the per-image stream ends where it does without them."""
    mean_e = np.full((64, 80), 500.0)
    a, b = make_rng(3, 2), make_rng(3, 2)
    SensorModel(dsnu_e=5.0, dead_pixel_fraction=0.01).expose_electrons(mean_e, a)
    SensorModel().expose_electrons(mean_e, b)
    assert a.bit_generator.state == b.bit_generator.state


# --- fixed per camera --------------------------------------------------------------------------------
def test_pattern_is_the_cameras_fixed_per_fpn_seed():
    s = SensorModel(**FPN, hot_pixel_fraction=0.002, dead_pixel_fraction=0.001)
    p = s.fixed_pattern(SHAPE)
    n = SHAPE[0] * SHAPE[1]
    # the maps' SD over the frame is the value set (normalised), mean gain 1, mean offset 0
    assert np.std(p.offset_e, ddof=1) == pytest.approx(FPN["dsnu_e"], rel=1e-12)
    assert np.std(p.gain, ddof=1) == pytest.approx(FPN["prnu_pct"] / 100, rel=1e-12)
    assert abs(p.gain.mean() - 1) < 1e-12 and abs(p.offset_e.mean()) < 1e-9
    assert p.hot.sum() == round(0.002 * n) and p.dead.sum() == round(0.001 * n) and not (p.hot & p.dead).any()
    # a pure function of the FPN keys: the same for another SensorModel object, other for another seed
    q = SensorModel(**FPN, hot_pixel_fraction=0.002, dead_pixel_fraction=0.001, gain_db=6.0).fixed_pattern(SHAPE)
    assert np.array_equal(p.offset_e, q.offset_e) and np.array_equal(p.hot, q.hot)
    r = SensorModel(**{**FPN, "fpn_seed": 8}).fixed_pattern(SHAPE)
    assert not np.array_equal(p.offset_e, r.offset_e)
    # each part has its own stream: PRNU off leaves the DSNU map; defect sets grow nested
    assert np.array_equal(SensorModel(dsnu_e=6.0, fpn_seed=7).fixed_pattern(SHAPE).offset_e, p.offset_e)
    more = SensorModel(fpn_seed=7, hot_pixel_fraction=0.004).fixed_pattern(SHAPE)
    assert (more.hot >= p.hot).all() and more.hot.sum() == 2 * p.hot.sum()
    # read-only (cached, shared)
    with pytest.raises(ValueError):
        p.offset_e[0, 0] = 1.0


def test_same_pattern_in_every_image_whatever_the_image_seed():
    """Averaged dark frames of two different image-seed sets agree pixel by pixel (their difference is
    temporal noise only), and their common part is the DSNU map."""
    s = SensorModel(**FPN)
    k = s.gain_dn_per_e
    a = (_frames(s, 0.0, 16, seed=100).mean(axis=0) - s.dark_offset_dn) / k
    b = (_frames(s, 0.0, 16, seed=900).mean(axis=0) - s.dark_offset_dn) / k
    d = s.fixed_pattern(SHAPE).offset_e
    sigma_t = np.sqrt(s.dark_noise_e ** 2 + 1 / (12 * k * k))  # temporal, per frame, e-
    rho = s.dsnu_e / np.hypot(s.dsnu_e, sigma_t / 4)  # correlation of a 16-frame average with the map
    assert np.corrcoef(a.ravel(), d.ravel())[0, 1] == pytest.approx(rho, abs=0.01)
    assert np.corrcoef(b.ravel(), d.ravel())[0, 1] == pytest.approx(rho, abs=0.01)
    assert np.std(a - b) == pytest.approx(sigma_t * np.sqrt(2 / 16), rel=0.02)


def test_a_crop_gets_its_window_of_the_frame_and_the_truth_states_it():
    from edgetruth.render.optics.camera import load_camera
    from edgetruth.render.sensor.capture import capture

    cam = load_camera()
    s = SensorModel(**FPN, hot_pixel_fraction=0.001, dead_pixel_fraction=0.001)
    frame = s.fixed_pattern((cam.height_px, cam.width_px))
    crop = (300, 200, 160, 120)  # x0, y0, width, height
    rad = np.full((120, 160), 0.05)
    _, truth = capture(rad, cam, s, make_rng(1, 2), crop=crop)
    fp = truth["fixed_pattern"]
    win = (slice(200, 320), slice(300, 460))
    rows, cols = np.nonzero(frame.hot[win])
    assert fp["hot_pixels"]["xy"] == [[int(c), int(r)] for r, c in zip(rows, cols)]
    assert fp["hot_pixels"]["count"] == int(frame.hot[win].sum()) and fp["origin_xy"] == [300, 200]
    assert fp["dead_pixels"]["count"] == int(frame.dead[win].sum())
    assert fp["dsnu_e"] == pytest.approx(np.std(frame.offset_e[win], ddof=1))
    assert fp["prnu_pct"] == pytest.approx(100 * np.std(frame.gain[win], ddof=1) / frame.gain[win].mean())
    # the same image without a crop: the frame's top-left corner
    _, corner = capture(rad, cam, s, make_rng(1, 2))
    assert corner["fixed_pattern"]["origin_xy"] == [0, 0]
    assert corner["fixed_pattern"]["dsnu_e"] == pytest.approx(np.std(frame.offset_e[:120, :160], ddof=1))
    # without FPN the block is there, empty
    _, off = capture(rad, cam, SensorModel(), make_rng(1, 2))
    assert off["fixed_pattern"]["dsnu_e"] == 0.0 and off["fixed_pattern"]["hot_pixels"] == {
        "count": 0, "current_e_s": SensorModel().hot_pixel_current_e_s, "xy": []}


def test_hot_and_dead_pixels():
    """Dead pixels read the black level in every frame; hot pixels add their dark current
    (mean K · I_hot · t_exp above the black level, Poisson: variance K² (σd² + I_hot t_exp))."""
    s = SensorModel(hot_pixel_fraction=0.01, dead_pixel_fraction=0.01, hot_pixel_current_e_s=3e4, fpn_seed=2)
    p = s.fixed_pattern(SHAPE)
    dark = _frames(s, 0.0, 8, seed=10).astype(np.float64)
    assert (dark[:, p.dead] == round(s.dark_offset_dn)).all()
    hot_e = s.hot_pixel_current_e_s * s.exposure_s  # 300 e-
    k = s.gain_dn_per_e
    hot = dark[:, p.hot]
    assert abs(hot.mean() - (s.dark_offset_dn + k * hot_e)) < 4 * k * np.sqrt((hot_e + 100) / hot.size)
    assert hot.var() == pytest.approx(k * k * (s.dark_noise_e ** 2 + hot_e) + 1 / 12, rel=0.05)
    normal = dark[:, ~(p.hot | p.dead)]
    assert abs(normal.mean() - s.dark_offset_dn) < 0.05
    # a bright field: dead pixels still read black, and are never "saturated"
    dn, sat = s.expose_clipped(np.full(SHAPE, 2e5), make_rng(1, 2))
    assert (dn[p.dead] == round(s.dark_offset_dn)).all() and not sat[p.dead].any() and sat[~p.dead].all()
    # hot pixels that fill the well are saturated pixels, but the image's saturation count (a warning
    # about the light) leaves the defects out: they are listed under fixed_pattern
    from edgetruth.render.optics.camera import load_camera
    from edgetruth.render.sensor.capture import capture

    blazing = SensorModel(hot_pixel_fraction=0.01, hot_pixel_current_e_s=1e7, fpn_seed=2)
    dim = np.full(SHAPE, 0.02)
    _, sat = blazing.expose_clipped(blazing.mean_electrons(dim, 4.0, 4.8), make_rng(1, 2))
    assert sat.sum() == round(0.01 * SHAPE[0] * SHAPE[1])
    _, truth = capture(dim, load_camera(), blazing, make_rng(1, 2))
    assert truth["saturation"]["fraction_all"] == 0.0 and truth["fixed_pattern"]["hot_pixels"]["count"] > 500


@pytest.mark.parametrize("table,fix", [({"prnu_pct": 12.0}, r"prnu_pct = 12.0: must be a finite number in \[0, 10\] %"),
                                       ({"dsnu_e": -1}, r"dsnu_e = -1: must be a finite number in \[0, 10000\] e-"),
                                       ({"hot_pixel_fraction": 0.5}, r"hot_pixel_fraction = 0.5: must be a finite"),
                                       ({"dead_pixel_fraction": "1%"}, r"dead_pixel_fraction = '1%': must be a finite"),
                                       ({"fpn_seed": 1.5}, r"fpn_seed = 1.5: must be an integer"),
                                       ({"hot_pixel_current_e_s": -3.0}, r"hot_pixel_current_e_s = -3.0")])
def test_fpn_keys_are_checked_at_load_with_one_line_errors(table, fix):
    with pytest.raises(InputError, match=fix) as err:
        sensor_from_dict(table, where="spec.toml [sensor]")
    assert "\n" not in str(err.value) and str(err.value).startswith("spec.toml [sensor]: ")


def test_fpn_keys_load_from_a_spec(tmp_path):
    from edgetruth.render.dataset.spec import load_spec
    from edgetruth.render.testing import write_tiny_spec

    path = write_tiny_spec(tmp_path, spp=4)
    text = path.read_text()
    assert "[sensor]" not in text
    path.write_text(text + "\n[sensor]\ndsnu_e = 3.5\nprnu_pct = 0.8\nfpn_seed = 11\n")
    s = load_spec(path).groups[0].sensor
    assert (s.dsnu_e, s.prnu_pct, s.fpn_seed) == (3.5, 0.8, 11) and s.to_dict()["prnu_pct"] == 0.8
    path.write_text(text + "\n[sensor]\nprnu_pct = 40\n")
    with pytest.raises(InputError, match=r"\[sensor\]: prnu_pct = 40"):
        load_spec(path)


# --- the EMVA 1288 numbers ---------------------------------------------------------------------------
def test_dsnu_from_an_averaged_dark_stack():
    """EMVA 1288 DSNU without the reference package: the SD over pixels of the average of L dark frames,
    in e⁻ ((DN − black) / K).  Its variance is s² = DSNU² + σt²/L plus sampling terms, σt² = σd² +
    1/(12 K²) the temporal dark variance per frame in e⁻ (read noise, ADC rounding).  The DSNU map is
    normalised over the frame, so only the temporal part is random: with N pixels, the cross term
    2 cov(d, n̄) has SD 2 · DSNU · σt / sqrt(L N) and the noise's own sample variance SD
    sqrt(2/N) · σt²/L.  Four of their combined SD is the tolerance on s² (~0.4 % of DSNU² here)."""
    s = SensorModel(**FPN)
    L = 32
    n = SHAPE[0] * SHAPE[1]
    k = s.gain_dn_per_e
    avg_e = (_frames(s, 0.0, L, seed=1).mean(axis=0) - s.dark_offset_dn) / k
    s2 = np.var(avg_e, ddof=1)
    t2 = (s.dark_noise_e ** 2 + 1 / (12 * k * k)) / L
    tol = 4 * np.sqrt(4 * s.dsnu_e ** 2 * t2 / n + 2 * t2 ** 2 / n)
    print(f"dark stack L={L}: SD {np.sqrt(s2):.4f} e- (DSNU^2 + sigma_t^2/L -> {np.sqrt(s.dsnu_e ** 2 + t2):.4f}); "
          f"corrected DSNU {np.sqrt(s2 - t2):.4f} e- vs {s.dsnu_e} set; tolerance on s^2 {tol:.4f} e-^2")
    assert abs(s2 - (s.dsnu_e ** 2 + t2)) < tol
    assert abs(np.sqrt(s2 - t2) / s.dsnu_e - 1) < 0.01


def _emva1288_results(s: SensorModel, tmp_path, n_levels: int = 24, L: int = 32):
    """Dark and bright stacks through the reference implementation's own loader and processing:
    temporal data = a dark pair and a pair at each of ``n_levels`` illuminations from 1 % to 115 % of
    saturation (one exposure time, the light varied); spatial data = L dark and L bright frames at
    50 % of saturation.  Frames are .npy files the loader reads with ``numpy.load``."""
    from emva1288.process import Data1288, LoadImageData, Results1288

    texp = s.exposure_s * 1e6  # µs; one exposure time (its unit does not enter the results)
    sat_e = _saturation_e(s)
    eta = s.qe

    def save(frames, tag):
        names = []
        for i, f in enumerate(frames):
            np.save(tmp_path / f"{tag}_{i}.npy", f)
            names.append(f"{tag}_{i}.npy")
        return names

    temporal, seed = {}, 1000
    for j, mu_e in enumerate(np.r_[0.0, np.linspace(0.01, 1.15, n_levels) * sat_e]):
        temporal[float(mu_e / eta)] = save(_frames(s, mu_e, 2, seed), f"t{j}")  # keyed by photons per pixel
        seed += 2
    bright_e = 0.5 * sat_e
    spatial = {0.0: save(_frames(s, 0.0, L, seed), "sd"),
               float(bright_e / eta): save(_frames(s, bright_e, L, seed + L), "sb")}
    images = {"temporal": {texp: temporal}, "spatial": {texp: spatial}}
    loaded = LoadImageData(images, path=str(tmp_path), fload=np.load)
    return Results1288(Data1288(loaded.data).data, loglevel=30)


@pytest.mark.parametrize("gain_db,kw", [(0.0, FPN), (12.0412, dict(dsnu_e=2.5, prnu_pct=3.0, fpn_seed=3))])
def test_emva1288_reference_implementation_measures_what_was_set(gain_db, kw, tmp_path, monkeypatch):
    """K, σd, DSNU and PRNU as the EMVA 1288 reference implementation (package ``emva1288``, standard
    release 4.0) measures them from simulated stacks: each within 5 % of the value set."""
    emva = pytest.importorskip("emva1288", reason="the EMVA 1288 reference implementation: pip install emva1288")
    assert emva.__standard_version__ == "4.0"
    if not hasattr(np, "asfarray"):  # emva1288 1.0.2 calls np.asfarray, removed in numpy 2.0
        monkeypatch.setattr(np, "asfarray", lambda a, dtype=np.float64: np.asarray(a, dtype=dtype), raising=False)
    s = SensorModel(gain_db=gain_db, **kw)
    r = _emva1288_results(s, tmp_path)
    k = s.gain_dn_per_e
    measured = {"K": (r.K, k), "sigma_y_dark": (r.sigma_y_dark, np.sqrt(k * k * s.dark_noise_e ** 2 + 1 / 12)),
                "sigma_d": (r.sigma_d, s.dark_noise_e), "DSNU1288.DN / K": (r.DSNU1288_DN() / k, s.dsnu_e),
                "DSNU1288": (r.DSNU1288, s.dsnu_e), "PRNU1288": (r.PRNU1288, s.prnu_pct)}
    print(f"\nemva1288 {emva.__version__} at {gain_db} dB: " + "; ".join(
        f"{name} {got:.4f} (set {want:.4f}, {100 * (got / want - 1):+.2f} %)"
        for name, (got, want) in measured.items()))
    for name, (got, want) in measured.items():
        assert abs(got / want - 1) < 0.05, (name, got, want)
