"""EMVA 1288 linear camera model: radiance -> photons -> electrons -> digital numbers.

    μp  = L · π/(4N²) · A_pix · t_exp · λ/(h c)        photons per pixel (on-axis irradiance)
    μe  = η · μp                                        electrons; Poisson shot noise
    e   = min(Poisson(μe), full well)
    y   = K · (e + N(0, σd²)) + offset                  K = K0 · 10^(G_dB / 20)  [DN/e⁻]
    DN  = clip(round(y), 0, 2^bits − 1)

so that Var(y) = K²(σd² + μe) + 1/12 below saturation.  The offset (black level) keeps the
dark noise above 0: nothing clips there.  With a Bayer colour filter array (``cfa``) each
pixel has its channel's QE (``qe_r``, ``qe_g``, ``qe_b``) instead of ``qe``; demosaicing and
the output encoding (``output``: raw DN, 8-bit sRGB, JPEG) are ``edgetruth.render.sensor.pipeline``,
as is an optional reduction of the 8-bit output to a few levels (``output_levels``: N gray
levels; ``output_levels_rgb``: an RGB palette of Nr x Ng x Nb levels, the gray read back as luma),
with or without Floyd-Steinberg error diffusion (``output_dither``), and a video camera's
processing of the encoded values (``output_gain``, ``output_offset_dn``; ``sharpen_amount``: an unsharp mask along x, y
or both; ``output_noise_dn``: noise added after them), a power-law curve instead of sRGB's (``output_gamma``) and a
clip below 255 (``output_clip_dn``).  All off by default; only
``output_noise_dn`` draws random numbers (from the image's generator, after the exposure's).
All randomness comes from a seeded ``numpy.random.Generator`` passed in by the caller
(never the global RNG).

Fixed-pattern noise (EMVA 1288 release 4.0 spatial non-uniformity), fixed per camera by
``fpn_seed`` (the same pattern in every image of a camera, drawn from its own generators, never
from the per-image one), with z_g, z_d two standard-normal maps over the camera's frame, each
shifted and scaled to mean 0 and SD 1 over the frame's pixels:

    g   = 1 + (prnu_pct / 100) · z_g                   relative photo-response (gain) map: PRNU
    d   = dsnu_e · z_d                                  dark-signal offset map [e⁻]: DSNU
    e   = min(Poisson(μe · g + I_hot · t_exp · [hot]), full well)
    y   = K · (e + d + N(0, σd²)) + offset
    DN  = clip(round(y), 0, 2^bits − 1);  DN = clip(round(offset)) on a dead pixel

PRNU scales the photo-electrons (a QE / fill-factor spread), so each pixel's shot noise follows
its own mean and the temporal photon transfer is unchanged; DSNU is an offset in electrons after
the well (a readout offset spread: no shot noise, not clipped by the full well).  So, measured as
EMVA 1288 does, DSNU1288 = SD over pixels of the averaged dark image / K = ``dsnu_e`` and
PRNU1288 = SD of (averaged bright − averaged dark) / its mean = ``prnu_pct`` %, with K and σd
(from frame differences) untouched.  Hot pixels (a ``hot_pixel_fraction`` of the frame) collect
an extra dark current ``hot_pixel_current_e_s`` (Poisson, clipped by the well like light); dead
pixels (``dead_pixel_fraction``) read the black level, without noise.  Both sets are drawn once
per camera (disjoint; each grows monotonically with its fraction).  With every FPN key at 0 the
model is the one above, drawing exactly the same numbers from the per-image generator.
"""
from __future__ import annotations

import functools
from dataclasses import asdict, dataclass, fields, replace

import numpy as np

from edgetruth.errors import require
from edgetruth.render.schema import Key, parse_table

