"""Reading images (gray images and colour photographs) as one gray array, with one clear error per failure mode.

Checked before anything is decoded: the path is a regular file (a FIFO would block
forever), and the size its header declares is at most ``MAX_IMAGE_PIXELS`` (a forged
PNG header claiming 60000 x 60000 px must not allocate 7 GB).  Decoder chatter
(libpng, OpenEXR) is silenced; the caller prints one line.

Photos: 8- and 16-bit PNG (palette PNGs are expanded by OpenCV), JPEG, TIFF, PGM, BMP
(OpenCV, ``IMREAD_UNCHANGED``: the stored values, no depth or colour conversion), EXR
(float) and ``.npy``.  Colour becomes gray by one rule, ``GRAY_RULES`` (see ``read_gray``).
The EXIF orientation tag (JPEG APP1, PNG ``eXIf``, TIFF's own tag 274) is honoured: the
tag is read by the small TIFF-directory parser below (an EXIF block is a TIFF directory
in all three formats), and the rotation/flip is applied here with numpy, the same way
for every format.  Why not OpenCV's flags: ``IMREAD_UNCHANGED`` ignores the tag for
JPEG and PNG, and the flags that honour it (``IMREAD_ANYCOLOR | IMREAD_ANYDEPTH``) drop the
alpha channel, which must be checked; OpenCV 5.0's TIFF decoder applies orientations 2-4
itself and fails outright on 5-8 (``imread`` returns nothing), so a TIFF whose tag is not
1 is decoded from memory with the tag set to 1.  Why not Pillow: it decodes 16-bit colour
TIFF and PNG to 8 bits, and reading a PNG's ``eXIf`` through it decodes the whole image.
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


def _read_exr(p: Path) -> tuple[np.ndarray, str]:
    """(pixels, channel order): ``R, G, B`` (and ``A``) as an (H, W, 3 or 4) array in RGB(A) order,
    else ``Y`` (and ``A``), else the file's first channel other than ``A``."""
    import OpenEXR  # lazy: OpenEXR is only needed to write EXR

    try:
        with quiet_stderr():
            with OpenEXR.File(str(p), header_only=True) as f:
                (x0, y0), (x1, y1) = (tuple(v) for v in f.header()["dataWindow"])
            check_size(p, int(x1 - x0 + 1), int(y1 - y0 + 1))
            with OpenEXR.File(str(p), separate_channels=True) as f:
                chans = {name: np.asarray(c.pixels) for name, c in f.channels().items()}
    except InputError:
        raise
    except Exception as exc:
        raise InputError(f"{p}: not a readable EXR file ({exc.__class__.__name__}); check the file is complete") from None
    alpha = [chans["A"]] if "A" in chans else []
    if {"R", "G", "B"} <= set(chans):
        return np.dstack([chans["R"], chans["G"], chans["B"], *alpha]), "RGB"
    if "Y" in chans:
        return (np.dstack([chans["Y"], *alpha]) if alpha else chans["Y"]), "RGB"
    other = [v for k, v in chans.items() if k != "A"]
    return (other or list(chans.values()))[0], "RGB"


# --- EXIF orientation ------------------------------------------------------------------------------
#: EXIF/TIFF orientation tag value -> the transform that shows the stored pixels upright (tag 274;
#: 2-4 flips and a half turn, 5 the main-diagonal transpose, 6 a quarter turn clockwise, 7 the
#: anti-diagonal transpose, 8 a quarter turn anticlockwise)
ORIENTATIONS = {
    1: lambda a: a,
    2: lambda a: a[:, ::-1],
    3: lambda a: a[::-1, ::-1],
    4: lambda a: a[::-1],
    5: lambda a: np.swapaxes(a, 0, 1),
    6: lambda a: np.rot90(a, -1),
    7: lambda a: np.swapaxes(a[::-1, ::-1], 0, 1),
    8: lambda a: np.rot90(a, 1),
}
_ORIENTATION_TAG = 274


