"""How a photo's stored values become the values the board study locates edges on (``--tone``).

An edge locator finds a blurred step's mid-level.  In linear light that is the edge for any symmetric blur; in
stored values that went through a camera's tone curve it is not: the curve lifts the dark half of the step,
so the mid-level moves towards the dark side and a dark square images small (docs/board.md, "The photos'
dark squares image small").  Decoding the stored values back to linear light before locating undoes that.

Tones (``parse_tone``):

- ``stored`` (default): the values as stored;
- ``srgb``: decoded with the sRGB curve (IEC 61966-2-1), as a camera that follows the standard stores them;
- ``power:G``: ``full · (v / full) ** G``, a pure power law with the black at 0 (G ≈ 2.2 is a display gamma);
- ``auto[:METHOD]`` (chessboards only): the power G at which METHOD's own side lines put each dark square's
  corners on the junctions (``tone_fit.estimate_power``), where the two squares' grid lines meet whatever the
  tone.  Default METHOD: ERF4P-fixed11 (``grid_corners.DEFAULT_METHOD``).

``full`` is the full scale of the stored values (``image_io.full_scale``: 255 for 8-bit, 65535 for 16-bit, 1 for
floats).  The decoded values keep that scale, so the study's thresholds read them alike.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from edgetruth.errors import InputError
from edgetruth.render.sensor.pipeline import srgb_decode


KINDS = ("stored", "srgb", "power", "auto")
#: the powers ``power:G`` accepts (and ``auto`` searches): beyond them a tone curve is not a camera's
POWER_RANGE = (0.4, 3.0)


@dataclass(frozen=True)
class Tone:
    """A tone to decode stored values with: ``kind`` (``KINDS``), the power for ``power``, the method for ``auto``."""

    kind: str = "stored"
    power: float | None = None
    method: str | None = None

    @property
    def spec(self) -> str:
        """The option's text that gives this tone back (``parse_tone``)."""
        if self.kind == "power":
            return f"power:{self.power:g}"
        if self.kind == "auto":
            return f"auto:{self.method}"
        return self.kind

    def describe(self, full: float | None = 255.0) -> str:
        """One phrase for a report; ``full``: the photos' full scale (None: they differ)."""
        if self.kind == "stored":
            return "the stored values, as stored"
        if self.kind == "srgb":
            return "the stored values decoded with the sRGB curve (IEC 61966-2-1)"
        if self.kind == "power":
            f = "full" if full is None else f"{full:g}"
            return f"the stored values v decoded as {f}·(v/{f})^{self.power:.3g}"
        return f"a power estimated so that {self.method}'s own corners meet the junctions"


def parse_tone(text: str | None, default_method: str = "erf4p_fixed11") -> Tone:
    """``stored`` | ``srgb`` | ``power:G`` | ``auto[:METHOD]`` -> ``Tone`` (module docstring); a bad value is an
    ``InputError`` naming it and the choices.  METHOD is checked by the caller (it must exist and be camera-free)."""
    raw = "stored" if text is None else str(text).strip()
    kind, _, arg = raw.partition(":")
    kind = kind.lower()
    if kind in ("stored", "srgb") and not arg:
        return Tone(kind)
    if kind == "power":
        try:
            g = float(arg)
        except ValueError:
            g = float("nan")
        lo, hi = POWER_RANGE
        if not lo <= g <= hi:
            raise InputError(f"--tone {raw}: the power must be a number from {lo:g} to {hi:g} (e.g. power:2.2)")
        return Tone("power", power=g)
    if kind == "auto":
        return Tone("auto", method=arg or default_method)
    raise InputError(f"--tone {raw}: unknown tone; choose stored, srgb, power:G (e.g. power:2.2) or auto[:METHOD]")


def decode(image: np.ndarray, tone: Tone, full: float) -> np.ndarray:
    """``image``'s stored values decoded by ``tone`` (float64, on the same full scale ``full``); ``stored`` returns
    ``image`` itself.  Values outside [0, full] are clipped first (a curve is defined on that range only)."""
    if tone.kind == "stored":
        return image
    if tone.kind == "auto":
        raise ValueError("an auto tone is estimated first (tone_fit.estimate_power), then decoded as a power")
    v = np.clip(np.asarray(image, np.float64) / full, 0.0, 1.0)
    if tone.kind == "srgb":
        return full * srgb_decode(v)
    return full * np.power(v, tone.power)
