"""Validation and conversion of input images: one place, used by every method."""
from __future__ import annotations

import numpy as np

from edgetruth.errors import InputError


def as_float_image(image, name: str = "image") -> np.ndarray:
    """Return ``image`` as a C-contiguous float64 2-D array.

    uint8/uint16/int images are converted to float before any arithmetic, so
    differences never wrap.  Raises ``InputError`` (a ``ValueError``) naming
    the input and the fix for anything that is not a finite, non-empty 2-D
    real array.
    """
    try:
        arr = np.asarray(image)
    except Exception as exc:  # pragma: no cover - exotic objects
        raise InputError(f"{name}: cannot be read as an array ({exc}); pass a 2-D numpy array") from exc
    if arr.dtype == object or not (np.issubdtype(arr.dtype, np.number) or arr.dtype == bool):
        raise InputError(f"{name}: dtype {arr.dtype} is not numeric; pass uint8, uint16 or float pixels")
    if np.iscomplexobj(arr):
        raise InputError(f"{name}: complex pixels are not supported; pass a real-valued image")
    if arr.ndim == 3 and arr.shape[2] == 1:
        arr = arr[:, :, 0]
    if arr.ndim != 2:
        raise InputError(
            f"{name}: expected a 2-D gray image, got shape {arr.shape}; convert colour images to gray first"
        )
    if arr.shape[0] < 3 or arr.shape[1] < 3:
        raise InputError(f"{name}: image of shape {arr.shape} is too small; edges need at least 3x3 pixels")
    out = np.ascontiguousarray(arr, dtype=np.float64)
    if not np.all(np.isfinite(out)):
        bad = int(np.size(out) - np.count_nonzero(np.isfinite(out)))
        raise InputError(f"{name}: {bad} pixel(s) are NaN or Inf; replace or mask them before locating edges")
    return out
