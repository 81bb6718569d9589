"""A chessboard photo set's tone curve, measured at its junctions (``--tone auto``).

A board has two gray levels, so its photos alone do not show the camera's tone curve by levels.  A chessboard
shows it by geometry: at an inner corner two dark squares touch, and the two grid lines through both halves
meet on the corner whatever the tone (a tone curve moves both halves' edges by opposite amounts), while each
square's own side lines move with the tone: a curve that lifts the dark half of a blurred step puts the square's
own corners inside the junction (docs/board.md).  So the power G of ``tone.decode`` at which a method's own
corners meet the junctions on average is the power law that makes the photos' edges symmetric steps again:

- ``offset(G)``: the mean signed distance (px) of every dark square's own corner from its junction, outward,
  with the stored values decoded as ``full · (v / full) ** G`` (``summary.outward_offsets``);
- the estimate is the root of ``offset(G)`` in ``tone.POWER_RANGE`` (``scipy.optimize.brentq``);
- per photo, its own root from the local slope at the estimate (finite difference ± ``SLOPE_STEP``), with its
  standard error (the SE of the photo's mean offset over the slope), and a 95 % percentile bootstrap CI of the
  estimate resampling photos (``BOOTSTRAP``, seeded);
- whether one power describes every photo: Cochran's Q of the per-photo roots about the estimate (χ² with P - 1
  degrees of freedom), and Spearman's ρ between the per-photo roots and each photo's white level (the median
  stored value at the light squares' centres), since a tone curve that is not a power law (a highlight shoulder,
  clipping) shows as a power that changes with the exposure; and, as a second sign of a shoulder, Spearman's ρ
  between the white level and the white flats' noise SD (``square_levels``).

The squares are found once on the stored values (OpenCV's corner grid; the tone moves them by far less than the
candidate margin); the Canny candidates and the method's points are recomputed at every G.  What the power
cannot tell apart: a tone curve from flare or any other effect that lifts the dark side of an edge; a black
level above zero (the power law has its black at 0).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq
from scipy.stats import chi2

from edgetruth.errors import InputError
from edgetruth.evaluate.board.detect import chessboard as cb
from edgetruth.evaluate.board.detect.levels import square_levels
from edgetruth.evaluate.board.detect.squares import MIN_FOUND_SHARE, board_candidates, find_board
from edgetruth.evaluate.board.measure.rows import method_row
from edgetruth.evaluate.board.measure.summary import outward_offsets
from edgetruth.evaluate.board.sides.lines import square_map
from edgetruth.evaluate.board.tone.values import POWER_RANGE, Tone, decode
from edgetruth.evaluate.stats import spearman


#: the half step (in G) of the finite difference that gives each photo's slope d offset / d G
SLOPE_STEP = 0.05
#: bootstrap resamples of the photos for the estimate's CI, and their seed
BOOTSTRAP, SEED = 2000, 0
#: brentq's tolerance on G: far below the per-photo roots' standard errors (~0.05)
XTOL = 1e-3
#: below this p, Cochran's Q says the photos' powers differ: no one power describes them
HETEROGENEITY_ALPHA = 0.01


@dataclass
class PowerFit:
    """The estimated power (``estimate_power``) and how it was found."""

    power: float
    ci: tuple[float, float]
    method: str
    photos: list[str]
    #: each photo's own root (its offset's zero from the local slope at ``power``) and its standard error
    per_photo: list[float]
    per_photo_se: list[float]
    #: each photo's flat levels and noise (``square_levels``)
    levels: list
    #: Cochran's Q of the per-photo roots about ``power`` and its p (χ², P - 1 dof)
    q_stat: float
    q_p: float
    #: Spearman's ρ (and p) between the per-photo roots and the white levels
    rho_white: float
    rho_white_p: float
    #: mean outward offset (px) of the method's own corners at the stored values (G = 1) and at ``power``
    offset_stored_px: float
    offset_fit_px: float
    evaluations: int

    def tone(self) -> Tone:
        return Tone("power", power=self.power)

    @property
    def white_levels(self) -> list[float]:
        return [lv.white for lv in self.levels]

    @property
    def dark_levels(self) -> list[float]:
        return [lv.dark for lv in self.levels]

    @property
    def rho_white_sd(self) -> tuple[float, float]:
        """Spearman's ρ (and p) between the white level and the white flats' noise SD: a shoulder compresses the
        noise where it compresses the edges, while shot noise alone makes the SD rise with the level."""
        return _spearman(self.white_levels, [lv.white_sd for lv in self.levels])

    @property
    def one_power_fits(self) -> bool:
        """Whether the per-photo roots agree with one power (Cochran's Q, p >= ``HETEROGENEITY_ALPHA``)."""
        return bool(self.q_p >= HETEROGENEITY_ALPHA)

    def as_json(self) -> dict:
        return {"power": self.power, "ci95": list(self.ci), "method": self.method,
                "per_photo": dict(zip(self.photos, self.per_photo)),
                "per_photo_se": dict(zip(self.photos, self.per_photo_se)),
                "dark_level": dict(zip(self.photos, (lv.dark for lv in self.levels))),
                "white_level": dict(zip(self.photos, (lv.white for lv in self.levels))),
                "dark_sd": dict(zip(self.photos, (lv.dark_sd for lv in self.levels))),
                "white_sd": dict(zip(self.photos, (lv.white_sd for lv in self.levels))),
                "spearman_rho_white_sd": self.rho_white_sd[0], "spearman_p_white_sd": self.rho_white_sd[1],
                "cochran_q": self.q_stat, "cochran_q_p": self.q_p, "one_power_fits": self.one_power_fits,
                "spearman_rho_power_white": self.rho_white, "spearman_p_power_white": self.rho_white_p,
                "offset_stored_px": self.offset_stored_px, "offset_fit_px": self.offset_fit_px,
                "evaluations": self.evaluations,
                "definition": "power G of full*(v/full)**G at which the method's own corners meet the junctions "
                              "(mean outward offset 0); evaluate/board/tone/fit.py"}


def require_chessboard(model) -> None:
    """An ``InputError`` unless ``model`` is a chessboard's: only its junctions show the tone."""
    if model.pattern is None:
        raise InputError("--tone auto: measures the tone at a chessboard's junctions, and this board has separate "
                         "squares; give --tone srgb or power:G (e.g. power:2.2), or --pattern for a chessboard")


def estimate_power(inp, images: list[np.ndarray], full_scales: list[float], label: str, method: str,
                   options: dict) -> PowerFit:
    """The power G (module docstring) for the photos ``images`` (stored values, full scales ``full_scales``) of the
    chessboard ``inp.model``, from ``method`` (with ``options``; ``label`` names it).  An ``InputError`` when the
    board is not a chessboard, too few photos show it, or no power in ``POWER_RANGE`` makes the offset 0."""
    require_chessboard(inp.model)
    found, _, model = find_board(inp, images, progress=False)
    keep = [i for i, c in enumerate(found) if c is not None and c.found.sum() >= MIN_FOUND_SHARE * len(model)]
    if len(keep) < 3:
        raise InputError(f"--tone auto: the chessboard was found on {len(keep)} photo(s); need 3 to measure the "
                         "tone: give --tone stored, srgb or power:G")
    quads = [found[i].corners for i in keep]
    smaps = [square_map(q, images[i].shape) for q, i in zip(quads, keep)]
    jn = cb.junctions(model)
    cache: dict[float, tuple] = {}

    def at(g: float) -> tuple[np.ndarray, np.ndarray, float]:
        """Each photo's mean outward offset (px) at power g and its standard error (P,), and the pooled mean."""
        if g not in cache:
            decoded = [decode(images[i], Tone("power", power=g), full_scales[i]) for i in keep]
            cands = [board_candidates(img, q, chessboard=True) for img, q in zip(decoded, quads)]
            row = method_row(label, method, options, decoded, cands, quads, smaps, junctions=jn)
            offs = [o[np.isfinite(o)] for o in outward_offsets(row, jn)]
            n = np.array([o.size for o in offs])
            mean = np.array([o.mean() if o.size else np.nan for o in offs])
            se = np.array([o.std(ddof=1) / np.sqrt(o.size) if o.size > 1 else np.nan for o in offs])
            every = np.concatenate(offs)
            cache[g] = (mean, se, float(every.mean()) if n.sum() else float("nan"))
        return cache[g]

    def per_photo(g: float) -> np.ndarray:
        return at(g)[0]

    def pooled(g: float) -> float:
        return at(g)[2]

    lo, hi = POWER_RANGE
    f1 = pooled(1.0)
    if not np.isfinite(f1):
        raise InputError(f"--tone auto: {label} measured no square's own corners on these photos; give --tone "
                         "stored, srgb or power:G")
    a, b = (1.0, hi) if f1 < 0 else (lo, 1.0)
    fa, fb = pooled(a), pooled(b)
    if not (np.isfinite(fa) and np.isfinite(fb)) or fa * fb > 0:
        raise InputError(f"--tone auto: no power from {lo:g} to {hi:g} puts {label}'s own corners on the junctions "
                         f"(mean offset {pooled(lo if f1 > 0 else hi):+.3f} px at the far end): the offset is not a "
                         "tone curve's; give --tone stored or power:G")
    g = float(brentq(pooled, a, b, xtol=XTOL)) if fa * fb < 0 else (a if fa == 0 else b)
    f0, se0, _ = at(g)
    slope = (per_photo(g + SLOPE_STEP) - per_photo(g - SLOPE_STEP)) / (2 * SLOPE_STEP)
    with np.errstate(invalid="ignore", divide="ignore"):
        roots = g - f0 / slope
        root_se = se0 / np.abs(slope)
    ok = np.isfinite(roots) & np.isfinite(root_se) & (root_se > 0)
    rng = np.random.default_rng(SEED)
    if ok.sum() >= 2:
        idx = rng.integers(0, ok.sum(), size=(BOOTSTRAP, int(ok.sum())))
        boot = g - f0[ok][idx].mean(axis=1) / slope[ok][idx].mean(axis=1)
    else:  # no spread to resample
        boot = np.full(1, np.nan)
    q = float(np.sum(((roots[ok] - g) / root_se[ok]) ** 2))
    levels = [square_levels(images[i], qd) for i, qd in zip(keep, quads)]
    white = np.array([lv.white for lv in levels])
    rho, rho_p = _spearman(roots[ok], white[ok])
    return PowerFit(g, (float(np.percentile(boot, 2.5)), float(np.percentile(boot, 97.5))), label,
                    [inp.names[i] for i in keep], [float(r) for r in roots], [float(s) for s in root_se], levels, q,
                    float(chi2.sf(q, max(int(ok.sum()) - 1, 1))), rho, rho_p, f1, pooled(g), len(cache))


def _spearman(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """Spearman's ρ and p (``stats.spearman``: exact for small n); NaN where undefined (fewer than 3 pairs, or
    one side constant)."""
    s = spearman(a, b)
    return s["rho"], s["p"]
