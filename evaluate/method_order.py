"""Canonical order and study options of the methods in tables and figures."""
from __future__ import annotations

from pathlib import Path

from edgetruth import locate
from edgetruth.errors import InputError
from edgetruth.locate import registry as _registry_mod, thresholds as thr


ORDER = _registry_mod.CANONICAL_ORDER

#: Options the studies pass to a method (documented in every report).
#: PAE2013: the authors' released detector for noisy images (3x3-smoothed, floating windows, A and B
#: from the smoothed image; their "iters=1"): the study's images are noisy, where the unsmoothed
#: floating windows stop at noise-made maxima (tests/locate/test_pae2013.py).
STUDY_OPTIONS = {"pae2013": {"variant": "smoothed"}}


#: Suffix of the dynamic methods run with thresholds calibrated for the camera (next to the shipped ones).
CAMERA_SUFFIX = "_camera"


def study_options(thresholds=None, camera_thresholds=None) -> dict:
    """Per-method options of a study: ``STUDY_OPTIONS``, plus the entropy thresholds of a
    ``--thresholds FILE`` for the dynamic methods (default: the shipped ones, which they load).

    ``camera_thresholds`` (a file from ``calibrate-thresholds --dataset``) adds the labels
    ``dynamic_erf_2p_camera`` and ``dynamic_erf_4p_camera``: the same methods with those thresholds
    (an option ``method`` names the registered method a label runs, ``resolve``)."""
    out = {m: dict(o) for m, o in STUDY_OPTIONS.items()}
    if thresholds is not None:
        for model in thr.MODELS:
            out.setdefault(f"dynamic_erf_{model}", {})["tau"] = thr.load(model, thresholds)
    if camera_thresholds is not None:
        for model in thr.MODELS:
            out[f"dynamic_erf_{model}{CAMERA_SUFFIX}"] = {"method": f"dynamic_erf_{model}",
                                                          "tau": thr.load(model, camera_thresholds)}
    return out


def resolve(label: str, options: dict | None = None) -> tuple[str, dict]:
    """(registered method, keyword options) of a label of a study's method list.

    A label with options, ``METHOD:key=value[:key=value]`` (``edgetruth --methods``), runs METHOD with
    the study's options for it (``options[METHOD]``, e.g. ``STUDY_OPTIONS``) overridden by its own."""
    if _registry_mod.OPTION_SEP in label:
        mid, own = _parsed(label)
        kw = {k: v for k, v in (options or {}).get(mid, {}).items() if k != "method"}
        return mid, {**kw, **own}
    kw = dict((options or {}).get(label, {}))
    return kw.pop("method", label), kw


_PARSED: dict = {}


def _parsed(label: str) -> tuple[str, dict]:
    """``registry.parse_method_spec`` without the probe, memoised (called per image and method)."""
    if label not in _PARSED:
        _PARSED[label] = _registry_mod.parse_method_spec(label, probe=False)
    mid, own = _PARSED[label]
    return mid, dict(own)


def method_specs(text: str | None) -> list[str] | None:
    """``--methods`` text -> its labels, each checked (``registry.parse_method_spec``) and written the
    canonical way; None for all.  Items are separated by ',' and a method's options by ':'
    (``pae2013:variant=floating:order=1,dynamic_erf_4p``); an item ``key=value`` right after a method's
    options adds one more option to it (``pae2013:variant=floating,order=1``)."""
    if not text:
        return None
    sep = _registry_mod.OPTION_SEP
    items: list[str] = []
    for part in (p.strip() for p in text.split(",")):
        if not part:
            continue
        head = part.split(sep, 1)[0]
        if "=" in head:  # key=value: an option of the method before it
            if not items or sep not in items[-1]:
                where = f"after {items[-1]}" if items else "first"
                raise InputError(f"--methods {text!r}: {part!r} ({where}) is an option but names no method; write "
                                 f"METHOD{sep}{part} (options of one method are joined by '{sep}')")
            items[-1] += sep + part
        else:
            items.append(part)
    if not items:
        raise InputError(f"--methods {text!r}: give comma-separated method ids (see `edgetruth methods`), each "
                         f"with options as METHOD{sep}key=value{sep}key=value if wanted")
    out: list[str] = []
    for item in items:
        label = _registry_mod.method_spec(*_registry_mod.parse_method_spec(item))
        if label not in out:
            out.append(label)
    return out


def options_text(label: str, options: dict | None = None) -> str:
    """``key=value, ...`` of the options ``label`` runs with (``resolve``; the entropy thresholds left
    out: the report gives them), or 'defaults'."""
    _, kw = resolve(label, options)
    kw = {k: v for k, v in kw.items() if k != "tau"}
    return ", ".join(f"{k}={_registry_mod.format_option_value(v)}" for k, v in kw.items()) or "defaults"


def options_line(methods, options: dict | None = None) -> str:
    """The report line of the options each method ran with: the methods with options of their own
    (the study's ``STUDY_OPTIONS`` or a ``METHOD:key=value`` label), then 'the others: their defaults'."""
    options = study_options() if options is None else options
    with_opts = [(label(m), options_text(m, options)) for m in methods if options_text(m, options) != "defaults"]
    rest = "the others: their signature's defaults" if len(with_opts) < len(list(methods)) else ""
    parts = [f"{lab}: {txt}" for lab, txt in with_opts] + ([rest] if rest else [])
    return ("Method options (`edgetruth locate -m METHOD` runs the same; `METHOD:key=value` sets others): "
            + "; ".join(parts) + ".")


def variant_labels(options: dict) -> list[str]:
    """The labels of ``options`` that run another registered method (e.g. the camera-τ variants)."""
    return [k for k, v in options.items() if "method" in v]


def thresholds_in_use(thresholds=None) -> dict:
    """{'2p': tau, '4p': tau, 'source': path, 'label': for reports} of the thresholds a study uses."""
    src = thr.source(thresholds)
    label = "shipped, assets/entropy_thresholds.json" if thresholds is None else f"from {Path(thresholds).name}"
    return {**{m: thr.load(m, thresholds) for m in thr.MODELS}, "source": str(src), "label": label}

REFERENCE = "dynamic_erf_4p"


def ordered(methods=None) -> list[str]:
    """Labels in ``ORDER``; a label with options (``pae2013:variant=floating``) right after its method."""
    ids = list(locate.METHODS) if methods is None else list(methods)
    sep = _registry_mod.OPTION_SEP
    known = []
    for m in ORDER:
        known += [m] * (m in ids) + [m + CAMERA_SUFFIX] * (m + CAMERA_SUFFIX in ids)
        known += [i for i in ids if sep in i and i.split(sep, 1)[0] == m and i not in known]
    rest = sorted({m for m in ids if m not in known and sep not in m})
    for m in rest:
        known += [m] + [i for i in ids if sep in i and i.split(sep, 1)[0] == m and i not in known]
    return known + [m for m in ids if m not in known]


def label(method_id: str) -> str:
    """The readable name of a label: the method's label, '(camera τ)', or its options in brackets."""
    sep = _registry_mod.OPTION_SEP
    if sep in method_id:
        mid, own = method_id.split(sep, 1)
        opts = ", ".join(own.split(sep))
        return f"{label(mid)} ({opts})"
    if method_id.endswith(CAMERA_SUFFIX) and method_id[:-len(CAMERA_SUFFIX)] in locate.METHODS:
        return locate.METHODS[method_id[:-len(CAMERA_SUFFIX)]].label + " (camera τ)"
    return locate.METHODS[method_id].label if method_id in locate.METHODS else method_id
