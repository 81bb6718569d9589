"""locate: subpixel edge localisation on shared Canny candidates.

    import locate
    pts = locate.locate(image, method="dynamic_erf_4p")
    cand = locate.candidates(image)          # stage 1, shared by every method
    pts = locate.refine(image, cand, "glm1984")  # stage 2

``locate.METHODS`` maps every method id to its ``Method`` record.  Each
module in ``locate/methods/`` registers its methods on import.
"""
from __future__ import annotations

import importlib as _importlib
import pkgutil as _pkgutil

from locate.candidates import Candidates, candidates
from locate.registry import METHODS, Method, get_method, locate, refine, register, sort_registry as _sort
from locate.result import EdgePoints, Refinement
from locate import methods as _methods

for _info in sorted(_pkgutil.iter_modules(_methods.__path__), key=lambda m: m.name):
    if not _info.name.startswith("_"):
        _importlib.import_module(f"locate.methods.{_info.name}")
_sort()

__all__ = ["METHODS", "Method", "Candidates", "EdgePoints", "Refinement", "candidates", "get_method",
           "locate", "refine", "register"]
