"""docs/formats.md lists every column and key the code writes (so the documentation cannot drift)."""
from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DOC = (ROOT / "docs" / "formats.md").read_text()
# the sensor and camera parameters a ground truth records are the spec keys of docs/spec.md
DOCUMENTED = set(re.findall(r"`([A-Za-z_][A-Za-z0-9_]*)`", DOC + (ROOT / "docs" / "spec.md").read_text()))


def test_every_locate_csv_column_of_every_builtin_method_is_documented():
    from edgetruth import locate
    from edgetruth.render.synthetic.scenarios import synthetic_image

    s = synthetic_image("ideal", 0, split="unit")
    cand = locate.candidates(s.image)
    missing = {}
    camera = {}
    for m, rec in locate.METHODS.items():
        if not rec.builtin:
            continue
        if rec.needs_camera:  # patch_esf_fit: the edge-spread tables of some camera (a Gaussian PSF here)
            from edgetruth.evaluate import bound_psf as BP

            camera = {"esf": BP.EdgeSpread(BP.Optics(sigma_x_px=0.6, sigma_y_px=0.6), 1.0, 1 << 12).tables()}
        cols = set(locate.refine(s.image, cand, m, **(camera if rec.needs_camera else {})).columns())
        if cols - DOCUMENTED:
            missing[m] = sorted(cols - DOCUMENTED)
    assert not missing, missing


def test_every_ground_truth_and_manifest_key_is_documented(tiny_dataset):
    from edgetruth.render import open_dataset

    ds = open_dataset(tiny_dataset[1])
    keys = set()
    for s in ds:
        gt = s.truth
        keys |= set(gt)
        for k in ("camera", "pose", "target", "outline", "illumination", "sensor", "render", "versions",
                  "checkerboard", "corners", "seeds"):
            if isinstance(gt.get(k), dict):
                keys |= set(gt[k])
    keys |= set(ds.manifest)
    entry = next(iter(ds.manifest["images"].values()))
    keys |= set(entry)
    missing = sorted(keys - DOCUMENTED)
    assert not missing, missing


def test_every_ranging_row_field_is_documented():
    from edgetruth.evaluate.ranging.images import ROW_FIELDS

    assert not sorted(set(ROW_FIELDS) - DOCUMENTED)


SCENE_SPEC = """
[spec]
name = "tinyscene"
camera = "{camera}"
spp = 4
edge_spp = 16
edge_mode = "path"

[[group]]
name = "own"
distance_range_cm = [60, 70]
count = 1
tilt_max_deg = 5
irradiance_w_m2 = 0.0044
ambient = 0.1
board_material = {{albedo = 0.7, texture = "tex.png"}}
shapes = [{{type = "rectangle", width_m = 0.1, height_m = 0.06, material = {{albedo = 0.5, texture = "tex.png"}}}},
          {{type = "ring", offset_m = [0.04, 0.0], outer_diameter_m = 0.05, inner_diameter_m = 0.02, material = {{type = "roughplastic", albedo = 0.2}}}},
          {{type = "polygon", offset_m = [-0.03, 0.0], vertices_m = [[0, 0], [0.01, 0], [0, 0.01]]}},
          {{type = "ellipse", offset_m = [0.0, 0.02], axes_m = [0.02, 0.01], material = {{type = "roughconductor", alpha = 0.2}}}},
          {{type = "circle", offset_m = [0.0, -0.02], diameter_m = 0.01}},
          {{type = "grid", offset_m = [-0.07, 0.0], rows = 2, cols = 2, element = "circle", element_size_m = 0.01, pitch_m = [0.02, 0.02]}}]
clutter = [{{type = "rectangle", offset_m = [0.05, 0.05], width_m = 0.02, height_m = 0.02, raised_m = 0.03}}]
lights = [{{type = "area"}}, {{type = "point", position_m = [0.3, 0.0, -0.05], share = 0.5}},
          {{type = "spot", position_m = [-0.3, 0.0, -0.05], share = 0.3}}]
"""


def _nested_keys(d) -> set:
    """Every key of ``d`` and of the dicts (and lists of dicts) inside it."""
    out = set()
    if isinstance(d, dict):
        for k, v in d.items():
            out.add(k)
            out |= _nested_keys(v)
    elif isinstance(d, list):
        for v in d:
            if isinstance(v, (dict, list)):
                out |= _nested_keys(v)
    return out


def test_every_own_scene_key_is_documented(tmp_path):
    """A group with its own scene (every shape type, a grid, every material and light type, printed textures,
    clutter, an ambient term):
    every key of its ``target``, ``board``, ``shapes`` and ``illumination`` blocks is in docs/formats.md."""
    from edgetruth.render import open_dataset
    from edgetruth.render.dataset.driver import render_spec
    from edgetruth.render.testing import write_tiny_spec

    import cv2
    import numpy as np

    write_tiny_spec(tmp_path, spp=4)
    cv2.imwrite(str(tmp_path / "tex.png"), np.arange(12, dtype=np.uint8).reshape(3, 4) * 20)
    spec = tmp_path / "scene.toml"
    spec.write_text(SCENE_SPEC.format(camera=tmp_path / "tiny_cam.toml"))
    render_spec(spec, tmp_path / "data", progress=False, announce=lambda s: None)
    gt = open_dataset(tmp_path / "data")[0].truth
    assert len(gt["shapes"]) == 6 and len(gt["illumination"]["lights"]) == 3 and "ambient" in gt["illumination"]
    assert "texture" in gt["board"] and "texture" in gt["shapes"][0]
    assert len(gt["clutter"][0]["shadows"]) == 3
    keys = set(gt) | _nested_keys({k: gt[k] for k in ("target", "board", "shapes", "illumination", "clutter")})
    missing = sorted(keys - DOCUMENTED)
    assert not missing, missing
