"""The sharpening a twin renders: an unsharp mask fitted, with the lens's blur, to the photos' edge-spread functions.

A camera that sharpens (a video camera's aperture correction, in-camera sharpening before the JPEG) leaves each
edge with an overshoot on both sides of the step (``photo_model.overshoot_pct``), and its ERF σ is no longer the
lens's: the mask narrows the edge.  A twin that rendered only the ERF σ's blur would have edges of another shape.

``sharpened_axes`` says along which axes the photos are sharpened: where the unsaturated photos' median overshoot
exceeds ``photo_model.SHARPENED_PCT``.  ``fit_sharpening`` then fits, per photo, the Gaussian aberration along each
of those axes and the mask's amount and σ (one pair for all of them: the renderer has one) to the photo's pooled
ESF along them (``photo_model.pooled_esf``), through the twin's own pixel, diffraction, defocus, tone curve and
output gain (``photo_model.normalised_model``: what the renderer does, ``render.sensor.pipeline``: encode, gain,
``sharpen`` along the axis).
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from edgetruth.evaluate.board.tone.photo_model import SHARPENED_PCT, normalised_model
from edgetruth.render.sensor.pipeline import sharpen


def sharpened_axes(photos: list[dict]) -> str | None:
    """'x', 'y' or 'xy' (the renderer's ``sharpen_axis``) where the photos' median overshoot (``overshoot_pct``,
    the larger of over- and undershoot) exceeds ``photo_model.SHARPENED_PCT``; None where no axis does (or none
    was measured)."""
    over = [p["overshoot_pct"] for p in photos if p.get("overshoot_pct")]
    axes = "".join(a for a in "xy" if over and np.nanmedian([o[a] for o in over]) > SHARPENED_PCT)
    return axes or None


def fit_sharpening(esfs: dict, camera, defocus_px: float, black: float, white: float, gain: float,
                   gamma: float) -> dict:
    """The aberration σ (µm) along each axis of ``esfs`` ({axis: (t, e)}: pooled normalised ESFs, t in px) and the
    unsharp mask's ``amount`` and ``sigma_px`` shared by them, least squares over all their bins; ``black`` and
    ``white`` the linear levels (fractions of the ADC's range), ``gain`` the output gain, ``gamma`` the power curve
    (1: linear).  -> {"sigma_um": {axis: σ}, "amount", "sigma_px", "fit_rms"}."""
    axes = sorted(esfs)
    data = {a: (np.asarray(esfs[a][0], float), np.asarray(esfs[a][1], float)) for a in axes}
    base = dict(camera=camera, defocus_px=defocus_px, black=black, white=white, gain=gain, gamma=gamma)

    def resid(q):
        *sig, amount, sigma_s = q
        return np.concatenate([normalised_model(t, **base, sigma_ab_um=s, amount=amount, sigma_s=sigma_s) - e
                               for s, (t, e) in zip(sig, data.values())])

    p = camera.pitch_um
    n = len(axes)
    # a step of 1e-3 spans the model's kinks in the mask's σ (photo_model.fit_esf says why)
    r = least_squares(resid, [0.5 * p] * n + [0.5, 1.0], bounds=([0.0] * n + [0.0, 0.3], [4.0 * p] * n + [5.0, 4.0]),
                      diff_step=1e-3)
    return {"sigma_um": {a: float(v) for a, v in zip(axes, r.x[:n])}, "amount": float(r.x[n]),
            "sigma_px": float(r.x[n + 1]), "fit_rms": float(np.sqrt(np.mean(r.fun ** 2)))}


def mask_noise_gain(amount: float, sigma_px: float, axes: str) -> float:
    """How much the renderer's unsharp mask (``render.sensor.pipeline.sharpen``, ``amount``, ``sigma_px``, along
    ``axes``) multiplies the variance of white noise before it: the sum of its impulse response's squares."""
    r = int(5.0 * sigma_px) + 2
    impulse = np.zeros((2 * r + 1, 2 * r + 1))
    impulse[r, r] = 1.0
    return float(np.sum(sharpen(impulse, amount, sigma_px, axes) ** 2))
