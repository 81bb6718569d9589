"""EMVA 1288 sensor model: photon transfer, SNR, clipping, reproducibility."""
from __future__ import annotations

import numpy as np
import pytest

from edgetruth.errors import InputError
from edgetruth.render.sensor import SensorModel, make_rng, sensor_from_dict

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
