"""A digital twin of your own board photos: measure what a twin needs on them, write its camera and scene.

A board of separate squares (``edgetruth twin PHOTOS --model Model.txt --model-unit-m 0.0254 -o DIR``) is measured
by ``measure_squares.measure_squares`` (its docstring says how each measurement differs from a chessboard's) and
written here alike, its model file named by the spec (``model_ref``).  The chessboard's path:

``edgetruth twin PHOTOS --pattern 9x6 --square-m 0.025 -o DIR`` (``measure.measure_chessboard``, then ``twin_texts``
here) writes ``DIR/camera.toml``, ``DIR/twin.toml`` (one group per photo: ``edgetruth render DIR/twin.toml``
renders it with exact truth) and ``DIR/measurements.json``.  OpenCV's shipped twins
(``scenes/opencv_left_twin.toml``, and with ``--bend`` ``opencv_left_twin_bent.toml``) and their camera
(``assets/cameras/opencv_left.toml``) are this module's output on its photos (``tools/twins/opencv_left_scene.py``).

Measured on the photos (``measure.measure_chessboard``):

- **Camera.**  Zhang's calibration (``calibrate_photos``, 5-term Brown-Conrady) on every photo's line corners,
  the grid lines fitted in the undistorted image (``grid_corners.grid_points``, ERF4P-fixed11: what ``edgetruth
  calibrate --corners lines`` gives).
- **Poses.**  ``cv2.solvePnP`` (iterative, with that K and distortion) on the same corners in the order of the
  board study's chessboard model (its dark squares between the inner corners; unit = one square), so the twin's
  chessboard (``[spec.squares] chessboard``) puts its dark squares where the photo's are.
- **Outer ring.**  How far the cut outer ring reaches beyond the outermost inner corners: along the middle of each
  ring square, the point where the stored value crosses halfway from dark to white, in squares (median).
- **Levels.**  ``levels.square_levels`` at the squares' centres (median, noise SD, saturated flag): each photo's
  white sets its exposure; the print's contrast (white / dark, median over the unsaturated photos) the squares'
  reflectance; a saturated photo's white becomes the clip (``output_clip_dn``), its white before the clip its dark
  level times that contrast.
- **Blur.**  ``photo_model.blur``: the ERF σ (px) per axis; for a JPEG photo less what the JPEG adds
  (``jpeg_synthetic.jpeg_blur_px``: on a synthetic image of its squares, ``jpeg_sigma_px``); then the Gaussian
  aberration whose edge through the pixel, the diffraction and the photo's defocus reads that σ
  (``blur_inverse.aberration_sigma_px``; ``aberration_sigma_um``).  A saturated photo takes the unsaturated ones'
  medians (a clipped edge biases its σ).  Where the photos' edges overshoot (``sharpening.sharpened_axes``) the
  aberration along that axis and the renderer's unsharp mask are fitted together to each photo's pooled ESF
  (``sharpening.fit_sharpening``) instead.
- **Tone.**  ``tone_fit.estimate_power`` on the unsaturated photos: linear (``output_gamma = 1``) when its 95 %
  interval holds 1, else the power found.  16-bit photos are rendered linear (raw), and refused where their power
  is a tone curve's (``measure.raw_tone``).
- **Lens shading.**  Each photo's light squares (``shading.light_levels`` at the points the pose projects them to);
  over the unsaturated photos the renderer's ``1 + a2 h² + a4 h⁴`` fitted to what they show beyond the twin's light
  (``shading.fit_shading``; the camera's ``shading_a2``, ``shading_a4``), and each group's irradiance set so that
  its light squares' median is the photo's (``_shading``).
- **Output.**  JPEG photos: the quality whose IJG (Annex K) luminance table the file carries (``jpeg_quality``);
  other 8-bit photos: 8-bit PNG.  16-bit photos: raw (the sensor's DN in a 16-bit PNG), taken as linear, the ADC's
  bits from their largest value, the gain, read noise and black level from their noise (``photon_transfer``: the
  squares' ``flat_noise``; one of read noise and black level assumed or given, ``dark_noise_e``, ``black_dn``).
- **Bend** (``--bend``).  The calibration's quadratic bend check per photo (``evaluate.board_bend``), written as the
  group's ``board_bend_mm`` on the renderer's scale (``bend_mm``).

Assumed (nothing in a photo gives them; ``TwinAssumptions``): the pixel pitch, the f-number (they set f = fx · pitch
and the defocus, small at these distances), the focus (the median board distance), the board's reflectance, the
light's direction, and the sensor's noise: shot noise with its SD before the output coding ``white_noise_dn`` at a
white of ``WHITE_REF_DN``, and ``dark_noise_e`` of read noise on top.  A photo's noise is measured after its JPEG; by
default a twin of JPEG photos with a linear tone takes both from their white and dark SDs before their JPEG
(``jpeg_synthetic.noise_before_jpeg``, ``noise_before_jpeg``: medians), other photos their white SD less
``DARK_NOISE_E`` of read noise.  Through a tone curve (8-bit photos, ``output_gamma`` != 1) the darks' SD tells noise
before the curve from noise after it: ``curve_noise`` fits both to the unsaturated photos' dark and white SDs and the
twin adds the latter as ``output_noise_dn``.  The twin study's Table 3 compares the noise of photos and twin.
"""
from __future__ import annotations

import json
import math
import re
import textwrap
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import minimize_scalar

from edgetruth.errors import InputError
from edgetruth.evaluate.board.tone.photo_model import SHARPENED_PCT, clipped_white
from edgetruth.evaluate.board.twin.blur_inverse import aberration_sigma_px
from edgetruth.evaluate.board.twin.photon_transfer import sensor_from_noise
from edgetruth.evaluate.board.twin.shading import (fit_shading, lens_shading, light_falloff, light_square_centres,
                                                   project)
from edgetruth.evaluate.board.twin.sharpening import fit_sharpening, mask_noise_gain, sharpened_axes
from edgetruth.render.optics.camera import camera_from_dict
from edgetruth.render.optics.mtf import diffraction_cutoff_cy_px
from edgetruth.render.optics.prediction import field_height
from edgetruth.render.scene.bend import BoardBend
from edgetruth.render.scene.targets import SquareBoard
from edgetruth.render.sensor.linear_model import SensorModel


