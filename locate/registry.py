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
    """A registered edge-localisation method: what ``METHODS`` holds for each id.

    Attributes
    ----------
    id : str
        The method id (``"dynamic_erf_4p"``): 1-64 lowercase letters, digits and ``_``.
    label : str
        The name tables print (the seed study's, e.g. ``"ProposedDynamicERF_4P"``; the id for user methods
        registered without one).
    family : str
        ``"proposed"``, ``"erf-fixed"``, ``"baseline"`` or ``"user"``.
    fn : callable
        ``fn(image, cand, **options) -> Refinement``: ``image`` float64 (H, W), ``cand`` the shared
        ``Candidates``.
    summary : str
        One line on what it does (the function's first docstring line by default).
    footprint : callable or None
        ``footprint(cand, **options) -> (N, SIZE, SIZE) bool``: the pixels it reads per candidate
        (``edgetruth.locate.footprints``), used by the per-point Cramér-Rao bound; None: not declared.
    needs_camera : bool
        It needs options only a camera model gives (``patch_esf_fit``); studies without one leave it out.
    """

    id: str
    label: str  # the seed study's name (the id for user methods without one)
    family: str  # "proposed", "erf-fixed", "baseline" or "user"
    fn: Callable[..., Refinement]
    summary: str = ""
    #: ``footprint(cand, **options) -> (N, SIZE, SIZE) bool``: the pixels the method reads per candidate
    #: (``edgetruth.locate.footprints``); None: not declared (the Cramér-Rao bound then assumes every
    #: pixel within ``footprints.RADIUS``).
    footprint: Callable[..., np.ndarray] | None = None
    #: the method needs the camera's model (e.g. ``patch_esf_fit``'s edge-spread tables): studies without one
    #: (synthetic, board) leave it out of their default method list (``camera_free``).
    needs_camera: bool = False

    def footprint_masks(self, cand: Candidates, **options) -> np.ndarray:
        """The pixels the method reads for each candidate (its declaration, or the whole neighbourhood).

        Parameters
        ----------
        cand : Candidates
            The candidates.
        **options
            The method's options (a window size changes the footprint).

        Returns
        -------
        numpy.ndarray
            (N, SIZE, SIZE) bool, centred on each candidate pixel.
        """
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
"""Every registered method: id -> ``Method``, built-in methods first in their presentation order, then plug-ins
(alphabetically). ``list(METHODS)`` gives the ids; ``METHODS[id].label`` the name tables print."""

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
             footprint: Callable[..., np.ndarray] | None = None, needs_camera: bool = False):
    """Decorator: register ``fn(image, cand, **options) -> Refinement`` as an edge-localisation method.

    ``image`` is the float64 (H, W) image, ``cand`` the shared ``Candidates``; the method returns one
    ``Refinement`` entry per candidate (``Refinement.from_offset(cand, offsets_px)`` for an offset along
    each normal, in px, > 0 towards the bright side). Keyword parameters after ``cand`` become the
    method's options (``-m my_method:window=9`` on the command line). Registering the same function again
    under its id is a no-op (a module imported twice); another function under a taken id is an error.

    Parameters
    ----------
    method_id : str
        The id: 1-64 lowercase letters, digits and ``_``, starting with a letter.
    label : str, optional
        The name tables print (default: the id).
    family : str, optional
        ``"user"`` (default) for methods outside edgetruth.
    summary : str, optional
        One line for ``edgetruth methods`` (default: the function's first docstring line).
    footprint : callable, optional
        ``footprint(cand, **options) -> (N, SIZE, SIZE) bool``, the pixels the method reads per candidate
        (``edgetruth.locate.footprints``); the per-point Cramér-Rao bound counts exactly those. Default:
        the whole neighbourhood (the bound can then only be lower).
    needs_camera : bool, optional
        The method needs options only a camera model gives; studies without one leave it out.

    Returns
    -------
    callable
        The decorator; it returns ``fn`` unchanged.

    Raises
    ------
    edgetruth.errors.InputError
        A malformed id, or another function already registered under it.
    """
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
        METHODS[method_id] = Method(method_id, label or method_id, family, fn, summary or doc, footprint,
                                    bool(needs_camera))
        return fn

    return deco


def camera_free(ids=None) -> list[str]:
    """The method ids of ``ids`` (default: every registered one) that run without a camera model: the
    default method list of a study that has none (synthetic images, real photos of a board)."""
    ids = list(METHODS) if ids is None else list(ids)
    return [m for m in ids if not (m in METHODS and METHODS[m].needs_camera)]


def get_method(method: str) -> Method:
    """The registered method ``method``.

    Parameters
    ----------
    method : str
        A method id (``list(METHODS)``).

    Returns
    -------
    Method
        Its registry record.

    Raises
    ------
    edgetruth.errors.InputError
        An unknown id (the message lists the registered ones).
    """
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


