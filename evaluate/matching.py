"""Which candidates belong to the true edge: one rule for every study.

A candidate is *on the edge* when its pixel centre lies within
``MATCH_RADIUS_PX`` of the true edge (|signed distance| <= 1.5 px).  Other
candidates (texture, noise) have no ground-truth counterpart; they are
counted and reported, and excluded from error statistics for every method
alike (all methods refine the same candidates).
"""
from __future__ import annotations

import numpy as np

MATCH_RADIUS_PX = 1.5


def on_edge(truth, cand, radius_px: float = MATCH_RADIUS_PX) -> np.ndarray:
    return np.abs(truth.signed_distance(cand.x, cand.y)) <= radius_px