CFA_PATTERNS = ("none", "RGGB", "BGGR", "GRBG", "GBRG")
OUTPUTS = ("raw", "srgb8", "jpeg")
DITHERS = ("none", "floyd_steinberg")
SHARPEN_AXES = ("x", "y", "xy")
#: the output-quantisation keys (left out of a spec's identity while no quantisation is on)
QUANTISE_KEYS = ("output_levels", "output_levels_rgb", "output_rgb_gains", "output_dither")
#: the video-processing keys (left out of a spec's identity while all are off)
VIDEO_KEYS = ("output_gain", "output_offset_dn", "sharpen_amount", "sharpen_sigma_px", "sharpen_axis", "output_noise_dn")
#: the output-curve keys (each left out of a spec's identity at its default: the sRGB curve, the clip at 255)
CURVE_KEYS = ("output_gamma", "output_clip_dn")
_CURVE_DEFAULTS = {"output_gamma": 0.0, "output_clip_dn": 255.0}


def _drop_default_curve(d: dict) -> None:
    """Leave the output-curve keys out of ``d`` (identity, JSON) where they hold their defaults."""
    for k in CURVE_KEYS:
        if d[k] == _CURVE_DEFAULTS[k]:
            d.pop(k)
PLANCK_J_S = 6.62607015e-34
SPEED_OF_LIGHT_M_S = 299792458.0
#: streams of the camera's fixed-pattern generators, [fpn_seed, stream] (the per-image streams are 1, 2)
PRNU_STREAM, DSNU_STREAM, DEFECT_STREAM = 128801, 128802, 128803
PRNU_MAX_PCT = 10.0  # keeps the gain map positive (10 SD below the mean)
DEFECT_MAX_FRACTION = 0.01
FPN_SEED_MAX = 10 ** 9


