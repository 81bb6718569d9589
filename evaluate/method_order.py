"""Canonical order and study options of the methods in tables and figures."""
from __future__ import annotations

import locate
import locate.registry

ORDER = locate.registry.CANONICAL_ORDER

#: Options the studies pass to a method (documented in every report).
#: PAE2013: the paper's smoothed variant (its Sec. 5, for noisy images); the study's images are
#: blurred and noisy, where the first-order case is biased by design.
STUDY_OPTIONS = {"pae2013": {"variant": "smoothed"}}

REFERENCE = "dynamic_erf_4p"


def ordered(methods=None) -> list[str]:
    ids = list(locate.METHODS) if methods is None else list(methods)
    known = [m for m in ORDER if m in ids]
    return known + sorted(m for m in ids if m not in ORDER)


def label(method_id: str) -> str:
    return locate.METHODS[method_id].label if method_id in locate.METHODS else method_id
