"""Canonical order and study options of the methods in tables and figures."""
from __future__ import annotations

from pathlib import Path

from edgetruth import locate
from edgetruth.locate import registry as _registry_mod

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
    from edgetruth.locate import thresholds as thr

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
    """(registered method, keyword options) of a label of a study's method list."""
    kw = dict((options or {}).get(label, {}))
    return kw.pop("method", label), kw


def variant_labels(options: dict) -> list[str]:
    """The labels of ``options`` that run another registered method (e.g. the camera-τ variants)."""
    return [k for k, v in options.items() if "method" in v]


def thresholds_in_use(thresholds=None) -> dict:
    """{'2p': tau, '4p': tau, 'source': path, 'label': for reports} of the thresholds a study uses."""
    from edgetruth.locate import thresholds as thr

    src = thr.source(thresholds)
    label = "shipped, assets/entropy_thresholds.json" if thresholds is None else f"from {Path(thresholds).name}"
    return {**{m: thr.load(m, thresholds) for m in thr.MODELS}, "source": str(src), "label": label}

REFERENCE = "dynamic_erf_4p"


def ordered(methods=None) -> list[str]:
    ids = list(locate.METHODS) if methods is None else list(methods)
    known = []
    for m in ORDER:
        known += [m] * (m in ids) + [m + CAMERA_SUFFIX] * (m + CAMERA_SUFFIX in ids)
    return known + sorted(m for m in ids if m not in known)


def label(method_id: str) -> str:
    if method_id.endswith(CAMERA_SUFFIX) and method_id[:-len(CAMERA_SUFFIX)] in locate.METHODS:
        return locate.METHODS[method_id[:-len(CAMERA_SUFFIX)]].label + " (camera τ)"
    return locate.METHODS[method_id].label if method_id in locate.METHODS else method_id