#: the white level (8-bit) the white noise SD is stated at
WHITE_REF_DN = 220.0
#: the read noise (e-) a twin assumes where its photos do not give it (not JPEG, or a tone curve)
DARK_NOISE_E = 15.0


@dataclass(frozen=True)
class TwinAssumptions:
    """What the photos do not say (module docstring); ``None``: derived as the docstring says."""

    pitch_um: float = 6.0
    f_number: float = 4.0
    wavelength_nm: float = 550.0
    board_reflectance: float = 0.8
    #: the 8-bit 255 is 1/output_gain of the ADC's range, so that whites above 255 exist to be clipped
    output_gain: float = 1.6
    #: the white's shot-noise SD (8-bit DN) before the output coding, at a white of ``WHITE_REF_DN`` (the read noise,
    #: ``dark_noise_e``, adds to it: 1.4 DN at 4.5 and 15 e-)
    white_noise_dn: float | None = None
    #: how ``white_noise_dn`` was found, for the scene's header (when given)
    white_noise_why: str = "given"
    #: the read noise (e-); ``None``: from JPEG photos' darks with their white (``jpeg_synthetic.noise_before_jpeg``)
    #: when the tone is linear, else ``DARK_NOISE_E``
    dark_noise_e: float | None = None
    #: 16-bit (raw) photos' black level (DN); ``None``: from their noise with the read noise (``photon_transfer``)
    black_dn: float | None = None
    light_position_m: tuple[float, float, float] = (0.0, -1.5, -2.0)


# --- the twin's files -------------------------------------------------------------------------------
def _median(values, empty: float = float("nan")) -> float:
    """The median of the finite ``values`` (None or NaN: not measured), ``empty`` when there are none."""
    v = [float(x) for x in values if x is not None and math.isfinite(float(x))]
    return float(np.median(v)) if v else empty


def _range(values, fmt: str = ".1f") -> str:
    lo, hi = min(values), max(values)
    return f"{lo:{fmt}}" if f"{lo:{fmt}}" == f"{hi:{fmt}}" else f"{lo:{fmt}}-{hi:{fmt}}"


def _board_mode(bend: bool) -> str:
    """The spec's ``board_mode`` line(s): a flat board's composite (no Monte-Carlo noise: the darks' noise is the
    photos' alone), a curled board's path-traced frame."""
    if bend:
        return "board_mode = \"path\"       # a curled board renders path-traced (board_mode = \"frame\" takes flat boards)\n"
    return ("board_mode = \"frame\"      # the plate's shading on a grid, the squares' coverage exact: no Monte-Carlo "
            "noise\n                          # at the edges or in the squares (docs/optics.md)\n")


def _output(rows) -> tuple[str, int | None, str]:
    """(output, jpeg quality or None, the words for the header)."""
    q = [r["jpeg_quality"] for r in rows]
    if any(v is None for v in q):
        return "srgb8", None, "8-bit PNG (not every photo is a JPEG)"
    qualities = sorted({v["quality"] for v in q})
    quality = int(np.median([v["quality"] for v in q]))
    exact = all(v["exact"] for v in q)
    words = (f"every photo's luminance table is the IJG table at quality {quality} exactly" if exact and
             len(qualities) == 1 else f"the photos' luminance tables are nearest the IJG tables at qualities "
             f"{', '.join(str(v) for v in qualities)}: quality {quality} (the median)")
    return "jpeg", quality, words


def bend_mm(m: dict, ring: list[float], square_m: float) -> list[list[float]]:
    """Each photo's quadratic bend (x², xy, y², mm) on the renderer's scale (``render.scene.bend.BoardBend`` of the
    twin's chessboard: half the larger side of the printed squares' box), from the bend check's (half the corners'
    larger extent): a monomial of degree 2 scales as (s_render / s_check)².  Both are centred on the board: the box
    and the corners are symmetric about its centre.  An ``InputError`` when a photo took no part in the check (too
    few corners)."""
    cols, rows = m["pattern"]
    board = SquareBoard.chessboard(cols, rows, square_m, tuple(ring))
    s_render = BoardBend.of((0.0, 0.0, 0.0), board.black_quads_local(0.0)).scale_m * 1e3
    out = []
    for p in m["photos"]:
        b = p.get("bend_squares")
        if b is None:
            raise InputError(f"{p['photo']}: no bend measured (the bend check needs every photo's corners, 13 or "
                             "more); drop --bend or leave the photo out")
        s_check = b["scale"] * square_m * 1e3
        out.append([round(c * square_m * 1e3 * (s_render / s_check) ** 2, 5) for c in b["coefficients"]])
    return out


