"""A defocus sweep with its plot: each method's RMSE against the exact truth as the blur grows.

Defocus widens an edge's blur. On analytic edges (exact pixel means of a blurred step, with noise) the blur
is a parameter, so a sweep fixes it at each level and draws everything else (position, angle, contrast,
noise) per image. Each level scores the methods on the same images and candidates and plots RMSE against
blur, with the Cramér–Rao bound of ERF4P-fixed11's footprint. For defocus through a real lens, render a
spec whose groups differ in distance or focus (docs/spec.md) and score it as render_scene.py does.

    python examples/sweep.py                        # 6 blur levels x 20 images -> sweep.png
    python examples/sweep.py --images 2 --levels 3  # what the tests run
"""
import argparse
from pathlib import Path

import numpy as np

from edgetruth import locate
from edgetruth.evaluate import crb, stats
from edgetruth.render.synthetic.scenarios import synthetic_image

METHODS = ("canny_devernay", "glm1984", "erf4p_fixed11", "dynamic_erf_4p", "patch_psf_fit")


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--images", type=int, default=20, help="images per blur level (default 20)")
    ap.add_argument("--levels", type=int, default=6, help="blur levels from 0.5 to 3 px (default 6)")
    ap.add_argument("-o", "--output", type=Path, default=Path("sweep.png"), help="the plot (PNG)")
    args = ap.parse_args(argv)

    blurs = np.linspace(0.5, 3.0, args.levels)
    rmse = {m: [] for m in METHODS}
    bound = []
    for blur in blurs:
        err = {m: [] for m in METHODS}
        bnd = []
        for i in range(args.images):
            s = synthetic_image("ideal", i, blur_px=float(blur), noise_rel=0.01)
            cand = locate.candidates(s.image)
            for m in METHODS:
                p = locate.refine(s.image, cand, m)
                err[m].append(s.truth.signed_distance(p.x, p.y)[p.converged])
            mask = {"f": locate.METHODS["erf4p_fixed11"].footprint_masks(cand)}
            q = s.params
            b = crb.footprint_bounds(crb.edge_geometry(s.truth, cand.x, cand.y), q["A"], q["B"], q["s_dark"],
                                     q["s_bright"], mask, noise_var=(q["noise_rel"] * q["B"]) ** 2)["f"]
            bnd.append(b)
        for m in METHODS:
            rmse[m].append(stats.rmse(np.concatenate(err[m])))
        bound.append(float(np.sqrt(np.mean(np.concatenate(bnd) ** 2))))
        print(f"blur {blur:.2f} px: " + ", ".join(f"{locate.METHODS[m].label} {rmse[m][-1]:.4f}" for m in METHODS)
              + f"; bound {bound[-1]:.4f} px")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 3.6))
    for m in METHODS:
        ax.plot(blurs, rmse[m], marker="o", ms=3, label=locate.METHODS[m].label)
    ax.plot(blurs, bound, "k--", label="Cramér–Rao bound (ERF4P-fixed11's pixels)")
    ax.set_xlabel("blur σ (px)")
    ax.set_ylabel("RMSE (px)")
    ax.set_yscale("log")
    ax.set_title(f"Ideal edges, noise 1 % of contrast, {args.images} images per level")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(args.output, dpi=100)
    print(f"plot: {args.output}")
    return {"blur_px": blurs.tolist(), "rmse_px": rmse, "bound_px": bound}


if __name__ == "__main__":
    main()
