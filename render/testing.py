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
{modes}sampler = "multijitter"
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


#: the tiny spec's ``[spec]`` lines naming the path tracer (the reference) for targets and boards: the tests
#: written on it assert path-traced renders; a spec that names no mode gets the composites (docs/spec.md)
PATH_MODES = 'edge_mode = "path"\nboard_mode = "path"\n'


def write_tiny_spec(tmp_path: Path, spp: int = 16, edge_spp: int = 64, modes: str = PATH_MODES) -> Path:
    """Write a 64×48-pixel camera and a 3-image spec (2 circles, 1 checkerboard) into ``tmp_path``; ``modes``:
    its ``[spec]`` lines naming edge_mode and board_mode (default: both "path"; "" names none)."""
    cam = tmp_path / "tiny_cam.toml"
    cam.write_text(TINY_CAMERA)
    spec = tmp_path / "tiny.toml"
    spec.write_text(TINY_SPEC.format(camera=cam, spp=spp, edge_spp=edge_spp, modes=modes))
    return spec


def tiny_spec_pair(tmp_path: Path, settings: str, spp: int = 16, edge_spp: int = 64):
    """(spec, reference): the tiny spec (``write_tiny_spec``) with the ``[spec]`` lines ``settings`` added (a
    mode they do not name stays "path"), and the path-traced reference without them -- the same name, so the
    same seeds and poses."""
    from edgetruth.render.dataset.spec import load_spec

    named = [ln for ln in PATH_MODES.splitlines() if ln.split(" =")[0] not in settings]
    path = write_tiny_spec(tmp_path, spp=spp, edge_spp=edge_spp, modes="".join(f"{ln}\n" for ln in named))
    text = path.read_text()
    path.write_text(text.replace("sampler = ", settings.rstrip("\n") + "\nsampler = ", 1))
    spec = load_spec(path)
    path = write_tiny_spec(tmp_path, spp=spp, edge_spp=edge_spp)
    return spec, load_spec(path)


def write_patch_spec(tmp_path: Path, n_images: int, name: str = "patches") -> Path:
    """A spec of ``n_images`` tiny training patches: the default camera binned 32x (40x32 px), 1 spp,
    the four targets in turn over 1.2-2 m with lateral offsets and tilts."""
    per, groups = n_images // 4, []
    for k, target in enumerate(("T1", "T2", "T3", "T4")):
        count = per if k < 3 else n_images - 3 * per
        if count:
            groups.append(f'[[group]]\nname = "{target}"\ntarget = "{target}"\ndistance_range_cm = [120, 200]\n'
                          f"count = {count}\nlateral_fraction = 0.5\ntilt_max_deg = 10\n"
                          # 32x32-binned pixels collect 1024x the light: the study's 1.2 W/m^2 / 1024
                          "irradiance_w_m2 = 0.0012\n")
    spec = Path(tmp_path) / f"{name}.toml"
    # path-traced: the figures are the fixed cost of an image around one small mi.render
    spec.write_text(f'[spec]\nname = "{name}"\ncamera_scale = 32\nspp = 1\nedge_mode = "path"\n\n' + "\n".join(groups))
    return spec