#: the fixed-pattern keys (left out of a spec's identity while no pattern is on)
FPN_KEYS = ("dsnu_e", "prnu_pct", "hot_pixel_fraction", "hot_pixel_current_e_s", "dead_pixel_fraction", "fpn_seed")


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
    dsnu_e: float = 0.0
    prnu_pct: float = 0.0
    hot_pixel_fraction: float = 0.0
    hot_pixel_current_e_s: float = 5.0e4
    dead_pixel_fraction: float = 0.0
    fpn_seed: int = 0
    output_levels: int = 0
    output_levels_rgb: tuple = (0, 0, 0)
    output_rgb_gains: tuple = (1.0, 1.0, 1.0)
    output_dither: str = "none"
    output_gain: float = 1.0
    output_offset_dn: float = 0.0
    sharpen_amount: float = 0.0
    sharpen_sigma_px: float = 1.0
    sharpen_axis: str = "x"
    output_noise_dn: float = 0.0
    output_gamma: float = _CURVE_DEFAULTS["output_gamma"]
    output_clip_dn: float = _CURVE_DEFAULTS["output_clip_dn"]
    #: False: each pixel gets its mean photo-electrons (no Poisson draw): with dark_noise_e = 0 and
    #: output_noise_dn = 0 a noise-free exposure (the twin's error budget switches the noise off so)
    shot_noise: bool = True

    def __post_init__(self) -> None:
        require(0 < self.qe <= 1, f"sensor: qe must be in (0, 1], got {self.qe}")
        require(self.exposure_s > 0 and self.full_well_e > 0 and self.k0_dn_per_e > 0,
                "sensor: exposure_s, full_well_e, k0_dn_per_e must be positive")
        require(self.dark_noise_e >= 0, "sensor: dark_noise_e must be >= 0")
        require(1 <= int(self.bits) <= 16, f"sensor: bits must be 1..16 (stored as 16-bit PNG), got {self.bits}")
        require(self.cfa in CFA_PATTERNS, f"sensor: cfa must be one of {', '.join(CFA_PATTERNS)}")
        require(self.output in OUTPUTS, f"sensor: output must be one of {', '.join(OUTPUTS)}")
        require(0 <= self.dark_offset_dn < self.max_dn, "sensor: dark_offset_dn must lie below full scale")
        require(self.dsnu_e >= 0, f"sensor: dsnu_e must be >= 0, got {self.dsnu_e}")
        require(0 <= self.prnu_pct <= PRNU_MAX_PCT,
                f"sensor: prnu_pct must be in [0, {PRNU_MAX_PCT:g}], got {self.prnu_pct}")
        require(0 <= self.hot_pixel_fraction <= DEFECT_MAX_FRACTION and 0 <= self.dead_pixel_fraction
                <= DEFECT_MAX_FRACTION, f"sensor: hot_pixel_fraction, dead_pixel_fraction must be in "
                f"[0, {DEFECT_MAX_FRACTION:g}]")
        require(self.hot_pixel_current_e_s >= 0, "sensor: hot_pixel_current_e_s must be >= 0")
        require(0 <= int(self.fpn_seed) <= FPN_SEED_MAX, f"sensor: fpn_seed must be in [0, {FPN_SEED_MAX}]")
        require(self.output_levels == 0 or 2 <= int(self.output_levels) <= 256,
                f"sensor: output_levels must be 0 (off) or 2..256, got {self.output_levels}")
        rgb = tuple(self.output_levels_rgb)
        require(len(rgb) == 3 and (all(v == 0 for v in rgb) or all(v == int(v) and 2 <= v <= 256 for v in rgb)),
                f"sensor: output_levels_rgb must be [0, 0, 0] (off) or three integers in 2..256, got {list(rgb)}")
        require(self.output_dither in DITHERS, f"sensor: output_dither must be one of {', '.join(DITHERS)}")
        require(not (self.output_levels and any(rgb)),
                "sensor: output_levels and output_levels_rgb both set; give one (gray levels or an RGB palette)")
        require(self.output_dither == "none" or self.quantised,
                "sensor: output_dither needs output_levels or output_levels_rgb (the levels to dither between)")
        require(not self.quantised or self.output != "raw",
                "sensor: output_levels / output_levels_rgb reduce the 8-bit output; use output = srgb8 or jpeg")
        require(self.sharpen_amount >= 0 and self.sharpen_sigma_px > 0,
                "sensor: sharpen_amount must be >= 0 and sharpen_sigma_px > 0")
        require(self.sharpen_axis in SHARPEN_AXES, f"sensor: sharpen_axis must be one of {', '.join(SHARPEN_AXES)}")
        require(not self.video_processed or self.output != "raw",
                "sensor: output_gain, output_offset_dn, sharpen_amount and output_noise_dn act on the encoded output; "
                "use output = "
                "srgb8 or jpeg")
        require(self.output_gain > 0 and self.output_noise_dn >= 0,
                "sensor: output_gain must be > 0 and output_noise_dn >= 0")
        require(self.output_gamma == 0 or 0.2 <= self.output_gamma <= 5.0,
                f"sensor: output_gamma must be 0 (the sRGB curve) or 0.2..5, got {self.output_gamma}")
        require(1.0 <= self.output_clip_dn <= 255.0,
                f"sensor: output_clip_dn must be in 1..255, got {self.output_clip_dn}")
        require(self.output != "raw" or (self.output_gamma == 0 and self.output_clip_dn == 255.0),
                "sensor: output_gamma and output_clip_dn shape the 8-bit output; use output = srgb8 or jpeg")
        require(len(tuple(self.output_rgb_gains)) == 3 and all(g > 0 for g in self.output_rgb_gains),
                "sensor: output_rgb_gains must be three positive numbers")
        require(tuple(self.output_rgb_gains) == (1.0, 1.0, 1.0) or any(self.output_levels_rgb),
                "sensor: output_rgb_gains applies to output_levels_rgb (the RGB palette); add it or drop the gains")

    def identity(self) -> dict:
        """The values that determine the images, for a spec's identity hash: the fixed-pattern keys
        appear only when a pattern is on, so datasets rendered before they existed still resume."""
        d = asdict(self)
        if not self.has_fixed_pattern:
            for k in FPN_KEYS:
                d.pop(k)
        if not self.quantised:
            for k in QUANTISE_KEYS:
                d.pop(k)
        if not self.video_processed:
            for k in VIDEO_KEYS:
                d.pop(k)
        _drop_default_curve(d)
        return d

    @property
    def video_processed(self) -> bool:
        """Any of output_gain, sharpening and output_noise_dn on (``edgetruth.render.sensor.pipeline``)."""
        return (self.output_gain != 1.0 or bool(self.output_offset_dn) or bool(self.sharpen_amount)
                or bool(self.output_noise_dn))

    @property
    def quantised(self) -> bool:
        """The 8-bit output reduced to fewer levels (``output_levels`` or ``output_levels_rgb``)."""
        return bool(self.output_levels) or any(self.output_levels_rgb)

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

    @property
    def has_fixed_pattern(self) -> bool:
        """Any fixed-pattern noise (DSNU, PRNU, hot or dead pixels) switched on."""
        return bool(self.dsnu_e or self.prnu_pct or self.hot_pixel_fraction or self.dead_pixel_fraction)

    def fixed_pattern(self, frame: tuple[int, int], window: tuple[int, int, int, int] | None = None
                      ) -> "FixedPattern | None":
        """The camera's fixed pattern over its ``frame`` (height, width), or over ``window`` = (x0, y0,
        width, height) of it; None when every FPN key is 0.  A pure function of the FPN keys and the
        frame (cached): the same pattern in every image of the camera."""
        if not self.has_fixed_pattern:
            return None
        full = _fixed_pattern(int(self.fpn_seed), float(self.dsnu_e), float(self.prnu_pct),
                              float(self.hot_pixel_fraction), float(self.dead_pixel_fraction),
                              (int(frame[0]), int(frame[1])))
        return full if window is None else full.window(*window)

    def expose_electrons(self, mean_e: np.ndarray, rng: np.random.Generator,
                         pattern: "FixedPattern | None" = None) -> np.ndarray:
        """Mean electrons -> digital numbers (uint16), with shot noise, dark noise, clipping, ADC."""
        return self.expose_clipped(mean_e, rng, pattern)[0]

    def expose_clipped(self, mean_e: np.ndarray, rng: np.random.Generator,
                       pattern: "FixedPattern | None" = None) -> tuple[np.ndarray, np.ndarray]:
        """(DN uint16, saturated bool): pixels whose electrons reached the full well or whose DN the ADC
        clipped at full scale (the black level keeps the low end unclipped; a dead pixel is never
        saturated).  ``pattern``: the camera's fixed pattern cut to this image (``fixed_pattern``);
        by default the pattern of a frame of this image's shape."""
        mean_e = np.clip(np.asarray(mean_e, dtype=np.float64), 0.0, None)
        if pattern is None and self.has_fixed_pattern:
            pattern = self.fixed_pattern(mean_e.shape)
        if pattern is not None:
            require(pattern.shape == mean_e.shape, f"sensor: fixed pattern {pattern.shape} does not match the "
                    f"image {mean_e.shape}")
        lam = mean_e if pattern is None else pattern.electron_mean(mean_e, self.hot_pixel_current_e_s * self.exposure_s)
        e = rng.poisson(lam).astype(np.float64) if self.shot_noise else np.array(lam, np.float64)
        saturated = e >= self.full_well_e
        e = np.minimum(e, self.full_well_e)
        if pattern is not None and pattern.offset_e is not None:
            e += pattern.offset_e
        e += rng.normal(0.0, self.dark_noise_e, size=e.shape) if self.dark_noise_e > 0 else 0.0
        y = np.rint(self.gain_dn_per_e * e + self.dark_offset_dn)
        saturated |= y >= self.max_dn
        dn = np.clip(y, 0, self.max_dn).astype(np.uint16)
        if pattern is not None and pattern.dead is not None:
            dn[pattern.dead] = np.clip(np.rint(self.dark_offset_dn), 0, self.max_dn)
            saturated[pattern.dead] = False
        return dn, saturated

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
        if self.quantised:
            d["output_levels_rgb"] = [int(v) for v in self.output_levels_rgb]
            d["output_rgb_gains"] = [float(v) for v in self.output_rgb_gains]
        else:  # off: the JSON of a sensor without output quantisation is unchanged
            for k in QUANTISE_KEYS:
                d.pop(k)
        if not self.video_processed:
            for k in VIDEO_KEYS:
                d.pop(k)
        _drop_default_curve(d)
        if self.shot_noise:  # on (the default): the JSON of every sensor with shot noise is unchanged
            d.pop("shot_noise")
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
    Key("dsnu_e", "float", _D.dsnu_e, "e-", "DSNU (EMVA 1288): SD over pixels of the fixed dark-signal offset, "
        "added in electrons after the full well; fixed per fpn_seed", 0.0, 1e4),
    Key("prnu_pct", "float", _D.prnu_pct, "%", "PRNU (EMVA 1288): SD over pixels of the relative photo-response "
        "(gain on the photo-electrons, before shot noise), in % of its mean; fixed per fpn_seed", 0.0, PRNU_MAX_PCT),
    Key("hot_pixel_fraction", "float", _D.hot_pixel_fraction, "", "fraction of hot pixels (extra dark current "
        "hot_pixel_current_e_s); positions fixed per fpn_seed, listed in the ground truth", 0.0, DEFECT_MAX_FRACTION),
    Key("hot_pixel_current_e_s", "float", _D.hot_pixel_current_e_s, "e-/s", "dark current of a hot pixel "
        "(Poisson, clipped by the full well; times exposure_s)", 0.0, 1e9),
    Key("dead_pixel_fraction", "float", _D.dead_pixel_fraction, "", "fraction of dead pixels (read the black "
        "level, no noise); positions fixed per fpn_seed, listed in the ground truth", 0.0, DEFECT_MAX_FRACTION),
    Key("fpn_seed", "int", _D.fpn_seed, "", "camera seed of the fixed-pattern noise (DSNU, PRNU, hot and dead "
        "pixels): the same pattern in every image of the camera, whatever the image seed", 0, FPN_SEED_MAX),
    Key("output_levels", "int", _D.output_levels, "levels", "reduce the 8-bit output to N gray levels evenly "
        "spaced over 0..255 (level k = round(255 k / (N - 1))), each pixel to the nearest; 0 = off (all 256)",
        0, 256, check=lambda v: None if v == 0 or v >= 2 else "use 0 (off) or 2..256"),
    Key("output_levels_rgb", "vec3", list(_D.output_levels_rgb), "levels", "reduce the 8-bit output through an "
        "RGB palette of [Nr, Ng, Nb] levels per channel (e.g. [8, 8, 4]: the 256-colour 3-3-2 palette), each "
        "channel = the gray value, to its nearest level; the pixel is then the rounded BT.601 luma 0.299 R + "
        "0.587 G + 0.114 B; [0, 0, 0] = off", 0, 256,
        check=lambda v: None if all(x == 0 for x in v) or all(x == int(x) and 2 <= x <= 256 for x in v)
        else "give [0, 0, 0] (off) or three integers in 2..256"),
    Key("output_rgb_gains", "vec3", list(_D.output_rgb_gains), "", "with output_levels_rgb: each channel starts "
        "at the gray value times its gain [gR, gG, gB] (a colour cast), clipped to 0..255", 0.01, 10.0),
    Key("output_dither", "str", _D.output_dither, "", "how output_levels / output_levels_rgb quantise: none = "
        "each pixel to its nearest level; floyd_steinberg = error diffusion (raster order, weights 7/16 right, "
        "3/16 down-left, 5/16 down, 1/16 down-right; each RGB channel on its own), which keeps the local mean",
        choices=DITHERS),
    Key("output_gain", "float", _D.output_gain, "", "video level: the encoded values e (sRGB, 0..1, before the "
        "8-bit rounding) times this, before sharpening, output noise and the clip to [0, 1] (> 1: the white may "
        "clip at 255); 1 = off", 0.01, 100.0),
    Key("output_offset_dn", "float", _D.output_offset_dn, "DN (8-bit)", "video black level: added to the encoded "
        "values (in 8-bit steps) after output_gain: e -> output_gain e + output_offset_dn / 255; 0 = off",
        -255.0, 255.0),
    Key("sharpen_amount", "float", _D.sharpen_amount, "", "a video camera's sharpening (aperture correction): "
        "the encoded values e become e + amount (e - G * e), G a Gaussian of sharpen_sigma_px along sharpen_axis "
        "(after output_gain, before output_noise_dn); its ESF overshoots; 0 = off", 0.0, 100.0),
    Key("sharpen_sigma_px", "float", _D.sharpen_sigma_px, "px", "sigma of the sharpening's Gaussian", 0.05, 50.0),
    Key("sharpen_axis", "str", _D.sharpen_axis, "", "the image axis the sharpening acts along (x: along the rows, "
        "as an analog video camera's horizontal aperture correction; xy: both)", choices=SHARPEN_AXES),
    Key("output_noise_dn", "float", _D.output_noise_dn, "DN (8-bit)", "SD of Gaussian noise added to the encoded "
        "values (in 8-bit steps) after output_gain and sharpening, before the 8-bit rounding and clip: an analog "
        "video chain's noise after the camera's gamma (independent per pixel); drawn from the image's sensor "
        "generator after the exposure's numbers; 0 = off", 0.0, 255.0),
    Key("output_gamma", "float", _D.output_gamma, "", "the 8-bit outputs' transfer curve: 0 = the sRGB curve; "
        "G > 0 = a pure power, e = v^(1/G) (1: linear; decoded by the board study's --tone power:G)", 0.0, 5.0,
        check=lambda v: None if v == 0 or 0.2 <= v <= 5.0 else "use 0 (sRGB) or 0.2..5"),
    Key("output_clip_dn", "float", _D.output_clip_dn, "DN (8-bit)", "the 8-bit outputs' largest value: the encoded "
        "values are clipped to [0, output_clip_dn / 255] after the video processing and its noise, so what "
        "reaches it is flat (a camera whose white saturates below 255); 255 = off", 1.0, 255.0),
    Key("shot_noise", "bool", _D.shot_noise, "", "Poisson shot noise on the photo-electrons; false: each pixel "
        "gets its mean electrons, so that with dark_noise_e = 0 and output_noise_dn = 0 the exposure has no "
        "temporal noise (the twin's error budget, `study twin --budget`)"),
]
assert [k.name for k in SENSOR_KEYS] == [f.name for f in fields(SensorModel)]


