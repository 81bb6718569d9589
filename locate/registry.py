"""The method registry and the refinement stage shared by every method."""
from __future__ import annotations

import inspect
import re
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from edgetruth.errors import InputError
from edgetruth.locate.candidates import Candidates, candidates as _candidates
from edgetruth.locate.image_input import as_float_image
from edgetruth.locate.result import EdgePoints, Refinement


@dataclass(frozen=True)
class Method:
    id: str
    label: str  # the seed study's name (the id for user methods without one)
    family: str  # "proposed", "erf-fixed", "baseline" or "user"
    fn: Callable[..., Refinement]
    summary: str = ""
    #: ``footprint(cand, **options) -> (N, SIZE, SIZE) bool``: the pixels the method reads per candidate
    #: (``edgetruth.locate.footprints``); None: not declared (the Cramér-Rao bound then assumes every
    #: pixel within ``footprints.RADIUS``).
    footprint: Callable[..., np.ndarray] | None = None

    def footprint_masks(self, cand: Candidates, **options) -> np.ndarray:
        """The pixels the method reads for each candidate (its declaration, or the whole neighbourhood)."""
        from edgetruth.locate import footprints

        fp = self.footprint or footprints.neighbourhood
        return fp(cand, **options)

    @property
    def builtin(self) -> bool:
        """Shipped with edgetruth (registered by ``edgetruth.locate.methods``)."""
        return getattr(self.fn, "__module__", "").startswith("edgetruth.locate.methods.")


_ID = re.compile(r"^[a-z][a-z0-9_]{0,63}$")

#: Every method id -> Method.  ``list(METHODS)`` gives the ids, in ``CANONICAL_ORDER``.
METHODS: dict[str, Method] = {}

#: Presentation order: the seed's baselines, then the ERF family (2P, then 4P) ending in the proposed method.
CANONICAL_ORDER = (
    "canny_pixel", "canny_devernay", "glm1984", "canny_zernike2020", "hagara_aef2011", "pae2013",
    "gaussian_fit2014", "arctan_fit2016", "sigmoid_logistic_fit2023", "ser_cis",
    "erf2p_fixed5", "erf2p_fixed7", "erf2p_fixed9", "erf2p_fixed11", "dynamic_erf_2p",
    "erf4p_fixed5", "erf4p_fixed7", "erf4p_fixed9", "erf4p_fixed11", "dynamic_erf_4p",
)


def sort_registry() -> None:
    """Put METHODS in CANONICAL_ORDER (methods not listed follow, alphabetically)."""
    rank = {m: i for i, m in enumerate(CANONICAL_ORDER)}
    items = sorted(METHODS.items(), key=lambda kv: (rank.get(kv[0], len(rank)), kv[0]))
    METHODS.clear()
    METHODS.update(items)


def register(method_id: str, label: str | None = None, family: str = "user", summary: str = "",
             footprint: Callable[..., np.ndarray] | None = None):
    """Decorator: register ``fn(image, cand, **options) -> Refinement`` under ``method_id``.

    ``image`` is the float64 (H, W) image, ``cand`` the shared ``Candidates``; return one
    ``Refinement`` entry per candidate (``Refinement.from_offset(cand, mu_px)`` for an offset
    along each normal).  Keyword options after ``cand`` become the method's options.
    Registering the same function again under its id is a no-op (a module imported twice);
    another function under a taken id is an error.  ``footprint``: the pixels the method reads
    (``edgetruth.locate.footprints``), used by the per-point Cramér-Rao bound."""
    if not (isinstance(method_id, str) and _ID.match(method_id)):
        raise InputError(f"method id {method_id!r}: use 1-64 lowercase letters, digits and '_', starting with a letter")

    def deco(fn):
        old = METHODS.get(method_id)
        if old is not None:
            if (getattr(old.fn, "__module__", None), getattr(old.fn, "__qualname__", None)) == (
                    getattr(fn, "__module__", None), getattr(fn, "__qualname__", None)):
                return fn
            raise InputError(f"method {method_id!r} is registered twice (by {old.fn.__module__} and "
                             f"{getattr(fn, '__module__', '?')}); give the new one another id")
        doc = (fn.__doc__ or "").strip().split("\n")[0]
        METHODS[method_id] = Method(method_id, label or method_id, family, fn, summary or doc, footprint)
        return fn

    return deco


def get_method(method: str) -> Method:
    if method not in METHODS:
        raise InputError(f"unknown method {method!r}; choose one of: {', '.join(METHODS)}")
    return METHODS[method]


def method_options(m: Method) -> list[str]:
    """The keyword options a method accepts (its named parameters after image and candidates)."""
    params = list(inspect.signature(m.fn).parameters.values())[2:]
    return [p.name for p in params if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)]


def check_options(m: Method, options: dict) -> None:
    known = method_options(m)
    bad = sorted(set(options) - set(known))
    if bad:
        raise InputError(f"method {m.id} has no option(s) {', '.join(bad)}; its options are: "
                         f"{', '.join(known) or 'none'}")


def refine(image, cand: Candidates, method: str = "dynamic_erf_4p", **options) -> EdgePoints:
    """Refine the candidates ``cand`` of ``image`` with ``method``.

    Points whose refinement failed or left the image keep the candidate pixel
    and are flagged ``converged=False``, so every output point is finite and
    inside the image.
    """
    m = get_method(method)
    img = as_float_image(image)
    if not isinstance(cand, Candidates):
        raise InputError(f"candidates: got {type(cand).__name__}; pass the result of locate.candidates(image)")
    check_options(m, options)
    if tuple(img.shape) != tuple(cand.shape):
        raise InputError(f"candidates were found on a {cand.shape} image but image is {img.shape}; "
                         "pass the image the candidates came from")
    n = len(cand)
    t0 = time.perf_counter()
    if n:
        r = m.fn(img, cand, **options)
    else:
        z = np.zeros(0)
        r = Refinement(z, z, np.zeros(0, bool))
    elapsed = time.perf_counter() - t0
    x = np.asarray(r.x, np.float64)
    y = np.asarray(r.y, np.float64)
    nx = cand.nx if r.nx is None else np.asarray(r.nx, np.float64)
    ny = cand.ny if r.ny is None else np.asarray(r.ny, np.float64)
    h, w = img.shape
    ok = np.isfinite(x) & np.isfinite(y) & (x >= 0) & (y >= 0) & (x <= w - 1) & (y <= h - 1)
    conv = np.asarray(r.converged, bool) & ok
    x = np.where(ok, x, cand.x)
    y = np.where(ok, y, cand.y)
    nok = np.isfinite(nx) & np.isfinite(ny)
    nx = np.where(nok, nx, cand.nx)
    ny = np.where(nok, ny, cand.ny)
    return EdgePoints(method, x, y, nx, ny, conv, np.arange(n), dict(r.extras), elapsed)


def locate(image, method: str = "dynamic_erf_4p", sigma_px: float = 1.0, low=None, high=None, **options) -> EdgePoints:
    """Canny candidates + refinement with ``method`` in one call."""
    get_method(method)
    img = as_float_image(image)
    cand = _candidates(img, sigma_px=sigma_px, low=low, high=high)
    return refine(img, cand, method, **options)
