"""Canonical order and study options of the methods in tables and figures."""
from __future__ import annotations

import locate

ORDER = (
    "canny_pixel", "canny_devernay", "glm1984", "canny_zernike2020", "hagara_aef2011", "pae2013",
    "gaussian_fit2014", "arctan_fit2016", "sigmoid_logistic_fit2023", "ser_cis",
    "erf2p_fixed5", "erf2p_fixed7", "erf2p_fixed9", "erf2p_fixed11", "dynamic_erf_2p",
    "erf4p_fixed5", "erf4p_fixed7", "erf4p_fixed9", "erf4p_fixed11", "dynamic_erf_4p",
)

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
