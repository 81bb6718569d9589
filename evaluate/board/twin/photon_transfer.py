"""A raw sensor's gain, read noise and black level from its photos' noise (EMVA 1288's photon transfer).

Below saturation a linear sensor's values y = K (e + N(0, σd²)) + b (``render.sensor.linear_model``: K DN/e⁻, e the
Poisson photo-electrons, σd the read noise in e⁻, b the black level) have

    Var(y) - q²/12 = K² σd² - K b + K · E[y]                (q the stored step: 1, or 16 for 12-bit data << 4)

a line in the mean whose slope is K and whose intercept a = K² σd² - K b holds σd and b together.  A chessboard
photo gives two points (its dark and light squares' levels and SDs, ``levels.square_levels``); a set of photos at
several exposures gives more.  ``photon_transfer`` fits the line (least squares, each point weighted by 1 / its
variance, whose sampling error grows with it).

A single frame's spatial SD also holds what grows as the level itself: the sensor's PRNU and the print's texture,
(p (y - b))² with p their relative SD (EMVA 1288's PRNU, the renderer's ``prnu_pct`` / 100).  Ignored, it steepens
the line: at 1 % it read K 60 % high on simulated values of 600-7,000 e- (``test_photon_transfer``).  With levels
from three exposures or more (``MIN_PRNU_LEVELS`` distinct levels) ``sensor_from_noise`` fits

    Var(y) - q²/12 = K² σd² + K (y - b) + p² (y - b)²

(``scipy.optimize.least_squares``, relative residuals) with one of σd and b given: the black level from an assumed
read noise, or the read noise from a given black level; from fewer levels, the line (p = 0).  The twin renders p as
its sensor's PRNU: a single photo cannot tell the print's texture from the sensor's, and both look alike in it.
What else the squares' SD holds: Monte-Carlo noise in a render (in the darks, where it raises the intercept).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from edgetruth.errors import InputError


#: distinct levels (more than ``LEVEL_GAP`` apart, relatively) the PRNU term needs: a dark and a light square
#: at two exposures are not enough to tell K, b and p apart
MIN_PRNU_LEVELS, LEVEL_GAP = 5, 0.05
#: the largest PRNU the fit may find (the renderer's ``PRNU_MAX_PCT`` / 100)
MAX_PRNU = 0.10


@dataclass(frozen=True)
class RawNoise:
    """What the photos' noise says about their sensor (``sensor_from_noise``)."""

    #: the gain K (DN per electron): the photon-transfer line's slope
    k_dn_per_e: float
    #: the line's intercept a = K² σd² - K b (DN²)
    intercept_dn2: float
    read_noise_e: float
    black_dn: float
    #: the relative SD that grows as the level (PRNU and the print's texture); 0 when not fitted
    prnu: float
    #: how ``read_noise_e`` and ``black_dn`` were found, in words (for a twin's header)
    read_why: str
    black_why: str
    prnu_why: str
    points: int


def noise_points(levels_dn, sds_dn) -> tuple[np.ndarray, np.ndarray]:
    """(levels, variances) of the points with a finite level and a finite SD above 0."""
    x = np.asarray(levels_dn, float)
    v = np.asarray(sds_dn, float) ** 2
    ok = np.isfinite(x) & np.isfinite(v) & (v > 0)
    return x[ok], v[ok]


def photon_transfer(levels_dn, sds_dn, step_dn: float = 1.0) -> tuple[float, float]:
    """(slope K, intercept a) of Var - step²/12 = a + K · level over the points, each weighted by 1 / its variance
    (a sample variance's SD is proportional to it)."""
    x, v = noise_points(levels_dn, sds_dn)
    if len(x) < 2 or np.ptp(x) <= 0:
        raise InputError(f"{len(x)} noise level(s): the photon transfer needs two distinct levels (dark and light "
                         "squares) with noise")
    w = 1.0 / v
    A = np.c_[np.ones_like(x), x] * np.sqrt(w)[:, None]
    (a, k), *_ = np.linalg.lstsq(A, (v - step_dn ** 2 / 12.0) * np.sqrt(w), rcond=None)
    return float(k), float(a)


def distinct_levels(levels_dn) -> int:
    """How many of ``levels_dn`` differ from every smaller one by more than ``LEVEL_GAP`` of it."""
    x = np.sort(np.asarray(levels_dn, float)[np.isfinite(levels_dn)])
    return int(len(x) and 1 + np.sum(np.diff(x) > LEVEL_GAP * x[1:]))


