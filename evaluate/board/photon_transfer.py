"""A raw sensor's gain, read noise and black level from its photos' noise (EMVA 1288's photon transfer).

Below saturation a linear sensor's values y = K (e + N(0, σd²)) + b (``render.sensor.linear_model``: K DN/e⁻, e the
Poisson photo-electrons, σd the read noise in e⁻, b the black level) have

    Var(y) - q²/12 = K² σd² - K b + K · E[y]                (q the stored step: 1, or 16 for 12-bit data << 4)

a line in the mean whose slope is K and whose intercept a = K² σd² - K b holds σd and b together.  A chessboard
photo gives two points (its dark and light squares' levels and SDs at their centres, ``levels.square_levels``);
a set of photos at several exposures gives more.  ``sensor_from_noise`` fits the line (least squares, each point
weighted by 1 / its variance, whose sampling error grows with it) and splits the intercept with one of σd and b
given: the black level from an assumed read noise, or the read noise from a given black level.

What the squares' SD also holds and the line does not model: the print's texture and the sensor's PRNU (both grow
as the level, not its square root), Monte-Carlo noise in a render.  They steepen the line a little; the twin
study's Table 3 compares the twin's noise with the photos'.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from edgetruth.errors import InputError


@dataclass(frozen=True)
class RawNoise:
    """What the photos' noise says about their sensor (``sensor_from_noise``)."""

    #: the gain K (DN per electron): the photon-transfer line's slope
    k_dn_per_e: float
    #: the line's intercept a = K² σd² - K b (DN²)
    intercept_dn2: float
    read_noise_e: float
    black_dn: float
    #: how ``read_noise_e`` and ``black_dn`` were found, in words (for a twin's header)
    read_why: str
    black_why: str
    points: int


def photon_transfer(levels_dn, sds_dn, step_dn: float = 1.0) -> tuple[float, float]:
    """(slope K, intercept a) of Var - step²/12 = a + K · level over the points, each weighted by 1 / its variance
    (a sample variance's SD is proportional to it)."""
    x = np.asarray(levels_dn, float)
    v = np.asarray(sds_dn, float) ** 2
    ok = np.isfinite(x) & np.isfinite(v) & (v > 0)
    x, v = x[ok], v[ok]
    if len(x) < 2 or np.ptp(x) <= 0:
        raise InputError(f"{len(x)} noise level(s): the photon transfer needs two distinct levels (dark and light "
                         "squares) with noise")
    w = 1.0 / v
    A = np.c_[np.ones_like(x), x] * np.sqrt(w)[:, None]
    (a, k), *_ = np.linalg.lstsq(A, (v - step_dn ** 2 / 12.0) * np.sqrt(w), rcond=None)
    return float(k), float(a)


def sensor_from_noise(levels_dn, sds_dn, step_dn: float = 1.0, read_noise_e: float | None = None,
                      black_dn: float | None = None, assumed_read_noise_e: float = 15.0,
                      lowest_level_dn: float | None = None) -> RawNoise:
    """The gain from the photon-transfer line, and read noise and black level from its intercept (module
    docstring): both given, each as given; the black level given, the read noise from it (0 where the line leaves
    none); otherwise the black level from the read noise (``read_noise_e``, else ``assumed_read_noise_e``), at 0
    where the line puts it below 0.  ``lowest_level_dn``: the darkest level measured, which the black level must
    stay below.  An ``InputError`` when the noise does not grow with the level (values that are not a linear
    sensor's) or puts the black level at or above the darkest level."""
    k, a = photon_transfer(levels_dn, sds_dn, step_dn)
    n = int(np.sum(np.isfinite(np.asarray(levels_dn, float))))
    if not k > 0:
        raise InputError(f"the photos' noise does not grow with their level (photon-transfer slope {k:.3g} DN/e-): "
                         "not a linear sensor's values; give the camera's raw (linear) output")
    if black_dn is not None:
        black, black_why = float(black_dn), "given"
        if read_noise_e is not None:
            read, read_why = float(read_noise_e), "given"
        else:
            var_e = (a + k * black) / k ** 2
            read = math.sqrt(max(var_e, 0.0))
            read_why = ("from the photos' noise at that black level" if var_e > 0 else
                        "0: the photos' noise at that black level leaves none")
    else:
        read = float(read_noise_e) if read_noise_e is not None else float(assumed_read_noise_e)
        read_why = "given" if read_noise_e is not None else "assumed"
        black = (k ** 2 * read ** 2 - a) / k
        black_why = f"from the photos' noise with that read noise ({n} levels)"
        if black < 0:
            black, black_why = 0.0, f"0: the photos' noise with that read noise puts it at {black:.1f} DN"
    if lowest_level_dn is not None and black >= lowest_level_dn:
        raise InputError(f"black level {black:.1f} DN: at or above the photos' darkest level "
                         f"({lowest_level_dn:.1f} DN); give --black-dn (the camera's black level)")
    return RawNoise(k, a, read, black, read_why, black_why, n)