def sensor_from_dict(d: dict, base: SensorModel | None = None, where: str = "sensor") -> SensorModel:
    """A ``SensorModel`` from a spec table (values checked against ``SENSOR_KEYS``), over ``base``."""
    return replace(base or SensorModel(), **parse_table(d, SENSOR_KEYS, where, defaults=False))


def make_rng(seed: int, stream: int) -> np.random.Generator:
    """An independent, reproducible generator per (image seed, purpose)."""
    return np.random.Generator(np.random.PCG64([int(seed), int(stream)]))


# --- fixed-pattern noise ------------------------------------------------------
@dataclass(frozen=True, eq=False)
class FixedPattern:
    """A camera's fixed pattern over one image: read-only maps, None where that part is off."""

    shape: tuple[int, int]
    gain: np.ndarray | None  # 1 + PRNU map (relative photo-response, mean 1 over the frame)
    offset_e: np.ndarray | None  # DSNU map, e- (mean 0 over the frame)
    hot: np.ndarray | None  # bool masks
    dead: np.ndarray | None
    fpn_seed: int = 0
    origin: tuple[int, int] = (0, 0)  # (x0, y0) of this image in the camera's frame

    def window(self, x0: int, y0: int, width: int, height: int) -> "FixedPattern":
        """The pattern of the (x0, y0, width, height) window of this frame."""
        h, w = self.shape
        require(0 <= x0 and 0 <= y0 and width > 0 and height > 0 and x0 + width <= w and y0 + height <= h,
                f"sensor: window {(x0, y0, width, height)} outside the {w}x{h} frame")
        cut = (slice(y0, y0 + height), slice(x0, x0 + width))
        return replace(self, shape=(int(height), int(width)), origin=(self.origin[0] + x0, self.origin[1] + y0),
                       **{k: None if getattr(self, k) is None else getattr(self, k)[cut]
                          for k in ("gain", "offset_e", "hot", "dead")})

    def electron_mean(self, mean_e: np.ndarray, hot_e: float) -> np.ndarray:
        """Poisson mean per pixel: μe · g, plus the hot pixels' dark electrons ``hot_e``."""
        lam = mean_e if self.gain is None else mean_e * self.gain
        if self.hot is not None and hot_e > 0:
            lam = lam + hot_e * self.hot
        return lam

    @property
    def defects(self) -> np.ndarray | None:
        """Hot or dead (bool mask), None without either."""
        if self.hot is None and self.dead is None:
            return None
        return (self.hot if self.hot is not None else False) | (self.dead if self.dead is not None else False)

    def truth(self, sensor: SensorModel) -> dict:
        """What the ground truth states: the pattern's values over this image and the defect positions."""
        def xy(mask):
            if mask is None:
                return []
            r, c = np.nonzero(mask)
            return [[int(a), int(b)] for a, b in zip(c, r)]

        def sd(a):
            return float(np.std(a, ddof=1)) if a is not None and a.size > 1 else 0.0

        hot, dead = xy(self.hot), xy(self.dead)
        return {"dsnu_e": sd(self.offset_e),
                "prnu_pct": 100.0 * sd(self.gain) / float(np.mean(self.gain)) if self.gain is not None else 0.0,
                "fpn_seed": self.fpn_seed,
                "origin_xy": list(self.origin),
                "hot_pixels": {"count": len(hot), "current_e_s": sensor.hot_pixel_current_e_s, "xy": hot},
                "dead_pixels": {"count": len(dead), "xy": dead},
                "model": FPN_MODEL}


