"""Print raggedness (evaluate/board/twin/raggedness.py): the detrend, the floor, and a ragged edge of known size."""
import math

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter1d
from scipy.special import ndtr

from edgetruth import locate
from edgetruth.evaluate.board.sides.lines import CANDIDATE_MARGIN_PX, near_sides, side_fits, square_map
from edgetruth.evaluate.board.twin import raggedness as rg

DARK, WHITE, SIGMA_PX = 40.0, 200.0, 1.0


def _square(angle=0.12, centre=(100.3, 99.6), half=55.0):
    c, s = math.cos(angle), math.sin(angle)
    local = np.array([[-half, -half], [half, -half], [half, half], [-half, half]])
    return local @ np.array([[c, s], [-s, c]]) + np.asarray(centre)  # clockwise on screen


def _wander(rng, n, sd_px, corr_px, step):
    w = gaussian_filter1d(rng.standard_normal(n), corr_px / step, mode="wrap")
    return sd_px * (w - w.mean()) / w.std()


def _image(quad, ragged_sd_px, noise_sd, seed, corr_px=4.0, size=200):
    """A dark square (its corners ``quad``) on white, each side displaced outward by a smooth random function of
    the position along it (SD ``ragged_sd_px``, correlation ``corr_px``), blurred by an ERF of SIGMA_PX across
    it, with Gaussian noise."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:size, 0:size].astype(float)
    inside = np.ones_like(xx)
    step = 0.25
    for k in range(4):
        a, b = quad[k], quad[(k + 1) % 4]
        u = (b - a) / np.linalg.norm(b - a)
        n = np.array([u[1], -u[0]])  # outward for a clockwise-on-screen quad
        t = (xx - a[0]) * u[0] + (yy - a[1]) * u[1]
        grid = np.arange(-20.0, np.linalg.norm(b - a) + 20.0, step)
        rho = np.interp(t, grid, _wander(rng, len(grid), ragged_sd_px, corr_px, step)) if ragged_sd_px else 0.0
        dist = (xx - a[0]) * n[0] + (yy - a[1]) * n[1] - rho
        inside *= ndtr(-dist / SIGMA_PX)
    img = WHITE - (WHITE - DARK) * inside
    return np.clip(np.round(img + noise_sd * rng.standard_normal(img.shape)), 0, 255)


def _sd(img, quad, method="canny_devernay"):
    quads = quad[None]
    cand = locate.candidates(img)
    cand = cand.subset(near_sides(quads, cand.x, cand.y, CANDIDATE_MARGIN_PX))
    pts = locate.refine(img, cand, method)
    f = side_fits(quads, square_map(quads, img.shape), pts.x, pts.y, pts.nx, pts.ny, pts.converged)
    return rg.pooled([rg.side_stats(pts.x, pts.y, f.labels, f.normal, f.offset)])


def test_the_detrend_takes_a_bow_and_leaves_the_wander():
    t = np.linspace(0, 100, 201)
    normal, offset = np.array([[[0.0, 1.0]] * 4]), np.zeros((1, 4))
    bow = 1e-4 * (t - 50) ** 2 + 0.01 * t  # a lens's or a sheet's bow over one side: degree 2
    st = rg.side_stats(t, bow, np.zeros(len(t), int), normal, offset)
    assert st["ss"][0, 0] < 1e-20 and st["n"][0, 0] == 201 and st["dof"][0, 0] == 198
    wig = 0.05 * np.sin(2 * np.pi * t / 10)  # 10 px wavelength, SD 0.05 / sqrt 2
    st = rg.side_stats(t, bow + wig, np.zeros(len(t), int), normal, offset)
    assert math.sqrt(st["ss"][0, 0] / st["dof"][0, 0]) == pytest.approx(0.05 / math.sqrt(2), rel=0.03)
    assert st["lag1"][0, 0] > 0.7  # correlated over several points
    assert np.isnan(st["ss"][0, 1])  # a side with no points


def test_excess_and_the_noise_map():
    assert rg.excess(0.05, 0.03) == pytest.approx(0.04)
    assert rg.excess(0.02, 0.03) == 0.0
    sd = rg.noise_sd_map(np.array([40.0, 120.0, 200.0]), 40.0, 200.0, 1.0, 3.0)
    assert sd[0] == pytest.approx(1.0) and sd[2] == pytest.approx(3.0) and sd[1] == pytest.approx(math.sqrt(5.0))


@pytest.mark.parametrize("method", ["canny_devernay", "patch_psf_fit"])
def test_a_ragged_edge_of_known_size_is_recovered_above_the_noise_floor(method):
    """A square whose sides wander by 0.06 px (correlation 4 px) under noise of SD 2 DN at a contrast of 160: its
    excess over the same square with straight sides and other noise is the wander, within 15 % (measured −6 % and
    −5 %); with straight sides the excess is within 0.015 px of none (measured 0.003 and 0)."""
    quad = _square()
    floor = _sd(_image(quad, 0.0, 2.0, seed=1), quad, method)
    ragged = _sd(_image(quad, 0.06, 2.0, seed=2), quad, method)
    straight = _sd(_image(quad, 0.0, 2.0, seed=3), quad, method)
    assert floor["sides"] == ragged["sides"] == 4
    assert rg.excess(ragged["sd_px"], floor["sd_px"]) == pytest.approx(0.06, rel=0.15)
    assert rg.excess(straight["sd_px"], floor["sd_px"]) < 0.015
    assert ragged["lag1"] > floor["lag1"] + 0.1  # the print's wander is correlated along the side, noise less so
