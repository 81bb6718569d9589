"""EMVA 1288 linear camera model: radiance -> photons -> electrons -> digital numbers.

    μp  = L · π/(4N²) · A_pix · t_exp · λ/(h c)        photons per pixel (on-axis irradiance)
    μe  = η · μp                                        electrons; Poisson shot noise
    e   = min(Poisson(μe), full well)
    y   = K · (e + N(0, σd²)) + offset                  K = K0 · 10^(G_dB / 20)  [DN/e⁻]
    DN  = clip(round(y), 0, 2^bits − 1)

so that Var(y) = K²(σd² + μe) + 1/12 below saturation.  The offset (black level) keeps the
dark noise above 0: nothing clips there.  With a Bayer colour filter array (``cfa``) each
pixel has its channel's QE (``qe_r``, ``qe_g``, ``qe_b``) instead of ``qe``; demosaicing and
the output encoding (``output``: raw DN, 8-bit sRGB, JPEG) are ``edgetruth.render.pipeline``.
All randomness comes from a seeded ``numpy.random.Generator`` passed in by the caller
(never the global RNG).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, fields, replace

import numpy as np

from edgetruth.errors import require
from edgetruth.render.schema import Key, parse_table

CFA_PATTERNS = ("none", "RGGB", "BGGR", "GRBG", "GBRG")
OUTPUTS = ("raw", "srgb8", "jpeg")
PLANCK_J_S = 6.62607015e-34
SPEED_OF_LIGHT_M_S = 299792458.0


@dataclass(frozen=True)
class SensorModel:
    """Sensor parameters.  Defaults: a 12-bit CCD-like sensor; 0 dB maps the full well to ~full scale."""

    qe: float = 0.6
    exposure_s: float = 0.01
    wavelength_nm: float = 550.0
    dark_noise_e: float = 10.0
    full_well_e: float = 10500.0
    k0_dn_per_e: float = 0.39
    gain_db: float = 0.0
    bits: int = 12
    dark_offset_dn: float = 256.0
    cfa: str = "none"
    qe_r: float = 0.15
    qe_g: float = 0.6
    qe_b: float = 0.15
    output: str = "raw"
    jpeg_quality: int = 90

    def __post_init__(self) -> None:
        require(0 < self.qe <= 1, f"sensor: qe must be in (0, 1], got {self.qe}")
        require(self.exposure_s > 0 and self.full_well_e > 0 and self.k0_dn_per_e > 0,
                "sensor: exposure_s, full_well_e, k0_dn_per_e must be positive")
        require(self.dark_noise_e >= 0, "sensor: dark_noise_e must be >= 0")
        require(1 <= int(self.bits) <= 16, f"sensor: bits must be 1..16 (stored as 16-bit PNG), got {self.bits}")
        require(self.cfa in CFA_PATTERNS, f"sensor: cfa must be one of {', '.join(CFA_PATTERNS)}")
        require(self.output in OUTPUTS, f"sensor: output must be one of {', '.join(OUTPUTS)}")
        require(0 <= self.dark_offset_dn < self.max_dn, "sensor: dark_offset_dn must lie below full scale")

    @property
    def gain_dn_per_e(self) -> float:
        """K = K0 · 10^(G_dB/20)."""
        return self.k0_dn_per_e * 10.0 ** (self.gain_db / 20.0)

    @property
    def max_dn(self) -> int:
        return 2 ** int(self.bits) - 1

    def photons_per_radiance(self, f_number: float, pitch_um: float) -> float:
        """Mean photons per pixel per unit radiance (W m⁻² sr⁻¹) during the exposure."""
        require(f_number > 0, "sensor photometry needs a finite f-number (camera f_number > 0)")
        pixel_area_m2 = (pitch_um * 1e-6) ** 2
        photon_energy_j = PLANCK_J_S * SPEED_OF_LIGHT_M_S / (self.wavelength_nm * 1e-9)
        return np.pi / (4.0 * f_number ** 2) * pixel_area_m2 * self.exposure_s / photon_energy_j

    def qe_map(self, shape: tuple[int, int]) -> np.ndarray | float:
        """η per pixel: ``qe`` without a CFA, else each pixel's channel QE (pattern from pixel (0, 0))."""
        if self.cfa == "none":
            return self.qe
        qe = {"R": self.qe_r, "G": self.qe_g, "B": self.qe_b}
        out = np.empty(shape)
        for k, ch in enumerate(self.cfa):
            out[k // 2::2, k % 2::2] = qe[ch]
        return out

    def mean_electrons(self, radiance: np.ndarray, f_number: float, pitch_um: float) -> np.ndarray:
        """μe = η · μp (no noise, no clipping)."""
        rad = np.asarray(radiance, dtype=np.float64)
        return self.qe_map(rad.shape) * self.photons_per_radiance(f_number, pitch_um) * rad

    def expose_electrons(self, mean_e: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Mean electrons -> digital numbers (uint16), with shot noise, dark noise, clipping, ADC."""
        return self.expose_clipped(mean_e, rng)[0]

    def expose_clipped(self, mean_e: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """(DN uint16, saturated bool): pixels whose electrons reached the full well or whose DN the ADC
        clipped at full scale (the black level keeps the low end unclipped)."""
        mean_e = np.clip(np.asarray(mean_e, dtype=np.float64), 0.0, None)
        e = rng.poisson(mean_e).astype(np.float64)
        saturated = e >= self.full_well_e
        e = np.minimum(e, self.full_well_e)
        e += rng.normal(0.0, self.dark_noise_e, size=e.shape) if self.dark_noise_e > 0 else 0.0
        y = np.rint(self.gain_dn_per_e * e + self.dark_offset_dn)
        saturated |= y >= self.max_dn
        return np.clip(y, 0, self.max_dn).astype(np.uint16), saturated

    def expose(self, radiance: np.ndarray, f_number: float, pitch_um: float, rng: np.random.Generator) -> np.ndarray:
        """Radiance image -> digital numbers (uint16)."""
        return self.expose_electrons(self.mean_electrons(radiance, f_number, pitch_um), rng)

    # --- EMVA predictions ------------------------------------------------------
    def predicted_mean_dn(self, mean_e: np.ndarray) -> np.ndarray:
        return self.gain_dn_per_e * np.asarray(mean_e, dtype=np.float64) + self.dark_offset_dn

    def predicted_variance_dn2(self, mean_e: np.ndarray) -> np.ndarray:
        """Var(y) = K²(σd² + μe) + 1/12."""
        return self.gain_dn_per_e ** 2 * (self.dark_noise_e ** 2 + np.asarray(mean_e, dtype=np.float64)) + 1.0 / 12.0

    def predicted_snr(self, mean_e: np.ndarray) -> np.ndarray:
        """EMVA SNR = μe / sqrt(σd² + μe + 1/(12 K²))."""
        mean_e = np.asarray(mean_e, dtype=np.float64)
        return mean_e / np.sqrt(self.dark_noise_e ** 2 + mean_e + 1.0 / (12.0 * self.gain_dn_per_e ** 2))

    def with_overrides(self, **overrides) -> "SensorModel":
        return replace(self, **overrides)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["gain_dn_per_e"] = self.gain_dn_per_e
        d["max_dn"] = self.max_dn
        d["model"] = "EMVA 1288 linear: Var(y) = K^2 (sigma_d^2 + mu_e) + 1/12"
        return d


_D = SensorModel()
#: The ``[sensor]`` table of a spec (and a group's ``sensor = {...}`` overrides).
SENSOR_KEYS = [
    Key("qe", "float", _D.qe, "", "quantum efficiency eta at the wavelength", 1e-6, 1.0),
    Key("exposure_s", "float", _D.exposure_s, "s", "exposure time", 1e-9, 3600.0),
    Key("wavelength_nm", "float", _D.wavelength_nm, "nm", "wavelength of the (monochromatic) light", 100.0, 2000.0),
    Key("dark_noise_e", "float", _D.dark_noise_e, "e-", "dark (read) noise sigma_d", 0.0, 1e4),
    Key("full_well_e", "float", _D.full_well_e, "e-", "full-well capacity (electrons clip here)", 1.0, 1e8),
    Key("k0_dn_per_e", "float", _D.k0_dn_per_e, "DN/e-", "system gain K0 at 0 dB", 1e-6, 1e3),
    Key("gain_db", "float", _D.gain_db, "dB", "analog gain G: K = K0 * 10^(G/20)", -40.0, 60.0),
    Key("bits", "int", _D.bits, "bit", "ADC resolution (stored in a 16-bit PNG)", 1, 16),
    Key("dark_offset_dn", "float", _D.dark_offset_dn, "DN", "black level (dark offset) added before the ADC, so "
        "that dark noise is not clipped at 0", 0.0, 65535.0),
    Key("cfa", "str", _D.cfa, "", "Bayer colour filter array (pattern of the 2x2 block at pixel (0, 0)); the "
        "output is demosaiced (OpenCV) to gray", choices=CFA_PATTERNS),
    Key("qe_r", "float", _D.qe_r, "", "QE of the red CFA pixels at the wavelength", 1e-6, 1.0),
    Key("qe_g", "float", _D.qe_g, "", "QE of the green CFA pixels at the wavelength", 1e-6, 1.0),
    Key("qe_b", "float", _D.qe_b, "", "QE of the blue CFA pixels at the wavelength", 1e-6, 1.0),
    Key("output", "str", _D.output, "", "image file content: raw = DN in a 16-bit PNG; srgb8 = (DN - black) / "
        "(full scale - black) through the sRGB curve in an 8-bit PNG; jpeg = srgb8 through a JPEG encoder "
        "(decoded pixels in an 8-bit PNG)", choices=OUTPUTS),
    Key("jpeg_quality", "int", _D.jpeg_quality, "", "JPEG quality (libjpeg scale) for output = jpeg", 1, 100),
]
assert [k.name for k in SENSOR_KEYS] == [f.name for f in fields(SensorModel)]


def sensor_from_dict(d: dict, base: SensorModel | None = None, where: str = "sensor") -> SensorModel:
    """A ``SensorModel`` from a spec table (values checked against ``SENSOR_KEYS``), over ``base``."""
    return replace(base or SensorModel(), **parse_table(d, SENSOR_KEYS, where, defaults=False))


def make_rng(seed: int, stream: int) -> np.random.Generator:
    """An independent, reproducible generator per (image seed, purpose)."""
    return np.random.Generator(np.random.PCG64([int(seed), int(stream)]))