FPN_MODEL = ("EMVA 1288 spatial non-uniformity, fixed per fpn_seed: e = min(Poisson(mu_e (1 + prnu z_g) + "
             "I_hot t_exp [hot]), full well); y = K (e + dsnu z_d + N(0, sigma_d^2)) + black; dead pixels read "
             "the black level. z_g, z_d: standard normal maps normalised to mean 0, SD 1 over the camera frame; "
             "dsnu_e, prnu_pct here: their SD over this image's pixels; xy: [column, row] of each defect")


def no_fixed_pattern_truth(sensor: SensorModel) -> dict:
    """The ground-truth block of a camera without fixed-pattern noise."""
    return {"dsnu_e": 0.0, "prnu_pct": 0.0, "fpn_seed": int(sensor.fpn_seed), "origin_xy": [0, 0],
            "hot_pixels": {"count": 0, "current_e_s": sensor.hot_pixel_current_e_s, "xy": []},
            "dead_pixels": {"count": 0, "xy": []}, "model": FPN_MODEL}


def _unit_map(seed: int, stream: int, shape: tuple[int, int]) -> np.ndarray:
    """A standard-normal map from [seed, stream], normalised to mean 0 and SD 1 (ddof 1) over its pixels."""
    z = make_rng(seed, stream).standard_normal(shape)
    if z.size > 1:
        z -= z.mean()
        z /= z.std(ddof=1)
    return z