#: Between a method id and its options, and between options, in a method spec: ``pae2013:variant=smoothed:order=1``.
OPTION_SEP = ":"


class _ProbeStop(Exception):
    """Raised by the probe's candidates the moment a method reads them (its option checks are behind it)."""


class _ProbeCandidates:
    def __getattr__(self, name):
        raise _ProbeStop

    def __len__(self):
        raise _ProbeStop

    def __getitem__(self, key):
        raise _ProbeStop


def _spec_value(raw: str):
    """A spec's value text -> bool, None, int, float or str (in that order of trial)."""
    low = raw.lower()
    if low in ("true", "false"):
        return low == "true"
    if low == "none":
        return None
    for kind in (int, float):
        try:
            return kind(raw)
        except ValueError:
            pass
    return raw


def format_option_value(v) -> str:
    """The spec text of an option value (``_spec_value`` reads it back)."""
    if isinstance(v, bool) or v is None:
        return str(v).lower()
    return repr(v) if isinstance(v, float) else str(v)


def _shown(v) -> str:
    return f"{v:.6g}" if isinstance(v, float) else format_option_value(v)


def _coerce(m: Method, param: inspect.Parameter, raw: str, spec: str, accepted: str):
    """``raw`` as the type ``param``'s default (or its annotation, when the default is None) says."""
    v = _spec_value(raw)
    d = param.default
    ann = "" if param.annotation is inspect.Parameter.empty else str(param.annotation)
    kinds = set(re.findall(r"\b(bool|int|float|str)\b", ann))

    def bad(what: str):
        return InputError(f"{spec}: option {param.name} of method {m.id} takes {what}, not {raw!r} "
                          f"(its options: {accepted})")

    if isinstance(d, bool) or (d is None and kinds == {"bool"}):
        if not isinstance(v, bool):
            raise bad("true or false")
        return v
    if isinstance(d, str) or (d is None and "str" in kinds):
        return raw
    if isinstance(d, int) or (d is None and kinds and kinds <= {"int"}):
        if d is None and v is None:
            return None
        if isinstance(v, bool) or not isinstance(v, int):
            raise bad("an integer" + (" or none" if d is None else ""))
        return v
    if isinstance(d, float) or (d is None and "float" in kinds):
        if d is None and v is None:
            return None
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise bad("a number" + (" or none" if d is None else ""))
        return float(v)
    return v  # no default type to go by: the value as read; the method checks it


def parse_method_spec(spec: str, probe: bool = True) -> tuple[str, dict]:
    """``METHOD[:key=value]...`` -> (method id, {option: value}), checked against the method's signature.

    Values are read as true/false, none, integers, numbers or text, then held to the type of the option's
    default (an int option refuses 2.5; a float one takes 2 as 2.0; a str one keeps the text as written).
    ``probe``: also call the method with the options on a stand-in that stops it as soon as it reads the
    candidates, so a value the method refuses up front (``variant=nope``) is refused here, one line."""
    if not isinstance(spec, str):
        raise InputError(f"method {spec!r}: give a method id (see `edgetruth methods`)")
    method_id, *parts = spec.strip().split(OPTION_SEP)
    m = get_method(method_id.strip())
    if not parts:
        return m.id, {}
    params = {p.name: p for p in list(inspect.signature(m.fn).parameters.values())[2:]
              if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)}
    accepted = ", ".join(f"{k}={_shown(p.default) if p.default is not p.empty else '?'}"
                         for k, p in params.items()) or "none"
    options: dict = {}
    for part in parts:
        key, eq, raw = part.partition("=")
        key, raw = key.strip(), raw.strip()
        if not eq or not key or not raw:
            raise InputError(f"{spec}: {part!r} is not key=value; write {m.id}{OPTION_SEP}key=value"
                             f"[{OPTION_SEP}key=value] (options of {m.id}: {accepted})")
        if key not in params:
            raise InputError(f"{spec}: method {m.id} has no option {key!r}; its options: {accepted}")
        if key in options:
            raise InputError(f"{spec}: option {key} is given twice; give it once")
        options[key] = _coerce(m, params[key], raw, spec, accepted)
    options = {k: options[k] for k in params if k in options}  # the signature's order
    if probe:
        try:
            m.fn(np.zeros((16, 16)), _ProbeCandidates(), **options)
        except InputError as exc:
            raise InputError(f"{spec}: {exc}") from None
        except Exception:  # _ProbeStop, or a method that reads the image or candidates first: it checks at run time
            pass
    return m.id, options