def twin_texts(m: dict, name: str, description: str, camera_ref: str, square_m: float, source: str,
               assumptions: TwinAssumptions = TwinAssumptions(), bend: bool = False,
               model_ref: str | None = None) -> tuple[str, str]:
    """(camera TOML, scene TOML) of the twin of the photos ``m`` (``measure.measure_chessboard``, or for a board of
    separate squares ``measure_squares.measure_squares``): ``name`` and ``description`` the spec's, ``camera_ref``
    how the spec names the camera (a shipped name or a path relative to the spec), ``square_m`` the printed
    square's side (m), or for a board of separate squares the model file's unit (m) (it scales the poses only),
    ``source`` the photos in words (for the headers); ``bend``: each board curled as its photo's (``bend_mm``;
    chessboards only); ``model_ref``: how the spec names a board of separate squares' model file (required
    for one)."""
    a = assumptions
    K, dist, photos = np.asarray(m["K"]), m["dist"], m["photos"]
    names = [group_name(p["photo"]) for p in photos]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise InputError(f"{twice[0]}: two photos share this name; a twin names one group per photo, so rename one")
    chess = "pattern" in m
    circles = m.get("board", {}).get("kind") == "circles"
    if circles and bend:
        raise InputError("--bend: for chessboards only (a circle grid has no bend check); drop it")
    if not chess and not circles and (bend or model_ref is None):
        raise InputError("--bend: for chessboards only (a board of separate squares has no bend check); drop it"
                         if bend else "a board of separate squares' twin names its model file (model_ref)")
    cols, rows = m["pattern"] if chess else (0, 0)
    clean = [p for p in photos if not p["white_saturated"]] or photos
    raw = float(m.get("full_scale", 255.0)) > 255.0
    if raw and a.white_noise_dn is not None:
        raise InputError("--white-noise-dn: for 8-bit photos; 16-bit photos give their sensor's gain and noise "
                         "(photon transfer), so leave it out")
    if not raw and a.black_dn is not None:
        raise InputError("--black-dn: for 16-bit (raw) photos; an 8-bit photo's coding puts its black at 0, so "
                         "leave it out")
    rn = _raw_noise(m, a) if raw else None
    black = rn.black_dn if raw else 0.0
    ratio = float(np.median([(p["white"] - black) / (p["dark"] - black) for p in clean]))
    sig_x, sig_y = (_median([p[k] for p in clean]) for k in ("sigma_x_px", "sigma_y_px"))
    if not (math.isfinite(sig_x) and math.isfinite(sig_y)):
        raise InputError("the photos' edges gave no blur (the photo model found no sides); the twin needs it")
    # a full square at most (the crossing reads a half-step past its far side); no ring square in view: a full one
    ring = [round(min(_median([p["ring"][k] for p in photos], 1.0), 1.0), 3) for k in ("x", "y")] if chess else None
    dist_m = float(np.median([translation(p)[2] for p in photos])) * square_m
    output, quality, output_words = _output(photos) if not raw else ("raw", None, _raw_words(m))
    gamma = float(m["tone"]["output_gamma"])
    # the 8-bit sensor (raw photos replace its gain and read noise by their photon transfer's, below)
    white_sd, white_why = a.white_noise_dn, a.white_noise_why
    read_e, read_why = a.dark_noise_e, "given" if a.dark_noise_e is not None else "assumed"
    # per photo before its JPEG: the shot SD scaled to the reference white (it goes as the square root of the level)
    # and the read noise in e- (r DN = r_e s^2 / L in linear 8-bit units, s the shot SD at the level L)
    joint = [(b["shot_dn"] * math.sqrt(WHITE_REF_DN / p["white"]), b["read_dn"]) for p in clean
             if (b := p.get("noise_before_jpeg")) is not None]
    derived_shot = white_sd is None and output == "jpeg" and bool(joint) and gamma == 1.0
    if derived_shot:
        white_sd = float(np.median([s for s, _ in joint]))
        white_why = ("the photos' white and dark SDs before their JPEG, found through it on a synthetic image of "
                     f"each photo's squares: median of {len(joint)}")
        if read_e is None:
            read_e = round(float(np.median([r * WHITE_REF_DN / s ** 2 for s, r in joint])), 1)
            read_why = f"with the white's, median of {len(joint)}"
    elif white_sd is None:
        white_sd = float(np.median([p["white_sd"] * math.sqrt(WHITE_REF_DN / p["white"]) for p in clean]))
        white_why = "the photos' white SD at that level"
    if read_e is None:
        read_e = DARK_NOISE_E
    s0 = SensorModel()
    span = s0.max_dn - s0.dark_offset_dn
    # stored s = 255 g v^(1/G) (render.sensor.pipeline: the curve, then ``output_gain`` g), v the linear signal:
    # levels, contrast and noise go back to the linear s = 255 g v they would have had with G = 1
    full = 255.0 * a.output_gain

    def lin(stored_8bit: float) -> float:
        return stored_8bit if gamma == 1.0 else full * (stored_8bit / full) ** gamma

    def dlin(stored_8bit: float) -> float:
        return 1.0 if gamma == 1.0 else gamma * (stored_8bit / full) ** (gamma - 1.0)

    slope = dlin(WHITE_REF_DN)  # d linear / d stored at 220
    cutoff = diffraction_cutoff_cy_px(a.pitch_um, a.wavelength_nm, a.f_number)
    # the twin camera's thin lens (f = fx * pitch, focused at dist_m), for each photo's defocus
    lens = camera_from_dict({"width_px": int(m["image_size"][0]), "height_px": int(m["image_size"][1]),
                             "pitch_um": a.pitch_um, "fx_px": float(K[0, 0]), "f_number": a.f_number,
                             "cx_px": float(K[0, 2]), "cy_px": float(K[1, 2]),
                             "focus_distance_m": dist_m, "diffraction_wavelength_nm": a.wavelength_nm}, name)

    def defocus_px(p: dict) -> float:
        """The blur disk's radius (px) at the board's centre."""
        z = board_centre_m(p, centre_model(m), square_m)[2]
        return float(lens.defocus_radius_px(z))

    # sharpening (an overshoot beyond photo_model.SHARPENED_PCT): along those axes the aberration and an unsharp mask
    # are fitted together to each unsaturated photo's pooled ESF; a clipped photo takes their medians
    axes = None if raw else sharpened_axes(clean)
    fits = {}
    for i, p in enumerate(photos if axes else []):
        if not p["white_saturated"] and p.get("esf"):
            fits[i] = fit_sharpening({ax: p["esf"][ax] for ax in axes}, lens, defocus_px(p), lin(p["dark"]) / full,
                                     lin(p["white"]) / full, a.output_gain, gamma)
    axes = axes if fits else None
    typical = None if not fits else {
        "sigma_um": {ax: _median([f["sigma_um"][ax] for f in fits.values()]) for ax in axes},
        "amount": _median([f["amount"] for f in fits.values()]),
        "sigma_px": _median([f["sigma_px"] for f in fits.values()])}

    # the mask amplifies what noise lies before it (the sensor's, through the curve) by its variance gain, per photo
    gains = [1.0 if not axes else mask_noise_gain(fits.get(i, typical)["amount"], fits.get(i, typical)["sigma_px"],
                                                  axes) for i in range(len(photos))]

    # through a tone curve the darks' SD tells noise before it (stretched there by the curve) from noise after it
    unsat = [p for p in photos if not p["white_saturated"]]
    split = not raw and gamma != 1.0 and a.white_noise_dn is None and len(unsat) >= 2
    if axes and not split and a.white_noise_dn is None:  # measured after the mask, rendered before it
        white_sd /= math.sqrt(_median([g for p, g in zip(photos, gains) if not p["white_saturated"]] or gains))
        white_why += ", through the sharpening's noise gain"
    sd_lin = white_sd * slope
    # the read noise in these units is r k 255 g / span = r s^2 / L (s the shot SD at L = lin(220)): a measured SD is
    # both, so the shot part solves s^2 + (r s^2 / L)^2 = sd^2
    c = (read_e / lin(WHITE_REF_DN)) ** 2
    curve = None
    if split:
        # q (linear units per electron) sets K = q span / full: at least 1e-4 DN/e-, whose ADC range (span / K e-)
        # a full well (at most 1e8 e-) still holds
        curve = curve_noise(unsat, lin, dlin, read_e, lin(WHITE_REF_DN), q_min=1e-4 * full / span,
                            gains=[g for p, g in zip(photos, gains) if not p["white_saturated"]])
        sd_lin = curve["shot_lin"]
        white_sd = sd_lin / slope
        own_noise = [photo_output_noise(p, curve["q"], lin, dlin, read_e, g) for p, g in zip(photos, gains)]
        white_why = (f"with a constant noise after the curve, output_noise_dn {curve['output_dn']:.2f} DN, fitted to "
                     f"the {len(unsat)} unsaturated photos' dark and white SDs less the 8-bit rounding (their SDs "
                     f"within {100 * curve['rms_rel']:.0f} % RMS; {read_e:g} e- of read noise held); each group adds "
                     f"its photo's own ({_range(own_noise, '.2f')} DN: what its dark and white SDs hold beyond the "
                     "shot noise)")
    if a.white_noise_dn is None and not derived_shot and curve is None and c > 0:
        total, sd_lin = white_sd, math.sqrt((math.sqrt(1.0 + 4.0 * c * sd_lin ** 2) - 1.0) / (2.0 * c))
        white_sd = sd_lin / slope
        white_why += f", {total:.2f} DN in all, less the read noise"
    k = sd_lin ** 2 * span / (255.0 * a.output_gain * lin(WHITE_REF_DN))  # DN per electron
    ppr = s0.photons_per_radiance(a.f_number, a.pitch_um)  # photons per W m^-2 sr^-1

    if raw:
        k, read_e = rn.k_dn_per_e, rn.read_noise_e

    def irradiance(white: float, relative: float) -> float:
        """The irradiance at the board's centre whose light squares read ``white`` (their median; linear 8-bit
        units, raw: DN) where the light and the lens shading leave ``relative`` of it there (their median)."""
        electrons = (white - black) / k if raw else white * span / (255.0 * a.output_gain * k)
        return electrons / relative * math.pi / (s0.qe * ppr * a.board_reflectance)

    shading, relative = _shading(m, a, lens, square_m, lambda v: lin(v) - black)

    def jpeg_px(p: dict, axis: str) -> float:
        return 0.0 if p.get("jpeg_sigma_px") is None else float(p["jpeg_sigma_px"][axis])

    jpeg_x, jpeg_y = (_median([jpeg_px(p, k) for p in clean], 0.0) for k in ("x", "y"))

    def aberration_um(sigma_px: float, jpeg: float, defocus: float) -> float:
        """The Gaussian aberration whose render reads ERF sigma ``sigma_px`` once a JPEG adds ``jpeg`` px."""
        return a.pitch_um * aberration_sigma_px(sigma_px - jpeg, cutoff, defocus, ratio ** gamma, gamma)

    def camera_aberration(axis: str, sigma_px: float, jpeg: float) -> float:
        return typical["sigma_um"][axis] if axes and axis in axes else aberration_um(sigma_px, jpeg, 0.0)

    cal_words = (f"Zhang's calibration on the {cols * rows} line corners of every photo (ERF4P-fixed11, the grid "
                 f"lines fitted in the undistorted image; `edgetruth calibrate --pattern {cols}x{rows} --corners "
                 f"lines`), RMS {m['rms_px']:.4f} px" if chess else
                 f"Zhang's calibration on the {m['board']['cols'] * m['board']['rows']} circles' corrected centres "
                 "of every photo (ERF4P-fixed11's points on each circle, an ellipse, the image of its centre; "
                 f"`edgetruth calibrate --pattern {m['board']['pattern_text']} --centres corrected`), RMS "
                 f"{m['rms_px']:.4f} px" if circles else
                 f"Zhang's calibration (k1, k2, as his) on the corners of the {4 * m['board']['squares']} squares' "
                 "side lines (Canny-Devernay points, edgetruth.evaluate.board.tone.photo_model.board_lines) of every "
                 f"photo, RMS {m['rms_px']:.4f} px")
    cam = _comment(
        f"The camera of {source}, as edgetruth measured it: {cal_words}.  Written by `edgetruth twin` "
        f"(edgetruth.evaluate.board.twin.derive).  Assumed (nothing published): the pixel pitch ({a.pitch_um} um), "
        f"the f-number (f/{a.f_number:g}) and the focus (the median board distance, with "
        + (f"a square of {square_m * 1000:g} mm" if chess else f"a spacing of {square_m * 1000:g} mm" if circles
           else f"a model unit of {square_m * 1000:g} mm")
        + "); they set f = fx * pitch and the defocus, which is small here.  The lens blur is "
        f"the median of the unsaturated photos' ERF sigma per axis (edgetruth.evaluate.board.tone.photo_model: "
        f"{sig_x:.3f} px along x, {sig_y:.3f} px along y)"
        + (f", less what the JPEG adds ({jpeg_x:.3f} and {jpeg_y:.3f} px on a synthetic board)" if output == "jpeg"
           else "") + ", as the Gaussian aberration whose edge through the pixel and the diffraction reads that "
        "sigma (edgetruth.evaluate.board.twin.blur_inverse; in focus); the twin scene sets it per photo, at the "
        "photo's defocus, and with its own sigma only where that is unbiased.  "
        + ("" if not axes else f"Along {' and '.join(axes)} the photos' edges overshoot (sharpening): there the "
           "aberration is fitted with the renderer's unsharp mask to each photo's pooled ESF "
           "(edgetruth.evaluate.board.twin.sharpening; here the median).  ") + (
            f"The lens shading (shading_a2, shading_a4: 1 + a2 h^2 + a4 h^4, h the field height) is what the "
            f"unsaturated photos' {'light squares' if chess else 'white between the circles' if circles else ''}"
            f"{'' if chess or circles else 'white gaps between the squares'} show beyond "
            "the twin's light (edgetruth.evaluate.board.twin.shading; "
            f"{shading['levels']} levels over {shading['photos']} photos): their RMS about the fit "
            f"{100 * shading['rms_after']:.1f} % of the level, {100 * shading['rms_before']:.1f} % with the light "
            "alone." if "note" not in shading else f"Lens shading: {shading['note']}.")) + f"""
[camera]
width_px = {m["image_size"][0]}
height_px = {m["image_size"][1]}
pitch_um = {a.pitch_um}
fx_px = {K[0, 0]:.4f}
fy_px = {K[1, 1]:.4f}
cx_px = {K[0, 2]:.4f}
cy_px = {K[1, 2]:.4f}
f_number = {a.f_number}
focus_distance_m = {dist_m:.4f}
diffraction_wavelength_nm = {a.wavelength_nm}
aberration_sigma_um = {camera_aberration("x", sig_x, jpeg_x):.3f}
aberration_sigma_y_um = {camera_aberration("y", sig_y, jpeg_y):.3f}
aberration_sigma_growth = 0.0
shading_a2 = {shading["a2"]:.4f}
shading_a4 = {shading["a4"]:.4f}
natural_vignetting = false

[camera.distortion]
k1 = {dist[0]:.6f}
k2 = {dist[1]:.6f}
p1 = {dist[2]:.6f}
p2 = {dist[3]:.6f}
k3 = {dist[4]:.6f}
"""
    groups = []
    light = "[" + ", ".join(f"{v}" for v in a.light_position_m) + "]"
    bends = bend_mm(m, ring, square_m) if bend else [None] * len(photos)
    offsets = []
    for i, (p, curl, rel) in enumerate(zip(photos, bends, relative)):
        sat = p["white_saturated"]
        white = black + (p["dark"] - black) * ratio if sat else p["white"]
        own = own_noise[i] if curve is not None else None
        # a model's ring is clipped at its top, not at its mean (which holds the blurred edges): the level before the
        # clip from the share of the ring there and the photo's noise (``photo_model.clipped_white``)
        clip_at = p["white"] if "white_top" not in p or raw else p["white_top"]
        if sat and clip_at != p["white"]:
            white = clipped_white({"at_max_fraction": p["white_at_max"]}, p["dark_sd"] if own is None else own,
                                  clip_at)
        # the print's contrast puts the dark at white / ratio; what the photo's dark holds beyond that (a camera's black
        # level, flare) is an offset of the stored values, and the white renders that much lower (8-bit photos)
        offset = 0.0
        if not raw and ratio > 1.05:
            offset = white - (white - p["dark"]) * ratio / (ratio - 1.0)
            offset = offset if abs(offset) >= 0.05 else 0.0
            offsets.append(offset)
        own_x, own_y = not sat and p["sigma_x_px"] is not None, not sat and p["sigma_y_px"] is not None
        sx, jx = (p["sigma_x_px"], jpeg_px(p, "x")) if own_x else (sig_x, jpeg_x)
        sy, jy = (p["sigma_y_px"], jpeg_px(p, "y")) if own_y else (sig_y, jpeg_y)
        ab_x, ab_y = aberration_um(sx, jx, defocus_px(p)), aberration_um(sy, jy, defocus_px(p))
        fit = fits.get(i, typical)
        if axes:
            ab_x = fit["sigma_um"].get("x", ab_x)
            ab_y = fit["sigma_um"].get("y", ab_y)
        R = ", ".join("[" + ", ".join(f"{v:.7f}" for v in row) + "]" for row in p["R"])
        t = ", ".join(f"{v:.5f}" for v in translation(p))
        sensor = f"output_clip_dn = {clip_at:.1f}" if sat else ""
        if raw:  # the well clips a white flat below the ADC's top
            top = 2 ** _raw_bits(m) - 1
            sensor = f"full_well_e = {(p['white'] - black) / k:.1f}" if sat and p["white"] < top - 0.5 else ""
        if offset:
            sensor = ", ".join(x for x in (sensor, f"output_offset_dn = {offset:.2f}") if x)
        if own is not None:  # each photo's own noise after the curve (a palette's dither, a cleaner frame)
            sensor = ", ".join(x for x in (sensor, f"output_noise_dn = {own:.2f}") if x)
        if axes:
            sensor = ", ".join(x for x in (sensor, f"sharpen_amount = {fit['amount']:.3f}",
                                           f"sharpen_sigma_px = {fit['sigma_px']:.3f}") if x)
        before = (f"dark x {ratio:.2f} = {white:.0f}" if clip_at == p["white"] else
                  f"{white:.1f}, from the {100 * p['white_at_max']:.0f} % of its ring there")
        note = (f"white saturated at {clip_at:.0f} (SD {p['white_sd']:.2f}); before the clip {before}; blur: the "
                "unsaturated photos' median" if sat else
                f"white {p['white']:.1f}, dark {p['dark']:.1f}; blur: "
                + ("its own" if p["sigma_x_px"] is not None and p["sigma_y_px"] is not None else
                   "the unsaturated photos' median"))
        groups.append(f"""[[group]]  # {p['photo']}: {note}
name = "{group_name(p['photo'])}"
kind = "{'circles_grid' if circles else 'squares'}"
{"" if curl is None else f"board_bend_mm = {curl}"}
irradiance_w_m2 = {irradiance(lin(white - offset), rel):.4f}
light_position_m = {light}
pose_unit_m = {square_m}
camera = {{ aberration_sigma_um = {ab_x:.3f}, aberration_sigma_y_um = {ab_y:.3f} }}
{"sensor = { " + sensor + " }" if sensor else ""}
poses = [{{ R = [{R}], t = [{t}] }}]
""".replace("\n\n", "\n"))
    sat = [p for p in photos if p["white_saturated"]]
    margin_m = 0.0 if chess else square_m if circles else m["board"]["side_model"] * square_m
    board_keys = (f'chessboard = "{cols}x{rows}"\nside_m = {square_m}\nring = [{ring[0]:.3f}, {ring[1]:.3f}]\n'
                  f'margin_m = {0.35 * square_m:.5f}' if chess else
                  f'cols = {m["board"]["cols"]}\nrows = {m["board"]["rows"]}\nspacing_m = {square_m}\n'
                  f'diameter_m = {2.0 * m["board"]["radius_spacings"] * square_m:.6f}\n'
                  f'asymmetric = {str(m["board"]["asymmetric"]).lower()}\nmargin_m = {margin_m:.5f}' if circles else
                  f'model = {_toml_str(model_ref)}\nmodel_unit_m = {square_m}\nmargin_m = {margin_m:.5f}')
    prnu_line = f"prnu_pct = {100 * rn.prnu:.3f}\n" if raw and round(100 * rn.prnu, 3) > 0 else ""
    tone = m["tone"]
    tone_words = (f"the unsaturated photos' power {tone['power']:.2f} (95 % {tone['ci'][0]:.2f}-{tone['ci'][1]:.2f}; "
                  f"--tone auto)" if tone.get("power") is not None and not raw else tone.get("note", "not measured"))
    noise = (f"dark SD {_range([p['dark_sd'] for p in unsat])} at {_range([p['dark'] for p in unsat], '.0f')}, "
             f"white SD {_range([p['white_sd'] for p in unsat])} at {_range([p['white'] for p in unsat], '.0f')}"
             if unsat else "no unsaturated photo")
    sensor_lines = [f'output = "{output}"'] + ([f"jpeg_quality = {quality}"] if quality is not None else []) + (
        [f'sharpen_axis = "{axes}"'] if axes else [])
    by_top = not chess and not raw  # a model's or circle grid's white  # a model's ring: clipped at its top, the level before from the share there
    clip = f" at {_range([p['white_top' if by_top else 'white'] for p in sat], '.0f')}" if sat else ""
    if circles:
        cb = m["board"]
        board_lines = [
            _comment(f"A digital twin of {source}: a {cb['pattern_text']} grid of circles {square_m * 1000:g} mm "
                     f"apart (OpenCV's squareSize), the camera edgetruth calibrated on them ({camera_ref}), one group "
                     "per photo at the pose its circles' corrected centres give (cv2.solvePnP on OpenCV's object "
                     "points; t in spacings).  Written by `edgetruth twin` (edgetruth.evaluate.board.twin.derive, "
                     "measure_circles); docs/board.md.  Measured on the photos:"),
            _comment(f"the board: circles of diameter {2000 * cb['radius_spacings'] * square_m:.3f} mm (each "
                     "fitted ellipse's area at its circle's depth, median) on a white plate one spacing beyond "
                     f"them (assumed: {margin_m * 1000:.1f} mm; the sheet's edge is not measured);", True)]
        where_white, flat_rule, beyond = "between its circles", \
            "noise SD < half the dark's, or over 30 % of it at its top", "the sheet's true extent"
    elif chess:
        board_lines = [
            _comment(f"A digital twin of {source}: a {cols}x{rows} chessboard, the camera edgetruth calibrated on "
                     f"them ({camera_ref}), one group per photo at the pose its line corners give (cv2.solvePnP on the "
                     "board study's chessboard model; t in squares).  Written by `edgetruth twin` "
                     "(edgetruth.evaluate.board.twin.derive); docs/board.md.  Measured on the photos:"),
            _comment(f"the board: {cols + 1} x {rows + 1} squares, the outer ring cut at {ring[0]:.3f} (x) and "
                     f"{ring[1]:.3f} (y) of a square beyond the outermost inner corners (median over the photos);",
                     True)]
        where_white, flat_rule, beyond = "at its light squares' centres", "noise SD < half the dark's", \
            "the board's margin beyond the ring"
    else:
        board_lines = [
            _comment(f"A digital twin of {source}: a board of {m['board']['squares']} separate squares (the model "
                     f"file {model_ref}, {square_m:g} m per unit), the camera edgetruth calibrated on them "
                     f"({camera_ref}), one group per photo at the pose its squares' corners give (cv2.solvePnP on "
                     "the model; t in model units).  Written by `edgetruth twin` "
                     "(edgetruth.evaluate.board.twin.derive, measure_squares); docs/board.md.  Measured on the "
                     "photos:"),
            _comment(f"the board: the model's squares on a white plate one square's side beyond their bounding box "
                     f"(assumed: {margin_m * 1000:.1f} mm; the sheet's edge is not measured);", True)]
        where_white, flat_rule, beyond = "in a ring around its squares", \
            "noise SD < half the dark's, or over 30 % of it at its top", "the sheet's true extent"
    over = {k: [p["overshoot_pct"][k] for p in photos if p.get("overshoot_pct")] for k in "xy"}
    if over["x"]:
        shape = (f"sharpening: the photos' pooled ESFs overshoot by {_range(over['x'])} % of the step along x and "
                 f"{_range(over['y'])} % along y (edgetruth.evaluate.board.tone.photo_model)")
        board_lines.append(_comment(shape + (
            f": above {SHARPENED_PCT:g} % (the unsaturated photos' median) along {' and '.join(axes)}, rendered as "
            f"an unsharp mask there (sharpen_axis), its amount "
            f"{_range([f['amount'] for f in fits.values()], '.2f')} and sigma "
            f"{_range([f['sigma_px'] for f in fits.values()], '.2f')} px fitted per photo with the aberration "
            f"along it to the photo's pooled ESF (edgetruth.evaluate.board.twin.sharpening; RMS "
            f"{_range([f['fit_rms'] for f in fits.values()], '.3f')} of the step); a clipped photo takes the "
            "medians;" if axes else f": none rendered (at most {SHARPENED_PCT:g} %, the unsaturated photos' "
            "median);"), True))
    scene = "\n".join([
        *board_lines,
        _comment(f"tone: {tone_words}: output_gamma = {gamma:g};", True),
        _comment(f"output: {output_words};", True),
        _comment(f"levels: each photo's white {where_white} (its exposure, irradiance_w_m2 here); the "
                 f"print's contrast, white / dark = {ratio:.2f} (median of the unsaturated photos), sets the "
                 + ("circles'" if circles else "squares'") + " reflectance" + ("" if not any(offsets) else
                                  ", and what each photo's dark holds beyond it an offset of its stored values (a "
                                  "camera's black level, flare: output_offset_dn, "
                                  f"{min(offsets):+.2f} to {max(offsets):+.2f} DN), its white rendered that much "
                                  "lower") + ";", True),
        _comment(f"saturation: {len(sat)} photo(s) with whites flat ({flat_rule}){clip}: "
                 + ("the ADC's top or full_well_e there" if raw else "output_clip_dn there")
                 + (", with the white before the clip from the share of the ring at its top and the photo's noise "
                    "(edgetruth.evaluate.board.tone.photo_model.clipped_white)" if by_top else
                    f", with the white before the clip their dark level x {ratio:.2f}")
                 + (" (above the black level)" if raw else "") + ";", True),
        _comment(f"noise: {noise}: " + (
            f"photon transfer over {rn.points} levels (edgetruth.evaluate.board.twin.photon_transfer), "
            f"K = {k:.4f} DN/e- (with the level), read noise {read_e:.1f} e- ({rn.read_why}), black level "
            f"{black:.1f} DN ({rn.black_why}), PRNU {100 * rn.prnu:.2f} % ({rn.prnu_why}; the print's texture looks "
            "alike) (the twin study's Table 3 compares the photos' noise and the twin's)." if raw else
            ("shot-noise limited, " if curve is None else "") + f"a sensor of K = {k:.4f} DN/e-, {read_e:g} e- read "
            + ("noise" if read_why in ("given", "assumed") else f"noise ({read_why})")
            + f", the white's shot-noise SD before the output coding {white_sd:.2f} DN at {WHITE_REF_DN:g} "
            f"({white_why}; the twin study's Table 3 compares the photos' noise and the twin's)."), True),
        *([_comment("bend: each photo's board curled as the calibration's bend check fitted it (x^2, xy, y^2; "
                    "board_bend_mm, rescaled to the renderer's s; docs/board.md, 'A bent twin');", True)]
          if bend else []),
        _comment(f"Not reproduced: the room behind the board (black here), {beyond}, uneven "
                 "light beyond the twin's one lamp and the lens shading fitted to the photos (camera).")]) + f"""
[spec]
name = {_toml_str(name)}
description = {_toml_str(description)}
camera = {_toml_str(camera_ref)}
spp = 256
sampler = "multijitter"
{_board_mode(bend)}
[spec.{'circles_grid' if circles else 'squares'}]
{board_keys}
{'circle' if circles else 'square'}_reflectance = {a.board_reflectance / ratio ** gamma:.4f}
board_reflectance = {a.board_reflectance}

[sensor]
{chr(10).join(sensor_lines)}
""" + (f"""bits = {_raw_bits(m)}
k0_dn_per_e = {k:.6f}
dark_offset_dn = {black:.2f}
dark_noise_e = {read_e:.2f}
full_well_e = {1.05 * (2 ** _raw_bits(m) - 1 - black) / k:.1f}
""" + prnu_line if raw else f"""output_gamma = {gamma}
output_gain = {a.output_gain}""" + (
        "" if curve is None or curve["output_dn"] < 0.005 else f"\noutput_noise_dn = {curve['output_dn']:.2f}") + f"""
k0_dn_per_e = {k:.5f}
dark_noise_e = {read_e}
full_well_e = {max(100000.0, round(1.05 * span / k, -3))}
""") + "\n" + "\n".join(groups)
    return cam, scene


