"""Small fixtures for tests of the renderer (like ``numpy.testing``): a tiny camera and spec."""
from __future__ import annotations

from pathlib import Path

TINY_CAMERA = """
[camera]
width_px = 64
height_px = 48
pitch_um = 96.0
focal_length_mm = 8.0
f_number = 4.0
focus_distance_m = 1.5
[camera.distortion]
k1 = -0.08
k2 = 0.03
p1 = 0.0002
p2 = -0.0001
"""

TINY_SPEC = """
[spec]
name = "tiny"
camera = "{camera}"
spp = {spp}
edge_spp = {edge_spp}
sampler = "multijitter"
checkerboard = {{ cols = 6, rows = 5, square_m = 0.03, margin_m = 0.03 }}

[[group]]
name = "T2"
target = "T2"
distance_range_cm = [60, 90]
count = 2
lateral_fraction = 0.5
tilt_max_deg = 5
irradiance_w_m2 = 0.0044

[[group]]
name = "cal"
kind = "checkerboard"
distance_range_cm = [70, 90]
count = 1
tilt_max_deg = 20
irradiance_w_m2 = 0.0044
"""


def write_tiny_spec(tmp_path: Path, spp: int = 16, edge_spp: int = 36) -> Path:
    """Write a 64×48-pixel camera and a 3-image spec (2 circles, 1 checkerboard) into ``tmp_path``."""
    cam = tmp_path / "tiny_cam.toml"
    cam.write_text(TINY_CAMERA)
    spec = tmp_path / "tiny.toml"
    spec.write_text(TINY_SPEC.format(camera=cam, spp=spp, edge_spp=edge_spp))
    return spec
