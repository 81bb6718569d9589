"""Specs: one typed object from one loader; cameras by name or relative path; per-group overrides;
docs/spec.md generated from the same key tables."""
from __future__ import annotations

from pathlib import Path

import pytest

from edgetruth.errors import InputError
from edgetruth.render.dataset.spec import load_spec

ROOT = Path(__file__).resolve().parents[3]

from edgetruth.render.testing import TINY_CAMERA as CAMERA  # 64 x 48 px, f/4, focus 1.5 m, mild barrel

SPEC = """
[spec]
name = "sweep"
camera = "cams/mine.toml"
spp = 4

[sensor]
gain_db = 3.0

[[group]]
name = "f2"
target = "T1"
count = 3
distance_range_cm = [60, 90]
camera = {{ f_number = 2.0, focus_distance_m = 0.8 }}
sensor = {{ exposure_s = 0.02 }}

[[group]]
name = "f8"
target = "T1"
count = 2
{extra}
"""


def _write(tmp_path: Path, extra: str = "camera = { f_number = 8.0 }") -> Path:
    (tmp_path / "specs" / "cams").mkdir(parents=True)
    (tmp_path / "specs" / "cams" / "mine.toml").write_text(CAMERA)
    p = tmp_path / "specs" / "sweep.toml"
    p.write_text(SPEC.format(extra=extra))
    return p


def test_camera_path_is_relative_to_the_spec_and_groups_override_it(tmp_path, monkeypatch):
    p = _write(tmp_path)
    monkeypatch.chdir(tmp_path)  # not the spec's folder: the camera is still found
    spec = load_spec(p)
    assert spec.camera.width_px == 64 and spec.camera.f_number == 4.0
    f2, f8 = spec.groups
    assert (f2.camera.f_number, f2.camera.focus_distance_m) == (2.0, 0.8)
    assert f8.camera.f_number == 8.0 and f8.camera.focus_distance_m == 1.5
    assert f2.sensor.exposure_s == 0.02 and f2.sensor.gain_db == 3.0 and f8.sensor.exposure_s == 0.01
    jobs = list(spec.jobs)
    assert [j.name for j in jobs] == ["0000_f2", "0001_f2", "0002_f2", "0003_f8", "0004_f8"]
    assert jobs[3].camera.f_number == 8.0 and jobs[0].camera.aperture_radius_m == pytest.approx(0.002)
    assert all(60 <= j.distance_cm <= 90 for j in jobs[:3])
    assert len({j.seed for j in jobs}) == 5


def test_identity_hash_follows_values_not_text(tmp_path):
    p = _write(tmp_path)
    a = load_spec(p)
    p.write_text(p.read_text().replace("spp = 4", "spp = 4  # same value, new comment"))
    assert load_spec(p).identity_sha256 == a.identity_sha256
    (p.parent / "cams" / "mine.toml").write_text(CAMERA.replace("f_number = 4.0", "f_number = 5.6"))
    assert load_spec(p).identity_sha256 != a.identity_sha256  # the camera file is part of the spec


@pytest.mark.parametrize("extra, expect", [
    ('camera = { width_px = 32 }', "fix the intrinsics"),
    ('camera = { f_number = -1 }', "f_number"),
    ('camera = { lens = 1 }', "unknown key"),
    ('sensor = { gain_db = "high" }', "gain_db"),
])
def test_bad_group_overrides_are_one_line_errors(tmp_path, extra, expect):
    p = _write(tmp_path, extra)
    with pytest.raises(InputError) as info:
        load_spec(p)
    assert expect in str(info.value) and "group 'f8'" in str(info.value) and "\n" not in str(info.value)


def test_absurd_camera_size_is_refused_before_anything_is_allocated(tmp_path):
    p = _write(tmp_path)
    (p.parent / "cams" / "mine.toml").write_text(CAMERA.replace("width_px = 64", "width_px = 16384")
                                                 .replace("height_px = 48", "height_px = 16384"))
    with pytest.raises(InputError, match="exceeds"):
        load_spec(p)


def test_jobs_are_computed_on_demand_for_huge_specs(tmp_path):
    p = _write(tmp_path)
    p.write_text(p.read_text().replace("count = 2\n", "count = 900000\n"))
    spec = load_spec(p)
    assert spec.n_images == 900003 and len(spec.jobs) == 900003
    assert spec.jobs[900002].name == "900002_f8" and spec.jobs[-1].index == 900002
    with pytest.raises(IndexError):
        spec.jobs[900003]


def test_shipped_specs_load():
    from edgetruth.resources import shipped_spec_names

    names = shipped_spec_names()
    assert {"quick", "study", "calibration"} <= set(names)
    for n in names:
        assert load_spec(n).n_images > 0


def test_docs_spec_md_is_generated_from_the_key_tables():
    from edgetruth.render.dataset.spec_doc import spec_markdown

    doc = (ROOT / "docs" / "spec.md").read_text()
    assert doc == spec_markdown(), "docs/spec.md is stale: python -m edgetruth.render.dataset.spec_doc > docs/spec.md"
    for key in ("irradiance_w_m2", "f_number", "dark_offset_dn", "distance_intervals_cm", "square_m"):
        assert f"`{key}`" in doc


def test_groups_sweep_the_optics_and_motion(tmp_path):
    p = _write(tmp_path, extra='camera = { aberration_sigma_um = 3.0, olpf_split_um = 2.0, '
                                'velocity_m_s = [0.2, 0.0, 0.0], natural_vignetting = false }')
    spec = load_spec(p)
    g = spec.group("f8").camera
    assert (g.aberration_sigma_um, g.olpf_split_um, g.velocity_m_s, g.natural_vignetting) == (3.0, 2.0, (0.2, 0.0, 0.0),
                                                                                              False)
    assert spec.group("f2").camera.aberration_sigma_um == spec.camera.aberration_sigma_um  # untouched
    with pytest.raises(InputError, match="pitch_um fix the intrinsics"):
        load_spec(_write(tmp_path / "b", extra="camera = { pitch_um = 3.0 }"))


def test_sample_counts_are_powers_of_two(tmp_path):
    """A pixel's samples must not straddle two of Dr.Jit's work blocks (ulp-level differences with
    the thread count): spp and edge_spp are powers of two up to 2^14 -- of four for multijitter,
    which rounds other counts up to a near-square grid (32 -> 35)."""
    p = _write(tmp_path)
    p.write_text(p.read_text().replace("spp = 4", "spp = 49"))
    with pytest.raises(InputError, match="spp = 49: use 16 or 64 -- a power of four"):
        load_spec(p)
    p.write_text(p.read_text().replace("spp = 49", "spp = 32"))
    with pytest.raises(InputError, match="spp = 32: use 16 or 64 -- a power of four .*multijitter"):
        load_spec(p)
    p.write_text(p.read_text().replace("spp = 32", "spp = 64\nedge_spp = 1000"))
    with pytest.raises(InputError, match="edge_spp = 1000: use 256 or 1024"):
        load_spec(p)
    p.write_text(p.read_text().replace("edge_spp = 1000", "edge_spp = 32768"))
    with pytest.raises(InputError, match="use at most 16384"):
        load_spec(p)
    p.write_text(p.read_text().replace("edge_spp = 32768", "edge_spp = 4096"))
    assert (load_spec(p).render.spp, load_spec(p).render.edge_spp) == (64, 4096)