def translation(photo: dict) -> list[float]:
    """A photo's pose translation in the board's units: ``t_squares`` (chessboard) or ``t_model`` (a model file)."""
    return photo["t_squares"] if "t_squares" in photo else photo["t_model"]


def centre_model(m: dict) -> tuple[float, float]:
    """The renderer's board centre (``SquareBoard.centre_model_m``, where the lamp aims) in the board's units: a
    chessboard's middle of the inner corners (its ring cut alike on both sides), a model's squares' bounding box
    centre."""
    if "pattern" in m:
        cols, rows = m["pattern"]
        return (cols - 1) / 2.0, (rows - 1) / 2.0
    return tuple(m["board"]["centre_model"])


def curve_noise(photos: list[dict], lin, dlin, read_e: float, level: float, q_min: float = 1e-9,
                gains=None) -> dict:
    """Noise through a tone curve: shot noise before it (variance q L in the linear units of ``lin``, q per
    electron, with ``read_e`` e- of read noise, (read_e q)²) and a constant SD o after it (stored DN), fitted to
    the photos' dark and white SDs (stored 8-bit DN, their rounding's 1/12 taken off): at a stored level v the
    stored variance is (q L + (read_e q)²) / L'(v)² + o², L = ``lin``(v), L' = ``dlin``(v) = dL/dv.  Before the
    curve a dark's SD is stretched by 1 / L' (about 8x a white's at sRGB's 2.2 for a contrast of 5), after it
    not, so the darks and whites tell them apart.  ``gains``: per photo, what multiplies the variance before the
    output noise (a sharpening mask's, ``sharpening.mask_noise_gain``; 1 without).  Least squares in relative
    variance, q >= ``q_min`` and o >= 0:
    for each q on a log grid o² is linear (closed form), then the best refined.  -> {shot_lin: the shot SD at
    ``level`` (linear units), q, output_dn: o, levels, rms_rel: the fitted SDs' RMS relative error}."""
    v = np.array([[p["dark"], p["white"]] for p in photos], float).ravel()
    sd = np.array([[p["dark_sd"], p["white_sd"]] for p in photos], float).ravel()
    var = np.maximum(sd ** 2 - 1.0 / 12.0, 1e-6)
    L = np.array([lin(x) for x in v])
    G = np.array([dlin(x) for x in v])
    M = np.repeat(np.ones(len(photos)) if gains is None else np.asarray(gains, float), 2)

    def before(q):
        return M * (q * L + (read_e * q) ** 2) / G ** 2

    def out2(q):  # the o² that fits best at this q: linear least squares in relative variance, o² >= 0
        return max(float(np.sum((1.0 - before(q) / var) / var) / np.sum(1.0 / var ** 2)), 0.0)

    def cost(log_q):
        q = math.exp(log_q)
        return float(np.sum(((before(q) + out2(q)) / var - 1.0) ** 2))

    q_top = max(float(np.max(var * G ** 2 / L)), q_min) * 10.0
    grid = np.linspace(math.log(q_min), math.log(q_top), 200)
    k = int(np.argmin([cost(x) for x in grid]))
    lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
    best = minimize_scalar(cost, bounds=(lo, hi), method="bounded", options={"xatol": 1e-10}) if hi > lo else None
    log_q = best.x if best is not None and best.fun <= cost(grid[k]) else grid[k]
    q = math.exp(log_q)
    fitted = before(q) + out2(q)
    return {"shot_lin": math.sqrt(q * level), "q": q, "output_dn": math.sqrt(out2(q)), "levels": int(len(v)),
            "rms_rel": float(np.sqrt(np.mean((np.sqrt(fitted / var) - 1.0) ** 2)))}


