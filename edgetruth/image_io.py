"""Reading gray images from disk with one clear error per failure mode.

Checked before anything is decoded: the path is a regular file (a FIFO would block
forever), and the size its header declares is at most ``MAX_IMAGE_PIXELS`` (a forged
PNG header claiming 60000 x 60000 px must not allocate 7 GB).  Decoder chatter
(libpng, OpenEXR) is silenced; the caller prints one line.
"""
from __future__ import annotations

import contextlib
import os
import struct
import sys
from pathlib import Path

import numpy as np

from edgetruth.errors import InputError
from edgetruth.fileio import check_input_file

#: Largest image edgetruth reads (pixels): 2^27 ~ 11585^2; the refinement keeps several float64 copies.
MAX_IMAGE_PIXELS = 1 << 27
# OpenCV's own decoder limit (read on first use), for formats whose header we do not parse
os.environ.setdefault("OPENCV_IO_MAX_IMAGE_PIXELS", str(MAX_IMAGE_PIXELS))
os.environ.setdefault("OPENCV_LOG_LEVEL", "ERROR")

import cv2  # noqa: E402  (after the environment above)

SUFFIXES = (".png", ".tif", ".tiff", ".jpg", ".jpeg", ".pgm", ".bmp", ".exr", ".npy")


@contextlib.contextmanager
def quiet_stderr():
    """Silence file descriptor 2 (C libraries such as libpng or OpenEXR print diagnostics there);
    our one-line error is printed after this block."""
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


def header_size(path: Path) -> tuple[int, int] | None:
    """(width, height) from a PNG or JPEG header, None for other formats (or unreadable headers)."""
    with open(path, "rb") as fh:
        head = fh.read(32)
        if head[:8] == b"\x89PNG\r\n\x1a\n" and head[12:16] == b"IHDR":
            return struct.unpack(">II", head[16:24])
        if head[:2] == b"\xff\xd8":  # JPEG: walk the markers to the first start-of-frame
            fh.seek(2)
            while True:
                b = fh.read(1)
                while b and b != b"\xff":
                    b = fh.read(1)
                while b == b"\xff":
                    b = fh.read(1)
                if not b:
                    return None
                marker = b[0]
                if marker in (0xD8, 0x01) or 0xD0 <= marker <= 0xD7:
                    continue
                seg = fh.read(2)
                if len(seg) < 2:
                    return None
                (length,) = struct.unpack(">H", seg)
                if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
                    body = fh.read(5)
                    if len(body) < 5:
                        return None
                    h, w = struct.unpack(">HH", body[1:5])
                    return w, h
                fh.seek(length - 2, 1)
    return None


def check_size(path: Path, width: int, height: int) -> None:
    if width <= 0 or height <= 0 or width * height > MAX_IMAGE_PIXELS:
        raise InputError(f"{path}: declares {width} x {height} pixels (limit {MAX_IMAGE_PIXELS:,} pixels); "
                         "the file is corrupt or too large: crop or downsample it")


def _read_npy(p: Path) -> np.ndarray:
    try:
        arr = np.load(p, mmap_mode="r", allow_pickle=False)
    except Exception as exc:
        raise InputError(f"{p}: not a readable .npy array ({exc.__class__.__name__}); re-save it with numpy.save") from None
    if arr.size > MAX_IMAGE_PIXELS:
        check_size(p, int(arr.shape[1]) if arr.ndim > 1 else int(arr.size), int(arr.shape[0]))
    return np.array(arr)


def _read_exr(p: Path) -> np.ndarray:
    import OpenEXR

    try:
        with quiet_stderr():
            with OpenEXR.File(str(p), header_only=True) as f:
                (x0, y0), (x1, y1) = (tuple(v) for v in f.header()["dataWindow"])
            check_size(p, int(x1 - x0 + 1), int(y1 - y0 + 1))
            with OpenEXR.File(str(p)) as f:
                chans = f.channels()
                return np.asarray(chans[next(iter(chans))].pixels)
    except InputError:
        raise
    except Exception as exc:
        raise InputError(f"{p}: not a readable EXR file ({exc.__class__.__name__}); check the file is complete") from None


def read_gray(path, channel: str = "luma") -> np.ndarray:
    """Read a gray image (PNG/TIFF/JPEG/PGM 8- or 16-bit, EXR float, or .npy) without changing its values.

    Colour images are rejected rather than silently converted: the conversion weights
    change edge positions, so the user should choose them."""
    p = check_input_file(path, "image")
    suffix = p.suffix.lower()
    if suffix == ".npy":
        return _read_npy(p)  # an array is taken as it is; edgetruth.locate checks its shape and values
    if suffix == ".exr":
        img = _read_exr(p)
    else:
        size = header_size(p)
        if size is not None:
            check_size(p, *size)
        try:
            with quiet_stderr():
                img = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
        except cv2.error:
            img = None
        if img is None:
            raise InputError(f"{p}: cannot be decoded as an image (corrupt, truncated, too large or unsupported); "
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
