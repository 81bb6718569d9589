"""edgetruth.locate: subpixel edge localisation on shared Canny candidates.

    from edgetruth import locate
    pts = locate.locate(image, method="dynamic_erf_4p")
    cand = locate.candidates(image)          # stage 1, shared by every method
    pts = locate.refine(image, cand, "glm1984")  # stage 2

``edgetruth.locate.METHODS`` maps every method id to its ``Method`` record.  Each
module in ``locate/methods/`` registers its methods on import; so do the packages that
declare an ``edgetruth.methods`` entry point (``edgetruth.locate.plugins``).  A user's
own method::

    @locate.register("my_method")
    def my_method(image, cand):
        return locate.Refinement.from_offset(cand, offsets_px)   # one offset along each normal
"""
from __future__ import annotations

from edgetruth.locate.candidates import Candidates, candidates
from edgetruth.locate.registry import METHODS, Method, get_method, locate, refine, register, sort_registry as _sort
from edgetruth.locate.result import EdgePoints, Refinement
from edgetruth.locate import methods as _methods  # noqa: F401  (registers the built-in methods)
from edgetruth.locate.plugins import load_entry_points as _load_entry_points  # noqa: E402

_load_entry_points()
_sort()

__all__ = ["METHODS", "Method", "Candidates", "EdgePoints", "Refinement", "candidates", "get_method",
           "locate", "refine", "register"]