def photo_output_noise(photo: dict, q: float, lin, dlin, read_e: float, gain: float = 1.0) -> float:
    """One photo's SD after the curve (stored DN), with the set's shot noise ``q`` before it (``curve_noise``): the
    RMS over its dark and (unsaturated) white of what their SDs, less the 8-bit rounding, hold beyond the shot and
    read noise through the curve, times the mask's ``gain`` (0 where they hold less)."""
    levels = [(photo["dark"], photo["dark_sd"])] + ([] if photo["white_saturated"] else
                                                    [(photo["white"], photo["white_sd"])])
    rest = [sd ** 2 - 1.0 / 12.0 - gain * (q * lin(v) + (read_e * q) ** 2) / dlin(v) ** 2 for v, sd in levels]
    return math.sqrt(max(float(np.mean(rest)), 0.0))


def board_centre_m(photo: dict, centre: tuple[float, float], unit_m: float) -> np.ndarray:
    """The board's centre in the camera frame (m) at a photo's pose (``R``, ``translation``): ``centre`` (board
    units, ``centre_model``) carried by the pose."""
    return (np.asarray(photo["R"]) @ [centre[0], centre[1], 0.0] + translation(photo)) * unit_m


def _shading(m: dict, a: TwinAssumptions, lens, square_m: float, linear) -> tuple[dict, list[float]]:
    """The lens shading the photos show beyond the twin's light (``shading.fit_shading`` on the unsaturated photos'
    ``light_levels``, taken to the linear signal by ``linear``), and per photo the median over its light squares of
    what the light and that shading leave of the level at the board's centre (it divides the group's
    irradiance, so that the rendered light squares' median is the photo's)."""
    K, dist = np.asarray(m["K"]), np.asarray(m["dist"])
    centres = light_square_centres(m["pattern"]) if "pattern" in m else np.asarray(m["light_points"], float)
    seen = []
    for p in m["photos"]:
        R, t = np.asarray(p["R"]), np.asarray(translation(p))
        points = (np.c_[centres, np.zeros(len(centres))] @ R.T + t) * square_m
        centre = board_centre_m(p, centre_model(m), square_m)
        uv = project(centres, R, t, K, dist)
        seen.append((light_falloff(points, centre, -R[:, 2], np.asarray(a.light_position_m, float)),
                     field_height(lens, uv[:, 0], uv[:, 1])))
    fit = fit_shading([{"level": np.array([np.nan if v is None else linear(v) for v in p["light_levels"]]),
                        "light": light, "h": h} for p, (light, h) in zip(m["photos"], seen)
                       if not p["white_saturated"] and p.get("light_levels")])
    return fit, [float(np.median(light * lens_shading(h, fit["a2"], fit["a4"]))) for light, h in seen]