def _readonly(a):
    if a is not None:
        a.setflags(write=False)
    return a


@functools.lru_cache(maxsize=4)
def _fixed_pattern(seed: int, dsnu_e: float, prnu_pct: float, hot_fraction: float, dead_fraction: float,
                   shape: tuple[int, int]) -> FixedPattern:
    """A camera's fixed pattern over a frame.  Each part has its own stream, so switching one on does
    not move another; defects: one uniform priority per pixel, the lowest ``round(hot_fraction · n)``
    are hot, the highest ``round(dead_fraction · n)`` dead (disjoint, nested in their fraction)."""
    gain = 1.0 + (prnu_pct / 100.0) * _unit_map(seed, PRNU_STREAM, shape) if prnu_pct else None
    offset = dsnu_e * _unit_map(seed, DSNU_STREAM, shape) if dsnu_e else None
    hot = dead = None
    n = shape[0] * shape[1]
    n_hot, n_dead = round(hot_fraction * n), round(dead_fraction * n)
    if n_hot or n_dead:
        priority = make_rng(seed, DEFECT_STREAM).random(n)
        if n_hot:
            hot = np.zeros(n, dtype=bool)
            hot[np.argpartition(priority, n_hot - 1)[:n_hot]] = True
            hot = hot.reshape(shape)
        if n_dead:
            dead = np.zeros(n, dtype=bool)
            dead[np.argpartition(-priority, n_dead - 1)[:n_dead]] = True
            dead = dead.reshape(shape)
    return FixedPattern(shape, _readonly(gain), _readonly(offset), _readonly(hot), _readonly(dead), seed)
