"""Atomic, deterministic file output: EXR (float32, OpenEXR package), 16-bit PNG, JSON; SHA-256.

Every writer writes a temporary file in the destination directory and renames it
into place with ``os.replace``, so an interrupted run never leaves a truncated file
under a final name.
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import numpy as np

from edgetruth.errors import InputError


def _tmp_path(path: Path) -> Path:
    # keep the suffix: some writers pick the format from it
    return path.with_name(f".tmp-{os.getpid()}-{path.stem}{path.suffix}")


def atomic_write_bytes(path: str | Path, data: bytes) -> None:
    path = Path(path)
    tmp = _tmp_path(path)
    with open(tmp, "wb") as fh:
        fh.write(data)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)


def write_json(path: str | Path, obj) -> None:
    atomic_write_bytes(path, (json.dumps(obj, indent=1, sort_keys=False) + "\n").encode())


def read_json(path: str | Path) -> dict:
    try:
        return json.loads(Path(path).read_text())
    except (OSError, ValueError) as exc:
        raise InputError(f"{path}: cannot read JSON: {exc}") from None


def write_png16(path: str | Path, image_dn: np.ndarray) -> None:
    """A 2-D uint16 image as a 16-bit grayscale PNG (values are raw DN, not rescaled)."""
    import cv2

    ok, buf = cv2.imencode(".png", np.ascontiguousarray(image_dn, dtype=np.uint16))
    if not ok:  # pragma: no cover
        raise OSError(f"cv2 could not encode {path}")
    atomic_write_bytes(path, buf.tobytes())


def read_png16(path: str | Path) -> np.ndarray:
    import cv2

    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise InputError(f"{path}: not a readable PNG")
    return img


def write_exr(path: str | Path, radiance: np.ndarray, channel: str = "Y") -> None:
    """A 2-D float32 radiance image as a one-channel ZIP-compressed EXR."""
    import OpenEXR

    path = Path(path)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    channels = {channel: np.ascontiguousarray(radiance, dtype=np.float32)}
    tmp = _tmp_path(path)
    with OpenEXR.File(header, channels) as f:
        f.write(str(tmp))
    os.replace(tmp, path)


def read_exr(path: str | Path, channel: str = "Y") -> np.ndarray:
    import OpenEXR

    with OpenEXR.File(str(path)) as f:
        return np.array(f.channels()[channel].pixels, dtype=np.float32)


def sha256_file(path: str | Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()