def _raw_bits(m: dict) -> int:
    """The ADC's bits for 16-bit photos: the fewest of 8, 10, ..., 16 that hold their largest value."""
    return next(b for b in (8, 10, 12, 14, 16) if 2 ** b - 1 >= m["max_value"])


def _raw_words(m: dict) -> str:
    step = int(m.get("value_step", 1))
    return (f"16-bit photos, taken as a linear sensor's values (raw), a {_raw_bits(m)}-bit ADC (the largest value "
            f"{m['max_value']})" + (f"; the photos store steps of {step}, the twin's of 1" if step > 1 else ""))


def _raw_noise(m: dict, a: TwinAssumptions):
    """The 16-bit photos' gain, read noise and black level (``photon_transfer.sensor_from_noise``) from the dark and
    light squares of the unsaturated photos (a flat white is clipped, and only the darks of the clipped ones)."""
    levels, sds = [], []
    for p in m["photos"]:
        f = p.get("flat_noise") or p
        levels.append(f["dark"])
        sds.append(f["dark_sd"])
        if not p["white_saturated"]:
            levels.append(f["white"])
            sds.append(f["white_sd"])
    return sensor_from_noise(levels, sds, float(m.get("value_step", 1)), a.dark_noise_e, a.black_dn, DARK_NOISE_E,
                             lowest_level_dn=min(p["dark"] for p in m["photos"]))


def _toml_str(text: str) -> str:
    """A TOML basic string (JSON's escapes are TOML's)."""
    return json.dumps(str(text), ensure_ascii=False)


def _comment(text: str, bullet: bool = False, width: int = 116) -> str:
    """``text`` as TOML comment lines of at most ``width`` characters (a bullet: '# - ', continued '#   ')."""
    first, rest = ("# - ", "#   ") if bullet else ("# ", "# ")
    return "\n".join(textwrap.wrap(text, width, initial_indent=first, subsequent_indent=rest,
                                   break_on_hyphens=False, break_long_words=False))


def safe_name(text: str) -> str:
    """``text`` as a spec or group name (``render.schema.NAME_RE``): anything but letters, digits, '-' and '_' as
    '_', starting with a letter or digit, at most 100 characters."""
    name = re.sub(r"[^A-Za-z0-9_-]", "_", str(text))
    name = name if name[:1].isalnum() and name[:1].isascii() else "p" + name
    return name[:100]


def group_name(photo: str) -> str:
    """A spec group's name for a photo file: its stem as ``safe_name`` makes it."""
    return safe_name(Path(photo).stem)
