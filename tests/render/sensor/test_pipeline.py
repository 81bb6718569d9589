"""The output encodings: 8-bit sRGB and JPEG at a known quality, checked against their standards."""
from __future__ import annotations

import numpy as np
import pytest

from edgetruth.render.sensor.pipeline import develop, srgb_decode, srgb_encode
from edgetruth.render.sensor.linear_model import SensorModel

#: ITU-T T.81 Annex K.1 luminance quantisation table (quality 50 in libjpeg's scaling)
ANNEX_K_LUMA = np.array([
    [16, 11, 10, 16, 24, 40, 51, 61], [12, 12, 14, 19, 26, 58, 60, 55], [14, 13, 16, 24, 40, 57, 69, 56],
    [14, 17, 22, 29, 51, 87, 80, 62], [18, 22, 37, 56, 68, 109, 103, 77], [24, 35, 55, 64, 81, 104, 113, 92],
    [49, 64, 78, 87, 103, 121, 120, 101], [72, 92, 95, 98, 112, 100, 103, 99]], dtype=float)


def _ijg_table(quality: int) -> np.ndarray:
    """libjpeg's jpeg_quality_scaling + jpeg_add_quant_table (baseline: clamp to 1..255)."""
    scale = 5000 / quality if quality < 50 else 200 - 2 * quality
    return np.clip(np.floor((ANNEX_K_LUMA * scale + 50) / 100), 1, 255)


def _block_dct(img: np.ndarray) -> np.ndarray:
    """JPEG's 8x8 DCT-II (T.81 A.3.3) of every block of img - 128, shape (nb, 8, 8)."""
    n = np.arange(8)
    c = np.where(n == 0, 1 / np.sqrt(2), 1.0)
    basis = 0.5 * c[:, None] * np.cos((2 * n[None, :] + 1) * n[:, None] * np.pi / 16)  # [u, x]
    h, w = (s - s % 8 for s in img.shape)
    blocks = (img[:h, :w].astype(np.float64) - 128).reshape(h // 8, 8, w // 8, 8).transpose(0, 2, 1, 3).reshape(-1, 8, 8)
    return np.einsum("ux,bxy,vy->buv", basis, blocks, basis)


def _lattice_fit(coeffs: np.ndarray, quality: int) -> float:
    """Fraction of DCT coefficients within a quarter step of the quality's quantisation lattice."""
    q = _ijg_table(quality)
    r = coeffs / q
    return float(np.mean(np.abs(r - np.round(r)) < 0.25))


def _scene(shape=(256, 256)):
    """An edge-and-ramp raw image (12-bit DN above the black level), noisy."""
    rng = np.random.default_rng(4)
    y, x = np.mgrid[0:shape[0], 0:shape[1]]
    s = SensorModel()
    clean = s.dark_offset_dn + 400 + 2200 * (x * np.cos(0.3) + y * np.sin(0.3) > 120) + 3 * y
    return np.clip(clean + rng.normal(0, 20, shape), 0, s.max_dn).astype(np.uint16)


def test_srgb8_is_the_srgb_curve_of_the_linear_signal():
    s = SensorModel(output="srgb8")
    raw = np.tile(np.linspace(s.dark_offset_dn, s.max_dn, 256).astype(np.uint16), (4, 1))
    out = develop(raw, s)
    v = (raw - s.dark_offset_dn) / (s.max_dn - s.dark_offset_dn)
    ref = np.where(v <= 0.0031308, 12.92 * v, 1.055 * v ** (1 / 2.4) - 0.055)  # IEC 61966-2-1
    assert out.dtype == np.uint8
    np.testing.assert_array_equal(out, np.rint(255 * ref).astype(np.uint8))
    np.testing.assert_allclose(srgb_decode(srgb_encode(v)), v, atol=1e-12)


@pytest.mark.parametrize("quality", [50, 75, 90])
def test_jpeg_round_trip_lies_on_the_quality_quantisation_lattice(quality):
    """The decoded JPEG's block DCT coefficients are multiples of libjpeg's table for the quality
    (up to the 8-bit rounding of the decoded pixels), and no other quality fits as well."""
    s = SensorModel(output="jpeg", jpeg_quality=quality)
    raw = _scene()
    out = develop(raw, s)
    srgb = develop(raw, SensorModel(output="srgb8"))
    assert out.dtype == np.uint8 and out.shape == raw.shape
    coeffs = _block_dct(out)
    fits = {q: _lattice_fit(coeffs, q) for q in range(30, 100)}
    best = max(fits, key=fits.get)
    err = out.astype(float) - srgb
    print(f"q {quality}: lattice fit {fits[quality]:.4f} (best quality {best}), round-trip RMSE {err.std():.2f} DN8")
    assert fits[quality] > 0.97
    assert best == quality or fits[best] - fits[quality] < 0.002
    assert 0.2 < err.std() < 4.0  # lossy, but close
