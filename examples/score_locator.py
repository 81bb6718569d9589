"""Score your own locator against the exact truth and the Cramér–Rao bound.

A locator is a function of the image and the shared Canny candidates that returns one point per candidate.
This one fits a parabola to the gradient magnitude at three samples along each candidate's normal (the
classic subpixel peak). Registered by name, it runs wherever the built-in methods do; here it is scored
on analytic edges, whose exact truth is the signed distance to the true edge, beside two built-ins, and
against each point's Cramér–Rao bound: the least RMSE any unbiased estimator could reach from the pixels
the method reads (its footprint; a method that declares none is bounded over the whole neighbourhood,
which can only lower the bound), under the edge's true blur, levels and noise.

    python examples/score_locator.py            # 40 images
    python examples/score_locator.py --images 4 # what the tests run
"""
import argparse

import numpy as np

from edgetruth import locate
from edgetruth.evaluate import crb, stats
from edgetruth.locate.profiles import sample_profiles
from edgetruth.render.synthetic.scenarios import synthetic_image


@locate.register("my_parabola", label="MyParabola")
def my_parabola(image, cand):
    """Gradient-magnitude parabola through the samples at t = -1, 0, +1 px along the normal."""
    prof = sample_profiles(image, cand, half=2)            # (N, 5) intensities at t = -2..2 px
    g = np.gradient(prof, axis=1)[:, 1:4]                  # the derivative at t = -1, 0, 1
    den = g[:, 0] - 2 * g[:, 1] + g[:, 2]
    ok = den < 0                                           # a maximum, not a minimum
    offset = np.where(ok, 0.5 * (g[:, 0] - g[:, 2]) / np.where(ok, den, -1.0), 0.0)
    ok &= np.abs(offset) <= 1.0
    return locate.Refinement.from_offset(cand, np.where(ok, offset, 0.0), converged=ok)


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--images", type=int, default=40, help="analytic Ideal edges to score (default 40)")
    args = ap.parse_args(argv)

    methods = ["canny_pixel", "my_parabola", "erf4p_fixed11"]
    errors = {m: [] for m in methods}
    bounds = {m: [] for m in methods}
    for i in range(args.images):
        s = synthetic_image("ideal", i)                    # random blur, levels, noise; exact truth
        cand = locate.candidates(s.image)
        p_ = s.params
        geometry = crb.edge_geometry(s.truth, cand.x, cand.y)
        masks = {m: locate.METHODS[m].footprint_masks(cand) for m in methods}
        b = crb.footprint_bounds(geometry, p_["A"], p_["B"], p_["s_dark"], p_["s_bright"], masks,
                                 noise_var=(p_["noise_rel"] * p_["B"]) ** 2)
        for m in methods:
            p = locate.refine(s.image, cand, m)
            e = s.truth.signed_distance(p.x, p.y)          # px along the true normal, exact
            errors[m].append(e[p.converged])
            bounds[m].append(b[m][p.converged])
    print(f"{args.images} Ideal edges (blur, contrast and noise drawn per image)")
    print(f"{'method':<16}{'points':>8}{'RMSE px':>10}{'bias px':>10}{'bound px':>10}{'RMSE/bound':>12}")
    out = {}
    for m in methods:
        e, bnd = np.concatenate(errors[m]), np.concatenate(bounds[m])
        r, rb = stats.rmse(e), float(np.sqrt(np.mean(bnd ** 2)))
        out[m] = {"rmse_px": r, "bound_px": rb}
        print(f"{locate.METHODS[m].label:<16}{e.size:>8}{r:>10.4f}{e.mean():>10.4f}{rb:>10.4f}{r / rb:>12.2f}")
    return out


if __name__ == "__main__":
    main()
