"""Entropy thresholds tau1 < tau2 < tau3 of the dynamic window: shipped defaults + provenance.

The shipped values live in ``assets/entropy_thresholds.json`` (written by
``edgetruth calibrate-thresholds``), one set per ERF model ("2p", "4p").
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from edgetruth.errors import InputError
from edgetruth.fileio import check_input_file
from edgetruth.resources import shipped_thresholds

MODELS = ("2p", "4p")


def validate(tau) -> tuple[float, float, float]:
    t = tuple(float(v) for v in np.asarray(tau, dtype=float).ravel())
    if len(t) != 3 or not all(np.isfinite(t)) or not (0.0 <= t[0] <= t[1] <= t[2] <= 1.0):
        raise InputError(f"entropy thresholds {tau}: need three numbers 0 <= tau1 <= tau2 <= tau3 <= 1")
    return t  # type: ignore[return-value]


def source(path: str | Path | None = None) -> Path:
    """The thresholds file in use: ``path``, else the shipped ``assets/entropy_thresholds.json``
    (an error if the install lacks it: a missing asset is never replaced by a silent default)."""
    if path is None:
        return shipped_thresholds()
    p = Path(path)
    if not p.exists():
        raise InputError(f"thresholds file {p} does not exist; run `edgetruth calibrate-thresholds -o {p}`")
    return check_input_file(p, "thresholds JSON")


def load(model: str = "4p", path: str | Path | None = None) -> tuple[float, float, float]:
    """Calibrated thresholds for ERF ``model`` ('2p' or '4p'), from ``path`` or the shipped file."""
    p = source(path)
    try:
        data = json.loads(p.read_text())
        return validate(data["models"][model]["tau"])
    except (KeyError, ValueError, TypeError) as exc:
        raise InputError(f"thresholds file {p}: no valid models.{model}.tau entry ({exc}); "
                         "re-run `edgetruth calibrate-thresholds`") from None