def method_spec(method_id: str, options: dict) -> str:
    """The canonical spec text of ``method_id`` with ``options`` (``parse_method_spec`` reads it back)."""
    return OPTION_SEP.join([method_id, *(f"{k}={format_option_value(v)}" for k, v in options.items())])


def _where(m: Method) -> str:
    """Where a user's method lives, for its errors: its source file, else its module."""
    try:
        return inspect.getsourcefile(m.fn) or m.fn.__module__
    except (TypeError, AttributeError):
        return getattr(m.fn, "__module__", "?")


def _call_user_method(m: Method, img, cand, options: dict):
    """A user's method on the candidates: an error inside it is the method's, reported as one line (the method,
    where it lives, what it raised) rather than a traceback from edgetruth's stack."""
    try:
        return m.fn(img, cand, **options)
    except InputError:
        raise
    except Exception as exc:
        first = (str(exc).strip().splitlines() or [""])[0]
        raise InputError(f"method {m.id!r} ({_where(m)}) raised {type(exc).__name__}: {first} -- on {len(cand)} "
                         "candidates; fix the method, or leave it out") from exc


def check_refinement(m: Method, r, n: int) -> None:
    """A method's answer is a ``Refinement`` with one entry per candidate: else one line naming the method and what
    it returned (a user's method that breaks the contract would otherwise fail later, far from its cause)."""
    fix = "return Refinement(x, y, converged) or Refinement.from_offset(cand, offsets), one entry per candidate"
    if not isinstance(r, Refinement):
        raise InputError(f"method {m.id!r} ({_where(m)}) returned {type(r).__name__}, not a Refinement; {fix}")
    fields = [("x", r.x), ("y", r.y), ("converged", r.converged), ("nx", r.nx), ("ny", r.ny)]
    for name, v in fields + [(f"extras[{k!r}]", v) for k, v in (r.extras or {}).items()]:
        if v is not None and np.shape(v) != (n,):
            raise InputError(f"method {m.id!r} ({_where(m)}) returned {name} of shape {np.shape(v)} for {n} "
                             f"candidates; {fix}")


def refine(image, cand: Candidates, method: str = "dynamic_erf_4p", **options) -> EdgePoints:
    """Stage 2: refine the candidates ``cand`` of ``image`` with ``method``.

    Every method refines the same candidates, so their points pair one to one. A point whose refinement
    failed or left the image keeps its candidate pixel and is flagged ``converged=False``: every output
    point is finite and inside the image.

    Parameters
    ----------
    image : numpy.ndarray
        The (H, W) image the candidates came from: uint8, uint16 or float (read as float64 gray levels).
    cand : Candidates
        The result of ``candidates(image)``.
    method : str, optional
        A method id (``list(METHODS)``); default ``"dynamic_erf_4p"``.
    **options
        The method's options (its keyword parameters, e.g. ``tau=(0.75, 0.83, 0.89)`` for the dynamic
        fits, ``psf_sigma_px=`` for ``patch_psf_fit``); unknown ones are refused.

    Returns
    -------
    EdgePoints
        One point per candidate, in candidate order: ``x``, ``y`` (px, OpenCV convention), the unit normal
        ``nx``, ``ny`` (dark to bright), ``converged``, and the method's extras (e.g. ``s``, ``se``, px).

    Raises
    ------
    edgetruth.errors.InputError
        An unknown method or option, candidates of another image's shape, or a method that breaks the
        one-entry-per-candidate contract.
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
        r = m.fn(img, cand, **options) if m.builtin else _call_user_method(m, img, cand, options)
        check_refinement(m, r, n)
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
    """Subpixel edge points of ``image``: Canny candidates (stage 1) refined by ``method`` (stage 2).

    Parameters
    ----------
    image : numpy.ndarray
        A 2-D image (H, W): uint8, uint16 or float gray levels; pixel (r, c) has its centre at x = c, y = r.
    method : str, optional
        A method id (``list(METHODS)``); default ``"dynamic_erf_4p"``.
    sigma_px : float, optional
        The Gaussian smoothing of the candidate stage, px (0.3-10; default 1).
    low, high : float, optional
        Canny's hysteresis thresholds on the smoothed gradient magnitude, gray levels per px (default:
        from the image's gradient statistics).
    **options
        The method's options, as for ``refine``.

    Returns
    -------
    EdgePoints
        One point per candidate (see ``refine``).

    Examples
    --------
    >>> from edgetruth import locate
    >>> pts = locate.locate(image, method="dynamic_erf_4p")   # doctest: +SKIP
    >>> pts.x, pts.y, pts.nx, pts.ny, pts.converged            # doctest: +SKIP
    """
    get_method(method)
    img = as_float_image(image)
    cand = _candidates(img, sigma_px=sigma_px, low=low, high=high)
    return refine(img, cand, method, **options)
