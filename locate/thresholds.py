"""Entropy thresholds tau1 < tau2 < tau3 of the dynamic window: shipped defaults + provenance.

The shipped values live in ``assets/entropy_thresholds.json`` (written by
``edgetruth calibrate-thresholds``), one set per ERF model ("2p", "4p").
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from edgetruth.errors import InputError
from edgetruth.paths import ASSETS_DIR

THRESHOLDS_FILE = ASSETS_DIR / "entropy_thresholds.json"
#: Used only if the asset file is missing (a broken install); the calibrated file overrides.
FALLBACK = (0.55, 0.65, 0.75)


def validate(tau) -> tuple[float, float, float]:
    t = tuple(float(v) for v in np.asarray(tau, dtype=float).ravel())
    if len(t) != 3 or not all(np.isfinite(t)) or not (0.0 <= t[0] <= t[1] <= t[2] <= 1.0):
        raise InputError(f"entropy thresholds {tau}: need three numbers 0 <= tau1 <= tau2 <= tau3 <= 1")
    return t  # type: ignore[return-value]


def load(model: str = "4p", path: str | Path | None = None) -> tuple[float, float, float]:
    """Calibrated thresholds for ERF ``model`` ('2p' or '4p')."""
    p = Path(path) if path is not None else THRESHOLDS_FILE
    if not p.exists():
        if path is not None:
            raise InputError(f"thresholds file {p} does not exist; run `edgetruth calibrate-thresholds -o {p}`")
        return FALLBACK
    try:
        data = json.loads(p.read_text())
        return validate(data["models"][model]["tau"])
    except (KeyError, ValueError, TypeError) as exc:
        raise InputError(f"thresholds file {p}: no valid models.{model}.tau entry ({exc}); "
                         "re-run `edgetruth calibrate-thresholds`") from exc
