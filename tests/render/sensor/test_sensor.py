"""EMVA 1288 sensor model: photon transfer, SNR, clipping, reproducibility."""
from __future__ import annotations

import numpy as np
import pytest

from edgetruth.errors import InputError
from edgetruth.render.sensor.linear_model import SensorModel, make_rng, sensor_from_dict

FLAT = (256, 256)


def _pair(sensor: SensorModel, mean_e: float, seed: int):
    rng = make_rng(seed, 2)
    field = np.full(FLAT, mean_e)
    return sensor.expose_electrons(field, rng).astype(np.float64), sensor.expose_electrons(field, rng).astype(np.float64)


@pytest.mark.parametrize("gain_db", [0.0, 12.0412])
def test_photon_transfer_recovers_gain(gain_db):
    """EMVA photon-transfer: var of a frame difference / 2 against the mean, slope = K (within 3 %)."""
    s = SensorModel(gain_db=gain_db)
    levels = np.linspace(0.05, 0.7, 8) * min(s.full_well_e, s.max_dn / s.gain_dn_per_e)
    means, variances = [], []
    for i, mu_e in enumerate(levels):
        a, b = _pair(s, mu_e, seed=10 + i)
        means.append(0.5 * (a.mean() + b.mean()) - s.dark_offset_dn)
        variances.append(np.var(a - b) / 2.0)
    k_fit = np.polyfit(means, variances, 1)[0]
    assert abs(k_fit / s.gain_dn_per_e - 1.0) < 0.03, (k_fit, s.gain_dn_per_e)


@pytest.mark.parametrize("gain_db,mu_e", [(0.0, 8000.0), (0.0, 300.0), (18.0618, 1000.0), (18.0618, 60.0)])
def test_snr_matches_emva(gain_db, mu_e):
    s = SensorModel(gain_db=gain_db, dark_offset_dn=20.0)  # offset keeps dark noise from clipping at 0
    a, _ = _pair(s, mu_e, seed=7)
    snr = (a.mean() - s.dark_offset_dn) / a.std()
    assert abs(snr / s.predicted_snr(mu_e) - 1.0) < 0.05, (snr, s.predicted_snr(mu_e))
    assert abs(a.var() / s.predicted_variance_dn2(mu_e) - 1.0) < 0.05


def test_gain_formula_and_clipping():
    s = SensorModel(k0_dn_per_e=0.5, gain_db=20.0, bits=10)
    assert s.gain_dn_per_e == pytest.approx(5.0)
    out = s.expose_electrons(np.array([[0.0, 1e9]]), make_rng(1, 2))
    assert out.dtype == np.uint16 and out.max() == 1023  # ADC clip at 2^bits - 1
    w = SensorModel(full_well_e=1000.0, k0_dn_per_e=1.0, dark_noise_e=0.0)
    # full-well clip (above the black level)
    assert w.expose_electrons(np.full((4, 4), 5e4), make_rng(1, 2)).max() == 1000 + w.dark_offset_dn


def test_same_seed_same_bytes_and_different_seed_differs():
    s = SensorModel()
    rad = np.random.default_rng(0).uniform(0, 0.5, (64, 80)).astype(np.float32)
    a = s.expose(rad, 4.0, 4.8, make_rng(123, 2)).tobytes()
    b = s.expose(rad, 4.0, 4.8, make_rng(123, 2)).tobytes()
    c = s.expose(rad, 4.0, 4.8, make_rng(124, 2)).tobytes()
    assert a == b and a != c


def test_global_rng_untouched():
    np.random.seed(5)
    before = np.random.get_state()[1].copy()
    SensorModel().expose(np.ones((8, 8)), 4.0, 4.8, make_rng(1, 2))
    assert np.array_equal(before, np.random.get_state()[1])


def test_photometry():
    """μp = L·π/(4N²)·A·t·λ/(hc): 4.8 µm, f/4, 10 ms, 550 nm -> 31 314 photons per W m⁻² sr⁻¹."""
    assert SensorModel().photons_per_radiance(4.0, 4.8) == pytest.approx(31314.0, rel=1e-4)


def test_unknown_sensor_key_is_input_error():
    with pytest.raises(InputError, match="unknown key"):
        sensor_from_dict({"gain": 3})