def _ifd0_orientation(fh, base: int) -> tuple[int, int | None]:
    """(orientation, absolute file offset of its 2-byte value) from the first directory of the TIFF
    structure that starts at ``base`` (a TIFF file: 0; an EXIF block: after ``Exif\\0\\0``);
    (1, None) when there is no valid tag."""
    fh.seek(base)
    head = fh.read(16)
    order = {b"II": "<", b"MM": ">"}.get(head[:2])
    if order is None or len(head) < 8:
        return 1, None
    (magic,) = struct.unpack(order + "H", head[2:4])
    if magic == 42:  # classic TIFF: 2-byte entry count, 12-byte entries, 4-byte offsets
        (ifd,) = struct.unpack(order + "I", head[4:8])
        count_fmt, entry_size, value_at = "H", 12, 8
    elif magic == 43 and len(head) == 16:  # BigTIFF: 8-byte count, 20-byte entries
        (ifd,) = struct.unpack(order + "Q", head[8:16])
        count_fmt, entry_size, value_at = "Q", 20, 12
    else:
        return 1, None
    fh.seek(base + ifd)
    raw = fh.read(struct.calcsize(count_fmt))
    if len(raw) < struct.calcsize(count_fmt):
        return 1, None
    (n,) = struct.unpack(order + count_fmt, raw)
    entries = fh.read(min(n, 4096) * entry_size)
    for k in range(len(entries) // entry_size):
        e = entries[k * entry_size:(k + 1) * entry_size]
        tag, typ = struct.unpack(order + "HH", e[:4])
        if tag == _ORIENTATION_TAG and typ == 3:  # SHORT
            (value,) = struct.unpack(order + "H", e[value_at:value_at + 2])
            offset = base + ifd + struct.calcsize(count_fmt) + k * entry_size + value_at
            return (value if value in ORIENTATIONS else 1), offset
    return 1, None


def _jpeg_exif_base(fh) -> int | None:
    """File offset of the TIFF header inside a JPEG's EXIF (APP1) segment, None without one."""
    fh.seek(2)
    while True:
        b = fh.read(2)
        if len(b) < 2 or b[0] != 0xFF:
            return None
        marker = b[1]
        if marker == 0xFF:  # fill byte
            fh.seek(-1, 1)
            continue
        if marker in (0xD8, 0x01) or 0xD0 <= marker <= 0xD7:
            continue
        if marker in (0xDA, 0xD9):  # image data or end: no EXIF before it
            return None
        seg = fh.read(2)
        if len(seg) < 2:
            return None
        (length,) = struct.unpack(">H", seg)
        if marker == 0xE1:
            if fh.read(6) == b"Exif\x00\x00":
                return fh.tell()
            fh.seek(length - 8, 1)
        else:
            fh.seek(length - 2, 1)


def _png_exif_base(fh) -> int | None:
    """File offset of a PNG's ``eXIf`` chunk data (a TIFF structure), None without one."""
    fh.seek(8)
    while True:
        head = fh.read(8)
        if len(head) < 8:
            return None
        length, kind = struct.unpack(">I", head[:4])[0], head[4:]
        if kind == b"eXIf":
            return fh.tell()
        if kind == b"IEND":
            return None
        fh.seek(length + 4, 1)  # data and CRC


def exif_orientation(path) -> tuple[int, str, int | None]:
    """(orientation 1-8, container 'jpeg'/'png'/'tiff'/'', file offset of the tag's value) of an image
    file; (1, ..., None) when it has no orientation tag or its EXIF block is unreadable."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(8)
            if head[:2] == b"\xff\xd8":
                kind, base = "jpeg", _jpeg_exif_base(fh)
            elif head == b"\x89PNG\r\n\x1a\n":
                kind, base = "png", _png_exif_base(fh)
            elif head[:4] in (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+"):
                kind, base = "tiff", 0
            else:
                return 1, "", None
            if base is None:
                return 1, kind, None
            value, offset = _ifd0_orientation(fh, base)
            return value, kind, offset
    except (OSError, struct.error, ValueError):
        return 1, "", None


def jpeg_is_complete(path) -> bool:
    """A JPEG file holds its end-of-image marker after its first scan.  libjpeg decodes a truncated
    JPEG without an error (the missing rows come out mid-gray, with a warning on stderr), so
    ``read_gray`` checks this first.  Data appended after the end marker (a phone's motion-photo
    video, a trailer) is allowed."""
    data = Path(path).read_bytes()
    pos = 2
    while pos + 4 <= len(data):  # the header segments, up to the first start-of-scan
        if data[pos] != 0xFF:
            return False
        marker = data[pos + 1]
        if marker == 0xFF:
            pos += 1
            continue
        if marker in (0xD8, 0x01) or 0xD0 <= marker <= 0xD7:
            pos += 2
            continue
        if marker == 0xD9:
            return False  # ends before any image data
        (length,) = struct.unpack(">H", data[pos + 2:pos + 4])
        pos += 2 + length
        if marker == 0xDA:
            # entropy-coded data never holds 0xFF 0xD9 (a data 0xFF is followed by 0x00)
            return data.find(b"\xff\xd9", pos) >= 0
    return False


def _decode(p: Path) -> np.ndarray | None:
    """OpenCV's decode of the stored values (``IMREAD_UNCHANGED``), turned upright by the EXIF tag."""
    orientation, kind, offset = exif_orientation(p)
    if kind == "jpeg" and not jpeg_is_complete(p):
        return None
    with quiet_stderr():
        if kind == "tiff" and orientation != 1:
            # OpenCV's TIFF decoder would apply (2-4) or choke on (5-8) the tag: decode with it set to 1
            data = bytearray(p.read_bytes())
            order = "<" if data[:2] == b"II" else ">"
            data[offset:offset + 2] = struct.pack(order + "H", 1)
            img = cv2.imdecode(np.frombuffer(bytes(data), np.uint8), cv2.IMREAD_UNCHANGED)
        else:
            img = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
    if img is None or orientation == 1:
        return img
    return np.ascontiguousarray(ORIENTATIONS[orientation](img))


# --- colour -> gray ---------------------------------------------------------------------------------
#: The rules ``read_gray(channel=...)`` (and the CLI's ``--channel``) offer for colour photos.
GRAY_RULES = {
    "luma": "0.299 R + 0.587 G + 0.114 B (ITU-R BT.601 luma, OpenCV's weights) in float64 on the stored "
            "values, not rounded",
    "r": "the red channel as stored",
    "g": "the green channel as stored",
    "b": "the blue channel as stored",
}
#: BT.601 luma weights of R, G, B
LUMA_WEIGHTS_RGB = (0.299, 0.587, 0.114)


def full_scale(dtype) -> float:
    """The value of full white for stored values of ``dtype``: its largest integer (255 for 8-bit, 65535 for
    16-bit), or 1.0 for floats (EXR, float arrays)."""
    dtype = np.dtype(dtype)
    return float(np.iinfo(dtype).max) if np.issubdtype(dtype, np.integer) else 1.0


def to_gray(img: np.ndarray, channel: str = "luma", order: str = "BGR", name: str = "image") -> np.ndarray:
    """One gray 2-D array from a decoded (H, W), (H, W, 1), gray + alpha (H, W, 2), colour (H, W, 3) or
    colour + alpha (H, W, 4) array whose colour channels are in ``order`` ('BGR' as OpenCV decodes,
    'RGB' as EXR stores them).  The rule is ``read_gray``'s."""
    if channel not in GRAY_RULES:
        raise InputError(f"channel {channel!r}: unknown gray rule; choose one of {', '.join(GRAY_RULES)}")
    if img.ndim != 3:
        return img
    n = img.shape[2]
    if n in (2, 4):
        alpha = img[..., -1]
        level = full_scale(img.dtype)
        clear = int(np.count_nonzero(alpha != level))
        if clear:
            raise InputError(f"{name}: {clear} of {alpha.size} pixels are not fully opaque (alpha below {level:g}); "
                             "flatten the photo onto its background or drop the alpha channel first")
        img = img[..., :-1]
        n -= 1
    if n == 1:
        return img[..., 0]
    if n != 3:
        raise InputError(f"{name}: {img.shape[2]} channels; expected gray, gray + alpha, colour or colour + alpha")
    c0 = img[..., 0]
    if np.array_equal(c0, img[..., 1]) and np.array_equal(c0, img[..., 2]):
        return np.ascontiguousarray(c0)  # a gray image stored as colour: unchanged, dtype kept
    rgb = (2, 1, 0) if order == "BGR" else (0, 1, 2)
    if channel != "luma":
        return np.ascontiguousarray(img[..., rgb["rgb".index(channel)]])
    r, g, b = (img[..., i].astype(np.float64) for i in rgb)
    wr, wg, wb = LUMA_WEIGHTS_RGB
    return wr * r + wg * g + wb * b


def read_gray(path, channel: str = "luma") -> np.ndarray:
    """Read an image file as one gray 2-D array of its stored values (``read_gray_scaled`` without the scale)."""
    return read_gray_scaled(path, channel)[0]


def read_gray_scaled(path, channel: str = "luma") -> tuple[np.ndarray, float]:
    """Read an image file as one gray 2-D array of its stored values, upright by its EXIF orientation.

    Formats: PNG 8/16-bit (palette PNGs too), JPEG, TIFF, PGM, BMP, EXR (float) and ``.npy`` (an
    array is taken as it is).  The size is the file's own.

    Colour becomes gray by ONE rule, ``channel``:

    - ``"luma"`` (default): 0.299 R + 0.587 G + 0.114 B, computed in float64 on the stored values and
      not rounded, so a 16-bit photo keeps its precision; the result is float64;
    - ``"r"``, ``"g"``, ``"b"``: that channel as stored (its dtype kept; OpenCV's BGR order is
      taken care of).

    A gray image, or a colour image whose three channels are all equal (a gray palette PNG such as
    Zhang's), is returned unchanged with its dtype, whatever ``channel`` says.  An alpha channel
    (gray + alpha, colour + alpha) that is fully opaque (255, 65535, or 1.0 for float) is dropped; any
    other alpha is refused (``InputError``): what lies behind a transparent pixel is unknown.

    Returns the gray array and the full scale of the file's stored values (``full_scale`` of its dtype before
    any gray rule: 255 for an 8-bit colour photo read as float luma).
    """
    if channel not in GRAY_RULES:
        raise InputError(f"channel {channel!r}: unknown gray rule; choose one of {', '.join(GRAY_RULES)}")
    p = check_input_file(path, "image")
    suffix = p.suffix.lower()
    if suffix == ".npy":
        arr = _read_npy(p)  # an array is taken as it is; edgetruth.locate checks its shape and values
        return arr, full_scale(arr.dtype)
    if suffix == ".exr":
        img, order = _read_exr(p)
    else:
        size = header_size(p)
        if size is not None:
            check_size(p, *size)
        try:
            img = _decode(p)
        except cv2.error:
            img = None
        if img is None:
            raise InputError(f"{p}: cannot be decoded as an image (corrupt, truncated, too large or unsupported); "
                             "use PNG, TIFF, JPEG, EXR or .npy")
        order = "BGR"
    return to_gray(img, channel, order, name=str(p)), full_scale(img.dtype)
