"""One-thread processes run the serial copies of the strict parallel kernels (``edgetruth.jit``): every
method gives the same bits on one numba thread (serial copies) as on several (parallel kernels), and the
kernels that reach fastmath code have no serial copy."""
import numpy as np
import pytest

from edgetruth import jit, locate
from edgetruth.evaluate import bound_psf as BP
from edgetruth.render.edge_truth import CircleEdge
from tests.support.edge_scenes import near_candidates

OPTICS = BP.Optics(cutoff_cy_px=4.8 / (0.55 * 4.0), sigma_x_px=0.35, sigma_y_px=0.35, defocus_px=0.8, olpf_px=0.3)
EDGE = CircleEdge(40.3, 38.8, 21.0, False)


def _image(spread):
    from edgetruth.evaluate import crb

    yy, xx = np.mgrid[0:80, 0:80].astype(float)
    m = BP.means_and_derivatives(spread, crb.edge_geometry(EDGE, xx.ravel(), yy.ravel()), np.zeros((1, 2)))[0][:, 0]
    rng = np.random.default_rng(5)
    return 40.0 + 120.0 * m.reshape(80, 80) + rng.normal(0.0, 1.5, (80, 80))


def _all_methods(img, cand, tab):
    out = {}
    for m in locate.METHODS:
        pts = locate.refine(img, cand, m, **({"esf": tab} if m == "patch_esf_fit" else {}))
        out[m] = np.concatenate([np.ravel(pts.x), np.ravel(pts.y)]).view(np.int64)
    return out


def test_one_thread_gives_the_parallel_kernels_bits():
    numba = pytest.importorskip("numba")
    from edgetruth.backends import numba_threads

    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba runs on one thread here: no parallel kernel to compare with")
    spread = BP.EdgeSpread(OPTICS, 1.0, 1 << 12)
    img = _image(spread)
    cand = near_candidates(img, EDGE)
    tab = spread.tables()
    with numba_threads(2):
        parallel = _all_methods(img, cand, tab)
    with numba_threads(1):
        serial = _all_methods(img, cand, tab)
    for m in locate.METHODS:
        assert np.array_equal(parallel[m], serial[m]), m
    from edgetruth.locate import curve_fit_kernels, erf_kernels
    from edgetruth.locate.methods import patch_esf_fit, patch_psf_fit

    # both copies ran: the serial one on one thread, the parallel one on two
    assert erf_kernels.refine_erf.serial.signatures and erf_kernels.refine_erf.dispatcher.signatures
    assert [k for k in vars(patch_esf_fit).values() if isinstance(k, jit.LazyKernel) and k.serial is not None]
    # fastmath reached: always parallel, and the module global is numba's dispatcher
    assert not isinstance(curve_fit_kernels._refine_kernel, jit.LazyKernel)
    assert not isinstance(patch_psf_fit.fit_patches, jit.LazyKernel)
