"""Image files of a dataset: EXR (float32 radiance, OpenEXR package) and 16-bit PNG (raw DN).

Encoders return bytes (hashed and written atomically by the dataset writer); readers
raise ``InputError`` naming the file.  Generic atomic writes, JSON and hashes live in
``edgetruth.fileio``.
"""
from __future__ import annotations

import io
import os
import tempfile
from pathlib import Path

import numpy as np

from edgetruth.errors import InputError
from edgetruth.fileio import atomic_write_bytes, check_input_file

EXR_CHANNEL = "Y"


def encode_png16(image_dn: np.ndarray) -> bytes:
    """A 2-D uint16 image as 16-bit grayscale PNG bytes (values are raw DN, not rescaled); a uint8
    image (the sRGB/JPEG outputs) as an 8-bit PNG."""
    import cv2

    dtype = np.uint8 if np.asarray(image_dn).dtype == np.uint8 else np.uint16
    ok, buf = cv2.imencode(".png", np.ascontiguousarray(image_dn, dtype=dtype))
    if not ok:  # pragma: no cover
        raise OSError("cv2 could not encode a 16-bit PNG")
    return buf.tobytes()


def write_png16(path: str | Path, image_dn: np.ndarray) -> None:
    atomic_write_bytes(path, encode_png16(image_dn))


def read_png16(path: str | Path) -> np.ndarray:
    from edgetruth.image_io import read_gray

    return read_gray(path)


def encode_exr(radiance: np.ndarray, channel: str = EXR_CHANNEL) -> bytes:
    """A 2-D float32 image as one-channel ZIP-compressed EXR bytes, encoded in memory (OpenEXR >= 3.3
    writes to a stream; older versions only to a path, so there via a private temporary file)."""
    import OpenEXR

    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    channels = {channel: np.ascontiguousarray(radiance, dtype=np.float32)}
    with OpenEXR.File(header, channels) as f:
        buf = io.BytesIO()
        try:
            f.write(buf)
            return buf.getvalue()
        except TypeError:  # this OpenEXR writes to paths only
            pass
        fd, tmp = tempfile.mkstemp(prefix="edgetruth-exr-", suffix=".exr")
        os.close(fd)
        try:
            f.write(tmp)
            return Path(tmp).read_bytes()
        finally:
            os.unlink(tmp)


def write_exr(path: str | Path, radiance: np.ndarray, channel: str = EXR_CHANNEL) -> None:
    atomic_write_bytes(path, encode_exr(radiance, channel))


def read_exr(path: str | Path, channel: str = EXR_CHANNEL) -> np.ndarray:
    from edgetruth.image_io import quiet_stderr

    import OpenEXR

    p = check_input_file(path, "EXR file")
    try:
        with quiet_stderr(), OpenEXR.File(str(p)) as f:
            return np.array(f.channels()[channel].pixels, dtype=np.float32)
    except Exception as exc:
        raise InputError(f"{p}: not a readable EXR with channel {channel!r} ({exc.__class__.__name__}); "
                         "re-render the image") from None
