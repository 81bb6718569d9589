"""Property tests: every locate method, on random images with and without edges, never crashes,
and every output point is finite and inside the image."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from edgetruth import locate

# the methods that run on any image (patch_esf_fit needs a camera's tables: tests/locate/test_patch_esf_fit.py)
METHOD_IDS = sorted(m for m, r in locate.METHODS.items() if r.builtin and not r.needs_camera)
SETTINGS = settings(max_examples=25, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


@st.composite
def images(draw):
    """Random gray images: noise only, or a straight/circular edge with random blur, contrast,
    noise, dtype and size (including tiny and flat ones)."""
    h = draw(st.integers(3, 48))
    w = draw(st.integers(3, 48))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    kind = draw(st.sampled_from(["flat", "noise", "line", "circle", "steps"]))
    yy, xx = np.mgrid[0:h, 0:w].astype(float)
    lo = draw(st.floats(0, 200))
    contrast = draw(st.floats(-255, 255))
    if kind == "flat":
        img = np.full((h, w), lo)
    elif kind == "noise":
        img = lo + rng.normal(0, draw(st.floats(0, 80)), (h, w))
    else:
        if kind == "line":
            th = draw(st.floats(0, 2 * np.pi))
            d = np.cos(th) * (xx - w / 2 - rng.uniform(-2, 2)) + np.sin(th) * (yy - h / 2 - rng.uniform(-2, 2))
        elif kind == "circle":
            d = np.hypot(xx - rng.uniform(0, w), yy - rng.uniform(0, h)) - rng.uniform(1, max(h, w))
        else:
            d = np.sin(xx * rng.uniform(0.2, 2)) * 3 + (yy - h / 2)
        s = draw(st.floats(0.05, 4))
        from scipy.special import ndtr

        img = lo + contrast * ndtr(d / s) + rng.normal(0, draw(st.floats(0, 20)), (h, w))
    dtype = draw(st.sampled_from(["float64", "float32", "uint8", "uint16"]))
    if dtype == "uint8":
        img = np.clip(np.round(img), 0, 255).astype(np.uint8)
    elif dtype == "uint16":
        img = np.clip(np.round(img * 100), 0, 65535).astype(np.uint16)
    else:
        img = img.astype(dtype)
    return img


@pytest.mark.parametrize("method", METHOD_IDS)
def test_every_point_finite_and_inside(method):
    @SETTINGS
    @given(img=images(), sigma=st.sampled_from([0.7, 1.0, 2.0]))
    def check(img, sigma):
        pts = locate.locate(img, method, sigma_px=sigma)
        h, w = img.shape
        n = len(pts)
        for a in (pts.x, pts.y, pts.nx, pts.ny):
            assert a.shape == (n,) and np.all(np.isfinite(a))
        assert np.all((pts.x >= 0) & (pts.x <= w - 1) & (pts.y >= 0) & (pts.y <= h - 1))
        assert pts.converged.shape == (n,) and pts.converged.dtype == bool

    check()


def test_twenty_two_builtin_methods():
    """The study's ten baselines, its ERF family (8 fixed windows, dynamic 2P and 4P) and edgetruth's own two:
    patch_psf_fit (any image) and patch_esf_fit (needs the camera's model)."""
    assert len(METHOD_IDS) == 21 and "patch_psf_fit" in METHOD_IDS
    builtin = {m for m, r in locate.METHODS.items() if r.builtin}
    assert builtin - set(METHOD_IDS) == {"patch_esf_fit"} and locate.METHODS["patch_esf_fit"].needs_camera
