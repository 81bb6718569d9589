"""ERF edge positions of a rendered board's square sides, against their exact distorted outline."""
from __future__ import annotations

import numpy as np

from edgetruth.render.scene.outline import OutlineCurve


def side_offsets(img: np.ndarray, camera, pose, quads: np.ndarray, bend=None) -> np.ndarray:
    """Per square side: the ERF edge position, fitted on the pixels within 3.5 px of the side's middle
    60 % as a function of their signed distance to the exact distorted outline (of a board curled by
    ``bend``, ``render.scene.bend``; None: flat), minus 0 (the outline)."""
    from scipy.optimize import least_squares
    from scipy.special import ndtr

    out = []
    for q in quads:
        curve = OutlineCurve.polygon(camera, pose, q, bend=bend)
        for k in range(4):
            side = curve.points((k + np.linspace(0.2, 0.8, 120)) / 4)
            lo = np.floor(side.min(0) - 4).astype(int)
            hi = np.ceil(side.max(0) + 4).astype(int)
            ys, xs = (a.ravel() for a in np.mgrid[lo[1]:hi[1] + 1, lo[0]:hi[0] + 1])
            dist = np.hypot(xs[:, None] - side[None, :, 0], ys[:, None] - side[None, :, 1])
            j = dist.argmin(1)
            keep = (j > 1) & (j < len(side) - 2) & (dist.min(1) <= 3.5)
            xs, ys = xs[keep], ys[keep]
            d = curve.signed_distance(xs.astype(float), ys.astype(float))
            v = img[ys, xs].astype(np.float64)
            p0 = [np.percentile(v, 2), np.ptp(v), 0.0, 0.6]
            res = least_squares(lambda p: p[0] + p[1] * ndtr((d - p[2]) / p[3]) - v, p0,
                                x_scale=[p0[1], p0[1], 0.1, 0.1])
            out.append(res.x[2])
    return np.asarray(out)
