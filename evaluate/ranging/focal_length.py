"""The focal length in pixels without a calibration board: from reference photos or from EXIF.

**Reference photos** (a photo at a known distance Z_ref of the same target): fx = Z_ref * l / S with l the
target's image size measured by each method, so each method has its own fx (``reference_fx``).  A
method's own scale error (it measures every l a little large or small) then cancels at the reference
distance: its Z is exact there and its errors elsewhere are those of *ratios* of sizes (l_ref / l), plus
the reference distance's own error, which scales every Z alike.

**EXIF** (``exif_fx``): the tags FocalLength (mm) and either FocalPlaneXResolution with its unit
(fx = f * pixels per mm on the sensor) or FocalLengthIn35mmFilm (fx = f35 * sqrt(W^2 + H^2) / 43.27:
the 35 mm equivalent is defined on the diagonal of a 36 x 24 mm frame; a camera that scales by the
width instead, fx = f35 * W / 36, differs by ~4 % on a 4:3 sensor).  Either is *approximate*: a lens
focused closer than infinity has a longer focal length than its nominal one, phones round f35 to a
whole millimetre, and a cropped or resized photo no longer matches the focal-plane resolution.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from PIL import Image, UnidentifiedImageError

from edgetruth.errors import InputError


TAG_EXIF_IFD = 0x8769
TAG_FOCAL_LENGTH = 37386
TAG_FOCAL_35MM = 41989
TAG_FP_XRES = 41486
TAG_FP_UNIT = 41488
#: FocalPlaneResolutionUnit -> millimetres per unit (2 inch, 3 cm; 4 mm and 5 um as some raw converters write)
FP_UNIT_MM = {2: 25.4, 3: 10.0, 4: 1.0, 5: 1e-3}
FULL_FRAME_DIAGONAL_MM = math.hypot(36.0, 24.0)  # 43.27


def _value(v) -> float:
    """An EXIF rational (Pillow's IFDRational, a (num, den) pair or a number) as a float (nan when 0/0)."""
    if isinstance(v, tuple) and len(v) == 2:
        return float(v[0]) / float(v[1]) if v[1] else float("nan")
    try:
        return float(v)
    except (TypeError, ValueError, ZeroDivisionError):
        return float("nan")


def read_exif_focal(path: str | Path) -> dict:
    """The focal-length tags of a photo's EXIF ({} when it has none): focal_mm, focal_35mm, fp_xres, fp_unit."""
    try:
        with Image.open(path) as im:  # lazy: the header only, no pixels decoded
            exif = im.getexif()
            sub = exif.get_ifd(TAG_EXIF_IFD)
    except (OSError, UnidentifiedImageError, ValueError, SyntaxError):
        return {}
    tags = {**{k: v for k, v in exif.items()}, **sub}
    out = {}
    for key, tag in (("focal_mm", TAG_FOCAL_LENGTH), ("focal_35mm", TAG_FOCAL_35MM), ("fp_xres", TAG_FP_XRES),
                     ("fp_unit", TAG_FP_UNIT)):
        if tag in tags:
            out[key] = _value(tags[tag])
    return out


def fx_from_tags(tags: dict, width_px: int, height_px: int, where: str = "photo") -> tuple[float, str]:
    """(fx in px, its source in words) from ``read_exif_focal``'s tags of a ``width_px`` x ``height_px`` photo."""
    if "focal_mm" not in tags:
        raise InputError(f"{where}: no focal length (FocalLength) in its EXIF; give --calibration or "
                         "--reference-photo instead of --exif-focal-length")
    f = tags["focal_mm"]
    if not (math.isfinite(f) and f > 0):
        raise InputError(f"{where}: its EXIF FocalLength is {f:g} mm (zero or unreadable); give --calibration or "
                         "--reference-photo instead of --exif-focal-length")
    xres, unit = tags.get("fp_xres", float("nan")), int(tags.get("fp_unit", 2) or 2)
    if math.isfinite(xres) and xres > 0 and unit in FP_UNIT_MM:
        px_per_mm = xres / FP_UNIT_MM[unit]
        return f * px_per_mm, (f"EXIF FocalLength {f:g} mm x FocalPlaneXResolution {px_per_mm:.2f} px/mm "
                               "(approximate: nominal focal length; wrong if the photo was resized or cropped)")
    f35 = tags.get("focal_35mm", float("nan"))
    if math.isfinite(f35) and f35 > 0:
        fx = f35 * math.hypot(width_px, height_px) / FULL_FRAME_DIAGONAL_MM
        return fx, (f"EXIF FocalLengthIn35mmFilm {f35:g} mm on the 43.27 mm diagonal (FocalLength {f:g} mm; "
                    "approximate: f35 is rounded to a millimetre and some makers scale by the width, ~4 % apart)")
    raise InputError(f"{where}: its EXIF has FocalLength {f:g} mm but neither FocalLengthIn35mmFilm nor "
                     "FocalPlaneXResolution, so the sensor's size is unknown; give --calibration or --reference-photo")


def exif_fx(path: str | Path, width_px: int, height_px: int, where: str = "photo") -> tuple[float, str]:
    """fx (px) of a photo from its EXIF, and where it came from (see the module docstring)."""
    return fx_from_tags(read_exif_focal(path), width_px, height_px, where)


def reference_fx(ref_rows: list[dict], size_m_of: dict) -> dict:
    """Per method, fx = mean over the reference photos of Z_ref * l / S (px): ``ref_rows`` are ranging rows
    (``size_px``, ``true_distance_m``, ``image``, ``method``, ``status``); ``size_m_of``: image -> S (m).
    Returns {method: {"fx_px", "n", "per_photo": {image: fx}}} for the methods that sized every reference."""
    out: dict = {}
    for r in ref_rows:
        l_px = float(r.get("size_px", float("nan")))
        if r.get("status") != "ok" or not (np.isfinite(l_px) and l_px > 0):
            out.setdefault(r["method"], {"per_photo": {}, "missing": []})["missing"].append(r["image"])
            continue
        fx = float(r["true_distance_m"]) * l_px / size_m_of[r["image"]]
        out.setdefault(r["method"], {"per_photo": {}, "missing": []})["per_photo"][r["image"]] = fx
    for m, v in out.items():
        fxs = list(v["per_photo"].values())
        v["fx_px"] = float(np.mean(fxs)) if fxs and not v["missing"] else float("nan")
        v["n"] = len(fxs)
    return out


def apply_fx(rows: list[dict], fx_by_method: dict, size_m_of: dict) -> list[dict]:
    """Test rows re-ranged with each method's own fx: z_hat = fx S / l, errors against the reference
    distance; the pose estimate (which needs the whole camera matrix) is left out (nan)."""
    out = []
    for r in rows:
        r = dict(r)
        fx = fx_by_method.get(r["method"], {}).get("fx_px", float("nan"))
        l_px = float(r.get("size_px", float("nan")))
        if r.get("status") == "ok":
            if not np.isfinite(fx):
                r.update(status="not ranged: the method did not size the reference photo(s)")
                z = float("nan")
            else:
                z = fx * size_m_of[r["image"]] / l_px
            zr = float(r["true_distance_m"])
            r.update(z_hat_m=z, error_cm=100.0 * (z - zr), rel_error_pct=100.0 * abs(z - zr) / zr,
                     z_pose_m=float("nan"), error_pose_cm=float("nan"))
        out.append(r)
    return out
