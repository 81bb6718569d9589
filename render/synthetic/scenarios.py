"""The study's synthetic edge scenarios (seed §4.2-4.3): Ideal, Slope, Texture, Asymmetric.

Each image holds one edge (straight, or a circle) with random orientation,
subpixel position, blur, contrast and noise, and comes with its exact ground
truth (``edgetruth.render.edge_truth``).  Images are pure functions of (split, index):
the seed is ``SeedSequence([SPLIT_ID[split], scenario_id, index])``, so the
calibration split never shares a random stream with the test split.

Parameter ranges (documented choices; the seed's method section with its
exact values is not available): blur s ~ U(0.5, 2.0) px, background
A ~ U(20, 60), contrast B ~ U(60, 180) gray levels, noise sigma_n / B ~
U(0.005, 0.03).  Slope: |grad| ~ U(0.5, 2.0) % of B per px in a random
direction.  Texture: 12 random cosines with wavelength 3-12 px and a total
RMS of U(2, 5) % of B.  Asymmetric: s_dark / s_bright ~ LogU(1/3, 3)
excluding ratios within [0.67, 1.5].
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from edgetruth.conventions import principal_point_centred
from edgetruth.errors import InputError
from edgetruth.render.synthetic.analytic import StepProfile, slope_image, step_image, texture_image
from edgetruth.render.edge_truth import CircleEdge, StraightEdge

SCENARIOS = ("ideal", "slope", "texture", "asymmetric")
SPLIT_ID = {"calibration": 1, "test": 2, "bench": 3, "unit": 4}
DEFAULT_SHAPE = (64, 64)


@dataclass
class SyntheticImage:
    """An analytic edge image with its exact truth (``synthetic_image``).

    Attributes
    ----------
    image : numpy.ndarray
        float64 (H, W) gray levels: exact pixel means of the blurred step (plus slope or texture), then noise.
    truth : StraightEdge or CircleEdge
        The true edge: ``signed_distance(x, y)`` in px along the true normal, > 0 on the bright side.
    scenario : str
        ``"ideal"``, ``"slope"``, ``"texture"`` or ``"asymmetric"``.
    params : dict
        The drawn parameters: ``blur_px``, ``A``, ``B`` (gray levels), ``noise_rel`` (noise SD / B),
        ``s_dark``, ``s_bright`` (px), ``kind``, ``split``, ``index`` and the scenario's own.
    """

    image: np.ndarray  # float64 (H, W), gray levels
    truth: object  # StraightEdge | CircleEdge
    scenario: str
    params: dict = field(default_factory=dict)

    def errors(self, x, y) -> np.ndarray:
        """Signed distance of points to the true edge, along the true normal: each point's error.

        Parameters
        ----------
        x, y : array_like
            Points, px, OpenCV convention.

        Returns
        -------
        numpy.ndarray
            px, > 0 on the bright side.
        """
        return self.truth.signed_distance(x, y)


def seed_sequence(split: str, scenario: str, index: int) -> np.random.SeedSequence:
    if split not in SPLIT_ID:
        raise InputError(f"split {split!r}: choose one of {', '.join(SPLIT_ID)}")
    if scenario not in SCENARIOS:
        raise InputError(f"scenario {scenario!r}: choose one of {', '.join(SCENARIOS)}")
    return np.random.SeedSequence([SPLIT_ID[split], SCENARIOS.index(scenario), int(index)])


def render_edge_image(shape, edge, A: float, B: float, s_dark: float, s_bright: float | None = None,
                      noise_sigma: float = 0.0, rng: np.random.Generator | None = None,
                      slope=None, texture=None) -> np.ndarray:
    """A + B * step + slope + texture + N(0, noise_sigma^2); exact pixel means before noise."""
    prof = StepProfile(s_dark, s_dark if s_bright is None else s_bright)
    img = A + B * step_image(shape, edge, prof)
    if slope is not None:
        img = img + slope_image(shape, *slope)
    if texture is not None:
        img = img + texture_image(shape, *texture)
    if noise_sigma > 0:
        if rng is None:
            raise InputError("noise_sigma > 0 needs a seeded numpy Generator (rng=...)")
        img = img + rng.normal(0.0, noise_sigma, size=img.shape)
    return img


def random_edge(rng: np.random.Generator, shape, kind: str):
    h, w = shape
    cx, cy = principal_point_centred(w, h)  # the image centre, OpenCV convention
    if kind == "line":
        return StraightEdge(cx + rng.uniform(-1, 1), cy + rng.uniform(-1, 1),
                            rng.uniform(-np.pi, np.pi))
    if kind == "circle":
        r = rng.uniform(0.2, 0.35) * min(h, w)
        return CircleEdge(cx + rng.uniform(-1, 1), cy + rng.uniform(-1, 1), r,
                          bool(rng.integers(0, 2)))
    raise InputError(f"edge kind {kind!r}: choose 'line' or 'circle'")


def synthetic_image(scenario: str, index: int, split: str = "test", shape=DEFAULT_SHAPE,
                    kind: str | None = None, **overrides) -> SyntheticImage:
    """Image ``index`` of a synthetic scenario: an analytic edge integrated exactly over each pixel, with noise.

    Images are pure functions of (split, scenario, index); the splits never share a random stream. Drawn:
    blur U(0.5, 2) px, background A U(20, 60), contrast B U(60, 180) gray levels, noise SD / B U(0.005, 0.03),
    and the edge's position and angle (a line) or centre and radius (a circle).

    Parameters
    ----------
    scenario : str
        ``"ideal"``, ``"slope"``, ``"texture"`` or ``"asymmetric"``.
    index : int
        The image's index in its split.
    split : str, optional
        ``"test"`` (default), ``"calibration"``, ``"bench"`` or ``"unit"``.
    shape : tuple of int, optional
        (H, W) in px (default 64 x 64).
    kind : str, optional
        ``"line"`` or ``"circle"``; default: a line at even indices, a circle at odd ones.
    **overrides
        Fix any drawn parameter (``blur_px``, ``A``, ``B``, ``noise_rel``, ...; ``edge`` an edge object).

    Returns
    -------
    SyntheticImage
        ``image`` (float64 gray levels), ``truth`` (the exact edge), ``scenario`` and ``params``.
    """
    rng = np.random.default_rng(seed_sequence(split, scenario, index))
    kind = kind or ("line" if index % 2 == 0 else "circle")
    edge = overrides.pop("edge", None) or random_edge(rng, shape, kind)
    p = {
        "blur_px": rng.uniform(0.5, 2.0),
        "A": rng.uniform(20, 60),
        "B": rng.uniform(60, 180),
        "noise_rel": rng.uniform(0.005, 0.03),
    }
    slope = texture = None
    s_bright = None
    if scenario == "slope":
        p["slope_rel"] = rng.uniform(0.005, 0.02) * rng.choice([-1, 1])
        p["slope_angle_rad"] = rng.uniform(-np.pi, np.pi)
    elif scenario == "texture":
        n = 12
        wl = rng.uniform(3.0, 12.0, n)
        ang = rng.uniform(-np.pi, np.pi, n)
        p["texture_rms_rel"] = rng.uniform(0.02, 0.05)
        p["_tex"] = (2 * np.pi / wl * np.cos(ang), 2 * np.pi / wl * np.sin(ang), rng.uniform(0, 2 * np.pi, n))
    elif scenario == "asymmetric":
        lr = rng.uniform(np.log(1.5), np.log(3.0)) * rng.choice([-1, 1])
        p["blur_ratio"] = float(np.exp(lr))
    p.update(overrides)
    B = p["B"]
    if scenario == "slope":
        slope = (p["slope_rel"] * B, p["slope_angle_rad"], (shape[1] / 2, shape[0] / 2))
    elif scenario == "texture":
        kx, ky, ph = p.pop("_tex")
        amp = np.full(kx.size, p["texture_rms_rel"] * B * np.sqrt(2.0 / kx.size))
        texture = (amp, kx, ky, ph)
    s_dark = p["blur_px"]
    if scenario == "asymmetric":
        # geometric mean of the two blurs is blur_px
        s_dark = p["blur_px"] * np.sqrt(p["blur_ratio"])
        s_bright = p["blur_px"] / np.sqrt(p["blur_ratio"])
    img = render_edge_image(shape, edge, p["A"], B, s_dark, s_bright, p["noise_rel"] * B, rng, slope, texture)
    p = {k: (float(v) if np.isscalar(v) else v) for k, v in p.items() if not k.startswith("_")}
    p.update(kind=kind, split=split, index=int(index), s_dark=float(s_dark),
             s_bright=float(s_dark if s_bright is None else s_bright))
    return SyntheticImage(img, edge, scenario, p)