def sensor_from_noise(levels_dn, sds_dn, step_dn: float = 1.0, read_noise_e: float | None = None,
                      black_dn: float | None = None, assumed_read_noise_e: float = 15.0,
                      lowest_level_dn: float | None = None) -> RawNoise:
    """Gain, read noise, black level and PRNU from the photos' noise (module docstring): read noise and black level
    both given, each as given; the black level given, the read noise from the noise (0 where it leaves none);
    otherwise the black level from the read noise (``read_noise_e``, else ``assumed_read_noise_e``), 0 where the
    noise puts it below 0.  The PRNU term only from ``MIN_PRNU_LEVELS`` distinct levels or more.
    ``lowest_level_dn``: the darkest level measured, which the black level must stay below.  An ``InputError``
    when the noise does not grow with the level (values that are not a linear sensor's) or puts the black level at
    or above the darkest level."""
    k0, a0 = photon_transfer(levels_dn, sds_dn, step_dn)
    x, v = noise_points(levels_dn, sds_dn)
    v = v - step_dn ** 2 / 12.0
    n, levels = int(len(x)), distinct_levels(x)
    if not k0 > 0:
        raise InputError(f"the photos' noise does not grow with their level (photon-transfer slope {k0:.3g} DN/e-): "
                         "not a linear sensor's values; give the camera's raw (linear) output")
    with_prnu = levels >= MIN_PRNU_LEVELS
    top = float(x.min()) if lowest_level_dn is None else min(float(x.min()), float(lowest_level_dn))
    read = float(read_noise_e) if read_noise_e is not None else float(assumed_read_noise_e)

    def fit(free_black: bool, black: float, free_read: bool):
        """least_squares over (K, b or σd², p) as free; -> (K, b, σd, p)."""
        start = [k0, (k0 ** 2 * read ** 2 - a0) / k0 if free_black else max((a0 + k0 * black) / k0 ** 2, 0.0), 0.0]
        # the second parameter: the black level (DN, below the darkest level) or the read noise's variance (e-²)
        lo, hi = [1e-9, -1e6 if free_black else 0.0, 0.0], [1e6, top if free_black else 1e8,
                                                           MAX_PRNU if with_prnu else 1e-12]
        if not (free_black or free_read):
            lo[1], hi[1], start[1] = 0.0, 1e-12, 0.0

        def model(q):
            k, second, p = q
            b, s2 = (second, read ** 2) if free_black else (black, second if free_read else read ** 2)
            return k * k * s2 + k * (x - b) + (p * (x - b)) ** 2

        start = np.clip(start, lo, [h - 1e-9 if h > 1e-9 else h for h in hi])
        q = least_squares(lambda q: (model(q) - v) / v, start, bounds=(lo, hi)).x
        b, s2 = (q[1], read ** 2) if free_black else (black, q[1] if free_read else read ** 2)
        return float(q[0]), float(b), math.sqrt(max(s2, 0.0)), float(q[2]) if with_prnu else 0.0

    if black_dn is not None:
        black, black_why = float(black_dn), "given"
        k, _, sd, p = fit(False, black, read_noise_e is None)
        if read_noise_e is not None:
            read_why = "given"
        else:
            read = sd
            read_why = "from the photos' noise at that black level" if sd > 0 else \
                "0: the photos' noise at that black level leaves none"
    else:
        read_why = "given" if read_noise_e is not None else "assumed"
        k, black, _, p = fit(True, 0.0, False)
        black_why = f"from the photos' noise with that read noise ({n} levels)"
        if black < 0:
            black_why = f"0: the photos' noise with that read noise puts it at {black:.1f} DN"
            black = 0.0
            k, _, _, p = fit(False, 0.0, False)
    if lowest_level_dn is not None and black >= lowest_level_dn:
        raise InputError(f"black level {black:.1f} DN: at or above the photos' darkest level "
                         f"({lowest_level_dn:.1f} DN); give --black-dn (the camera's black level)")
    prnu_why = (f"from {levels} distinct levels" if with_prnu else
                f"not fitted: {levels} distinct level(s), {MIN_PRNU_LEVELS} needed (photos at three exposures or more)")
    return RawNoise(k, a0, read, black, p, read_why, black_why, prnu_why, n)
