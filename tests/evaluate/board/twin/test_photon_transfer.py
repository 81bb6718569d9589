"""A raw sensor's gain, read noise and black level from its noise (``photon_transfer``): on simulated EMVA 1288
values (Poisson electrons, Gaussian read noise, a black level, rounding) of known K, σd and b."""
from __future__ import annotations

import re

import numpy as np
import pytest

from edgetruth.errors import InputError
from edgetruth.evaluate.board.twin.photon_transfer import photon_transfer, sensor_from_noise

K, READ_E, BLACK = 0.5, 12.0, 200.0
ELECTRONS = (600.0, 1500.0, 3000.0, 6000.0)
N = 200_000  # values per level: the variances' relative SE sqrt(2 / N) = 0.3 %


def levels_and_sds(step: int = 1, seed: int = 0, black: float = BLACK):
    """(mean, SD) at each electron level of y = K (Poisson(e) + N(0, σd²)) + b, rounded to ``step`` DN."""
    rng = np.random.default_rng(seed)
    out = []
    for e in ELECTRONS:
        y = K * (rng.poisson(e, N) + rng.normal(0.0, READ_E, N)) + black
        y = step * np.round(y / step)
        out.append((y.mean(), y.std(ddof=1)))
    return np.array(out).T


def test_the_line_is_the_gain_and_the_intercept():
    """Slope K to 1 % and intercept K² σd² - K b (= 36 - 100 DN²) to 3 DN²: the line's SEs at N values per level
    are 0.3 % and ~1 DN²."""
    x, sd = levels_and_sds()
    k, a = photon_transfer(x, sd)
    assert k == pytest.approx(K, rel=0.01)
    assert a == pytest.approx(K ** 2 * READ_E ** 2 - K * BLACK, abs=3.0)


def test_a_coarse_step_is_taken_off():
    """Values stored in steps of 16 DN (12-bit data shifted by 4) add 16²/12 = 21 DN² to every variance: the line's
    intercept is the same as at step 1 once it is taken off (within 4 DN²), and 21 DN² higher when it is not."""
    x, sd = levels_and_sds(step=16)
    _, a16 = photon_transfer(x, sd, 16.0)
    _, a_naive = photon_transfer(x, sd, 1.0)
    assert a16 == pytest.approx(K ** 2 * READ_E ** 2 - K * BLACK, abs=4.0)
    assert a_naive - a16 == pytest.approx(256.0 / 12.0 - 1.0 / 12.0, abs=1e-6)


def test_the_black_level_from_the_read_noise_and_back():
    """With the true read noise the black level comes back to 8 DN (its SE ~2 DN: the intercept's / K); with the
    true black level the read noise to 0.5 e-; both given, both as given."""
    x, sd = levels_and_sds()
    r = sensor_from_noise(x, sd, read_noise_e=READ_E)
    assert r.black_dn == pytest.approx(BLACK, abs=8.0) and r.read_why == "given" and r.points == 4
    r = sensor_from_noise(x, sd, black_dn=BLACK)
    assert r.read_noise_e == pytest.approx(READ_E, abs=0.5) and r.black_why == "given"
    r = sensor_from_noise(x, sd, read_noise_e=3.0, black_dn=50.0)
    assert (r.read_noise_e, r.black_dn) == (3.0, 50.0)
    # black-subtracted values (b = 0) with an assumed read noise below the true one: the line puts b at
    # K (5² - 12²) = -60 DN; it is 0, and the words say where the line put it
    r = sensor_from_noise(*levels_and_sds(black=0.0), assumed_read_noise_e=5.0)
    assert r.black_dn == 0.0 and r.black_why.startswith("0: ") and r.read_why == "assumed"
    assert float(re.search(r"puts it at (\S+) DN", r.black_why).group(1)) == pytest.approx(-60.0, abs=8.0)


