"""Write ``scenes/opencv_left_twin.toml`` and ``assets/cameras/opencv_left.toml`` from the measurements of
``tools/twins/opencv_left_measure.py`` (not packaged).

    python tools/twins/opencv_left_measure.py > /tmp/opencv_left_twin.json
    python tools/twins/opencv_left_scene.py /tmp/opencv_left_twin.json

What is measured and what is assumed is written into both files' headers (and docs/board.md).
"""
from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np

from edgetruth.render.sensor.linear_model import SensorModel

ROOT = Path(__file__).resolve().parents[2]
SIDE_M = 0.025              # assumed: the board's printed square (not published; it scales the poses only)
PITCH_UM = 6.0              # assumed: a 640 x 480 sensor of 3.84 x 2.88 mm
F_NUMBER = 4.0              # assumed
WAVELENGTH_NM = 550.0
GAIN = 1.6                  # output_gain: the 8-bit 255 is 1/1.6 of the ADC's range, so whites above 255 exist
PRE_JPEG_WHITE_SD = 4.5     # 8-bit noise SD at a white of 220 before the JPEG (the photos' 2.1 is after it): closed
                            # loop, 3 and 6 gave white SDs after the JPEG below and above the photos' (docs/board.md)
WHITE_REF = 220.0
BOARD_REFLECTANCE = 0.8
DARK_NOISE_E = 15.0         # with 2 e-, the JPEG left the dark squares half the photos' SD


def airy_sigma_px() -> float:
    """The Gaussian that matches the Airy core's (0.42 λN) in px."""
    return 0.42 * WAVELENGTH_NM * 1e-3 * F_NUMBER / PITCH_UM


