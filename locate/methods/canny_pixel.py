"""CannyPixel: the candidate pixel centre itself (no subpixel refinement).

The study's lower baseline.  Every shared Canny candidate (``edgetruth.locate.candidates``)
is returned unchanged: x = column, y = row of the candidate pixel (OpenCV
convention, pixel centres at integers), normal = the candidate's smoothed
gradient direction.  Always ``converged``.

What to expect: the candidate is the pixel OpenCV's non-maximum suppression
keeps, i.e. the pixel nearest the gradient maximum along the gradient direction
quantised to 0/45/90/135 degrees (lattice step L = 1 or sqrt(2) px).  For a
straight edge at a random subpixel offset the error along the normal is then
~uniform on +-L |cos(theta - q)| / 2: RMSE 1/sqrt(12) = 0.289 px for
axis-aligned edges, up to ~0.38 px near 22.5 degrees, ~0.345 px averaged over
all angles (checked against this prediction in the tests).
"""
from __future__ import annotations

import numpy as np

from edgetruth.locate import footprints as FP
from edgetruth.locate.registry import register
from edgetruth.locate.result import Refinement


@register("canny_pixel", "CannyPixel", family="baseline", footprint=FP.candidate_decision)
def canny_pixel(image, cand, **options) -> Refinement:
    """CannyPixel: the Canny candidate pixel centre, unrefined."""
    n = len(cand)
    return Refinement(cand.x.copy(), cand.y.copy(), np.ones(n, bool), extras={"offset": np.zeros(n)})