def test_values_that_are_not_a_linear_sensors_are_refused():
    """Noise that does not grow with the level (an 8-bit tone curve, a denoiser), and a black level at or above the
    darkest level measured: one InputError each, naming the fix."""
    with pytest.raises(InputError, match="not a linear sensor's values"):
        sensor_from_noise([100.0, 1000.0, 3000.0], [20.0, 15.0, 10.0])
    x, sd = levels_and_sds()
    with pytest.raises(InputError, match="give --black-dn"):
        sensor_from_noise(x, sd, black_dn=float(x[0]), lowest_level_dn=float(x[0]))
    with pytest.raises(InputError, match="two distinct levels"):
        photon_transfer([500.0, 500.0], [10.0, 10.0])


def levels_with_prnu(prnu: float, electrons=(600.0, 1000.0, 2000.0, 3000.0, 4000.0, 5000.0, 7000.0), seed: int = 0):
    """(mean, SD) over N pixels at each electron level, each pixel's photo-electrons scaled by its own gain 1 + prnu z
    (the renderer's PRNU): a single frame's spatial SD."""
    rng = np.random.default_rng(seed)
    out = []
    for e in electrons:
        g = 1.0 + prnu * rng.standard_normal(N)
        y = np.round(K * (rng.poisson(e * g) + rng.normal(0.0, READ_E, N)) + BLACK)
        out.append((y.mean(), y.std(ddof=1)))
    return np.array(out).T


def test_prnu_is_fitted_from_enough_levels_and_the_line_alone_is_biased():
    """PRNU of 1 % over 7 levels (600-7,000 e-): the fit with the PRNU term finds K to 3 %, p to 0.05 % points and
    the black level to 15 DN (with the true read noise; measured 0.4983, 1.004 %, 199.1); the line alone reads K
    40 % high or more (measured 0.8007, +60 %).  From 4 levels
    (two exposures) the term is not fitted, and the words say why."""
    from edgetruth.evaluate.board.twin.photon_transfer import MIN_PRNU_LEVELS

    x, sd = levels_with_prnu(0.01)
    r = sensor_from_noise(x, sd, read_noise_e=READ_E)
    print(f"K {r.k_dn_per_e:.4f}, p {100 * r.prnu:.3f} %, black {r.black_dn:.1f}; line alone K "
          f"{photon_transfer(x, sd)[0]:.4f}")
    assert r.k_dn_per_e == pytest.approx(K, rel=0.03) and r.prnu == pytest.approx(0.01, abs=5e-4)
    assert r.black_dn == pytest.approx(BLACK, abs=15.0) and r.prnu_why.startswith("from 7 distinct")
    assert photon_transfer(x, sd)[0] > 1.4 * K
    four = sensor_from_noise(*levels_and_sds(), read_noise_e=READ_E)
    assert four.prnu == 0.0 and four.prnu_why.startswith("not fitted: 4 distinct") and MIN_PRNU_LEVELS > 4
    # no PRNU in the values: the term stays small (measured 0.10 %) and K within 2 % (measured 0.3 %)
    r0 = sensor_from_noise(*levels_with_prnu(0.0), read_noise_e=READ_E)
    assert r0.prnu < 0.002 and r0.k_dn_per_e == pytest.approx(K, rel=0.02)


def test_a_large_read_noise_comes_back_from_a_given_black_level():
    """A read noise of 60 e- (3,600 e-², more than the darkest level in DN) comes back from the true black level
    to 2 e-: the fit's bound on σd² is not the levels' range."""
    rng = np.random.default_rng(5)
    out = []
    for e in ELECTRONS:
        y = np.round(K * (rng.poisson(e, N) + rng.normal(0.0, 60.0, N)) + BLACK)
        out.append((y.mean(), y.std(ddof=1)))
    x, sd = np.array(out).T
    r = sensor_from_noise(x, sd, black_dn=BLACK)
    assert r.read_noise_e == pytest.approx(60.0, abs=2.0) and x.min() < 3600