def main(path: str) -> None:
    d = json.loads(Path(path).read_text())
    K, dist, photos = np.asarray(d["K"]), d["dist"], d["photos"]
    clean = [p for p in photos if not p["white_saturated"]]
    ratio = float(np.median([p["white"] / p["dark"] for p in clean]))
    sig_x = float(np.median([p["sigma_x_px"] for p in clean]))
    sig_y = float(np.median([p["sigma_y_px"] for p in clean]))
    ring = [float(np.median([p["ring"][a] for p in photos])) for a in ("x", "y")]
    dist_m = float(np.median([p["t_squares"][2] for p in photos])) * SIDE_M

    # sensor: shot-noise limited (the photos' dark and white SDs go as the square root of the level)
    s0 = SensorModel()
    span = s0.max_dn - s0.dark_offset_dn
    k = PRE_JPEG_WHITE_SD ** 2 * span / (255.0 * GAIN * WHITE_REF)          # DN per electron
    ppr = s0.photons_per_radiance(F_NUMBER, PITCH_UM)                      # photons per W m^-2 sr^-1

    def irradiance(white_8bit: float) -> float:
        electrons = white_8bit * span / (255.0 * GAIN * k)
        return electrons * math.pi / (s0.qe * ppr * BOARD_REFLECTANCE)

    def aberration_um(sigma_px: float) -> float:
        return PITCH_UM * math.sqrt(max(sigma_px ** 2 - 1.0 / 12.0 - airy_sigma_px() ** 2, 0.0))

    cam = f"""# The camera of OpenCV's left01-14 sample photos (assets/real/opencv_left), as edgetruth measured it: Zhang's
# calibration on the 54 line corners of every photo (ERF4P-fixed11, the grid lines fitted in the undistorted image;
# `edgetruth calibrate opencv_left --pattern 9x6 --corners lines`), RMS {d['rms_px']:.4f} px.  Written by
# tools/twins/opencv_left_scene.py.
# Assumed (nothing published): the pixel pitch ({PITCH_UM} um), the f-number (f/{F_NUMBER:g}) and the focus (the
# median board distance, with a square of {SIDE_M * 1000:g} mm); they set f = fx * pitch and the defocus, which is
# small here.  The lens blur is the median of the unsaturated photos' ERF sigma per axis
# (edgetruth.evaluate.board.photo_model: {sig_x:.3f} px along x, {sig_y:.3f} px along y) less the pixel and the Airy
# core (in quadrature); the twin scene sets it per photo only where a photo's own sigma is unbiased.
[camera]
width_px = 640
height_px = 480
pitch_um = {PITCH_UM}
fx_px = {K[0, 0]:.4f}
fy_px = {K[1, 1]:.4f}
cx_px = {K[0, 2]:.4f}
cy_px = {K[1, 2]:.4f}
f_number = {F_NUMBER}
focus_distance_m = {dist_m:.4f}
diffraction_wavelength_nm = {WAVELENGTH_NM}
aberration_sigma_um = {aberration_um(sig_x):.3f}
aberration_sigma_y_um = {aberration_um(sig_y):.3f}
aberration_sigma_growth = 0.0
natural_vignetting = false

[camera.distortion]
k1 = {dist[0]:.6f}
k2 = {dist[1]:.6f}
p1 = {dist[2]:.6f}
p2 = {dist[3]:.6f}
k3 = {dist[4]:.6f}
"""
    (ROOT / "assets/cameras/opencv_left.toml").write_text(cam)

    groups = []
    for i, p in enumerate(photos):
        sat = p["white_saturated"]
        white = p["dark"] * ratio if sat else p["white"]
        sx = sig_x if sat else p["sigma_x_px"]
        sy = sig_y if sat else p["sigma_y_px"]
        R = ", ".join("[" + ", ".join(f"{v:.7f}" for v in row) + "]" for row in p["R"])
        t = ", ".join(f"{v:.5f}" for v in p["t_squares"])
        sensor = f"output_clip_dn = {p['white']:.1f}" if sat else ""
        note = (f"white saturated at {p['white']:.0f} (SD {p['white_sd']:.2f}); before the clip dark x {ratio:.2f} = "
                f"{white:.0f}; blur: the unsaturated photos' median" if sat else
                f"white {p['white']:.1f}, dark {p['dark']:.1f}; blur: its own")
        groups.append(f"""[[group]]  # {p['photo']}: {note}
name = "{Path(p['photo']).stem}"
kind = "squares"
irradiance_w_m2 = {irradiance(white):.4f}
light_position_m = [0.0, -1.5, -2.0]
pose_unit_m = {SIDE_M}
camera = {{ aberration_sigma_um = {aberration_um(sx):.3f}, aberration_sigma_y_um = {aberration_um(sy):.3f} }}
{"sensor = { " + sensor + " }" if sensor else ""}
poses = [{{ R = [{R}], t = [{t}] }}]
""".replace("\n\n", "\n"))
    scene = f"""# A digital twin of OpenCV's left01-14 sample photos (assets/real/opencv_left): a 9x6 chessboard, the camera
# edgetruth calibrated on them (assets/cameras/opencv_left.toml), one group per photo at the pose its line corners
# give (cv2.solvePnP on the board study's chessboard model; t in squares).  Written by
# tools/twins/opencv_left_scene.py from tools/twins/opencv_left_measure.py's measurements; docs/board.md.
# Measured on the photos:
# - the board: 10 x 7 squares, the outer ring cut at {ring[0]:.2f} (x) and {ring[1]:.2f} (y) of a square beyond the
#   outermost inner corners (median over the photos);
# - tone: stored close to linear (the unsaturated photos' power 0.86-1.11; --tone auto): output_gamma = 1;
# - JPEG: every photo's quantisation table is the IJG table at quality 50 exactly: output = "jpeg", quality 50;
# - levels: each photo's white at its light squares' centres (its exposure, irradiance_w_m2 here); the print's
#   contrast, white / dark = {ratio:.2f} (median of the unsaturated photos), sets the squares' reflectance;
# - saturation: 6 photos' whites are flat (noise SD < half the dark's) at 246-250: output_clip_dn there, with the
#   white before the clip their dark level x {ratio:.2f};
# - noise: shot-noise limited (dark SD 0.5-1.0 at 19-35, white SD 1.8-2.2 at 195-239: as the square root of the
#   level): a sensor of K = {k:.4f} DN/e-, {DARK_NOISE_E:g} e- read noise.  The photos' noise is measured after
#   their JPEG, the twin's set before it ({PRE_JPEG_WHITE_SD:g} DN at a white of {WHITE_REF:g}) by a closed loop
#   through the JPEG (the twin study's Table 3 compares both).
# Not reproduced: the room behind the board (black here), the board's rounded white margin, uneven light.
[spec]
name = "opencv_left_twin"
description = "digital twin of OpenCV's left01-14 chessboard photos: their camera, board, poses, exposure, clip and JPEG"
camera = "opencv_left"
spp = 256
sampler = "multijitter"

[spec.squares]
chessboard = "9x6"
side_m = {SIDE_M}
ring = [{ring[0]:.3f}, {ring[1]:.3f}]
margin_m = {0.35 * SIDE_M:.5f}
square_reflectance = {BOARD_REFLECTANCE / ratio:.4f}
board_reflectance = {BOARD_REFLECTANCE}

[sensor]
output = "jpeg"
jpeg_quality = 50
output_gamma = 1.0
output_gain = {GAIN}
k0_dn_per_e = {k:.5f}
dark_noise_e = {DARK_NOISE_E}
full_well_e = 100000.0

""" + "\n".join(groups)
    (ROOT / "scenes/opencv_left_twin.toml").write_text(scene)


if __name__ == "__main__":
    main(sys.argv[1])