def test_black_level_keeps_dark_noise_unclipped_and_the_ptc_linear():
    """Dark frames at the highest gain the shipped specs use: no pixel at DN 0; the photon-transfer
    curve from the dark level up is linear, slope K, intercept K² σd² + 1/12, dark mean = black level."""
    from edgetruth.render.dataset.spec import load_spec

    gain_db = max(g.sensor.gain_db for name in ("study", "quick") for g in load_spec(name).groups)
    s = SensorModel(gain_db=gain_db)
    levels = np.r_[0.0, np.linspace(0.02, 0.7, 8) * (s.max_dn - s.dark_offset_dn) / s.gain_dn_per_e]
    means, variances = [], []
    for i, mu_e in enumerate(levels):
        a, b = _pair(s, mu_e, seed=40 + i)
        if mu_e == 0:
            assert a.min() > 0 and b.min() > 0  # nothing clips at 0
            assert abs(a.mean() - s.dark_offset_dn) < 4 * a.std() / np.sqrt(a.size)
        means.append(0.5 * (a.mean() + b.mean()) - s.dark_offset_dn)
        variances.append(np.var(a - b) / 2.0)
    slope, intercept = np.polyfit(means, variances, 1)
    k = s.gain_dn_per_e
    print(f"gain {gain_db} dB: PTC slope {slope:.4f} (K {k:.4f}), intercept {intercept:.2f} "
          f"(K^2 sd^2 + 1/12 = {k * k * s.dark_noise_e ** 2 + 1 / 12:.2f})")
    assert abs(slope / k - 1.0) < 0.02
    assert abs(intercept / (k * k * s.dark_noise_e ** 2 + 1 / 12) - 1.0) < 0.05


def test_cfa_channel_means_follow_their_qe():
    """A flat field through an RGGB mosaic: each channel's mean DN = K η_c μp + black; OpenCV's
    demosaicing keeps a flat field flat, and the gray output is 0.299 R + 0.587 G + 0.114 B."""
    from edgetruth.render.sensor.pipeline import develop

    s = SensorModel(cfa="RGGB", qe_r=0.2, qe_g=0.55, qe_b=0.12)
    radiance = np.full((256, 256), 0.2)
    mu_p = s.photons_per_radiance(4.0, 4.8) * 0.2
    raw = s.expose(radiance, 4.0, 4.8, make_rng(3, 2)).astype(np.float64)
    k = s.gain_dn_per_e
    expected = {}
    for (dy, dx), ch, qe in (((0, 0), "R", s.qe_r), ((0, 1), "G", s.qe_g), ((1, 0), "G", s.qe_g), ((1, 1), "B", s.qe_b)):
        px = raw[dy::2, dx::2]
        expected[ch] = k * qe * mu_p + s.dark_offset_dn
        se = np.sqrt(s.predicted_variance_dn2(qe * mu_p) / px.size)
        assert abs(px.mean() - expected[ch]) < 4 * se, (ch, px.mean(), expected[ch])
    gray = develop(raw.astype(np.uint16), s).astype(np.float64)[4:-4, 4:-4]
    y = 0.299 * expected["R"] + 0.587 * expected["G"] + 0.114 * expected["B"]
    assert abs(gray.mean() - y) < 1.0  # rounding of the 16-bit demosaic and gray steps
    assert gray.dtype == np.float64 and develop(raw.astype(np.uint16), s).dtype == np.uint16


def test_shot_noise_off_gives_the_mean_electrons_exactly_and_on_leaves_the_json_unchanged():
    """``shot_noise = false`` with no read noise: every DN is round(K μe + black) (the noise-free exposure the twin's
    error budget renders), the full well still clips; with it on (the default) the sensor's JSON has no new key, so
    every earlier render's truth is byte-identical."""
    from edgetruth.render.sensor.linear_model import sensor_from_dict

    s = SensorModel(shot_noise=False, dark_noise_e=0.0)
    mu = np.array([[0.0, 0.4, 100.3, 2000.7, 5000.5, 2.0e4]])
    dn, sat = s.expose_clipped(mu, np.random.default_rng(0))
    want = np.clip(np.rint(s.gain_dn_per_e * np.minimum(mu, s.full_well_e) + s.dark_offset_dn), 0, s.max_dn)
    assert np.array_equal(dn, want.astype(np.uint16))
    assert sat.tolist() == [[False, False, False, False, False, True]]
    assert "shot_noise" not in SensorModel().to_dict() and s.to_dict()["shot_noise"] is False
    assert sensor_from_dict({"shot_noise": False}).shot_noise is False
    on = SensorModel(dark_noise_e=0.0).expose_clipped(np.full((200, 200), 1000.0), np.random.default_rng(1))[0]
    assert np.std(on.astype(float)) == pytest.approx(s.gain_dn_per_e * np.sqrt(1000.0), rel=0.03)  # Poisson: √μ
