"""Reading images from disk with one clear error per failure mode."""
from __future__ import annotations

import contextlib
import os
import sys
from pathlib import Path

import cv2
import numpy as np

from edgetruth.errors import InputError


@contextlib.contextmanager
def _quiet_stderr_fd():
    """Silence file descriptor 2 (C libraries such as OpenEXR's decoder print their own diagnostics
    there); our one-line error is printed after this block."""
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):
        yield
        return
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 2)
            yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def read_gray(path) -> np.ndarray:
    """Read a gray image (PNG/TIFF/JPEG 8- or 16-bit, EXR float, or .npy) without changing its values.

    Colour images are rejected rather than silently converted: the conversion
    weights change edge positions, so the user should choose them."""
    p = Path(path)
    if not p.exists():
        raise InputError(f"{p}: no such file; check the path")
    if p.is_dir():
        raise InputError(f"{p}: is a directory; pass an image file")
    if p.suffix.lower() == ".npy":
        try:
            return np.load(p, allow_pickle=False)
        except Exception as exc:
            raise InputError(f"{p}: not a readable .npy array ({exc.__class__.__name__}); re-save it with numpy.save") from exc
    if p.suffix.lower() == ".exr":
        try:
            import OpenEXR

            with _quiet_stderr_fd(), OpenEXR.File(str(p)) as f:
                chans = f.channels()
                name = next(iter(chans))
                img = np.asarray(chans[name].pixels)
        except Exception as exc:
            raise InputError(f"{p}: not a readable EXR file ({exc.__class__.__name__}); check the file is complete") from exc
    else:
        img = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
        if img is None:
            raise InputError(f"{p}: cannot be decoded as an image (corrupt, truncated or unsupported); "
                             "use PNG, TIFF, JPEG, EXR or .npy")
    if img.ndim == 3:
        if img.shape[2] == 1:
            img = img[:, :, 0]
        elif np.array_equal(img[..., 0], img[..., 1]) and np.array_equal(img[..., 0], img[..., -1]):
            img = img[..., 0]
        else:
            raise InputError(f"{p}: colour image ({img.shape[2]} channels); convert it to gray first "
                             "(the conversion weights move edges, so edgetruth does not choose them)")
    return img
