"""A spec that names no ``edge_mode`` / ``board_mode`` gets the noise-free composites where they are valid (preset
targets T1..T4 and flat boards, a static camera), and the path tracer elsewhere, said once in one line on stderr;
a spec that names a mode renders as it always did; every shipped spec names the modes its images use."""
from __future__ import annotations

import re

import pytest

from edgetruth.errors import InputError
from edgetruth.render.dataset.spec import load_spec
from edgetruth.render.testing import write_tiny_spec


def _tiny(folder, **kw):
    folder.mkdir(parents=True, exist_ok=True)
    return write_tiny_spec(folder, **kw)


def _warnings(capsys) -> list[str]:
    return [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]


def test_no_mode_named_gives_the_composites_where_valid(tmp_path, capsys):
    """The tiny spec (preset T2 targets, a flat checkerboard, static camera) without mode keys: both "frame", no line
    on stderr, and an identity of its own (it renders other images than the spec naming "path")."""
    spec = load_spec(_tiny(tmp_path / "a", modes=""))
    assert (spec.render.edge_mode, spec.render.board_mode) == ("frame", "frame")
    assert _warnings(capsys) == []
    frame = load_spec(_tiny(tmp_path / "b", modes='edge_mode = "frame"\nboard_mode = "frame"\n'))
    path = load_spec(_tiny(tmp_path / "c"))
    assert (path.render.edge_mode, path.render.board_mode) == ("path", "path")
    assert spec.identity_sha256 == frame.identity_sha256 != path.identity_sha256


@pytest.mark.parametrize("change, key, why", [
    (('target = "T2"\n', 'target = "T2"\ntarget_material = { albedo = 0.1 }\n'), "edge_mode", "a scene of its own"),
    (('name = "T2"\n', 'name = "T2"\ncamera = { velocity_m_s = [0.1, 0.0, 0.0] }\n'), "edge_mode", "camera moves"),
    (('kind = "checkerboard"\n', 'kind = "checkerboard"\nboard_bend_mm = [0.5, 0.0, 0.5]\n'), "board_mode",
     "board is curled")])
def test_out_of_scope_falls_back_to_path_in_one_line_once(tmp_path, capsys, change, key, why):
    """Out of the composite's scope, the mode the spec did not name is "path", said in one line naming the group,
    the reason and the fix -- once, however often the spec loads; the other mode keeps its default."""
    p = write_tiny_spec(tmp_path, modes="")
    p.write_text(p.read_text().replace(*change, 1))
    spec = load_spec(p)
    other = "board_mode" if key == "edge_mode" else "edge_mode"
    assert getattr(spec.render, key) == "path" and getattr(spec.render, other) == "frame"
    err = _warnings(capsys)
    assert len(err) == 1 and str(p) in err[0] and f'{key} = "path"' in err[0] and why in err[0], err
    assert "name the mode in [spec]" in err[0] and other not in err[0]
    load_spec(p)
    assert _warnings(capsys) == []  # once per spec, not per load or image
    # named, it renders as named: "path" silently, "frame" refused with the reason
    p.write_text(p.read_text().replace("sampler = ", f'{key} = "path"\nsampler = ', 1))
    assert getattr(load_spec(p).render, key) == "path" and _warnings(capsys) == []
    p.write_text(p.read_text().replace(f'{key} = "path"', f'{key} = "frame"', 1))
    with pytest.raises(InputError, match=key):
        load_spec(p)


def test_both_fallbacks_share_one_line(tmp_path, capsys):
    p = write_tiny_spec(tmp_path, modes="")
    p.write_text(p.read_text().replace('target = "T2"\n', 'target = "T2"\ntarget_material = { albedo = 0.1 }\n', 1)
                 .replace('kind = "checkerboard"\n', 'kind = "checkerboard"\nboard_bend_mm = [0.5, 0.0, 0.5]\n', 1))
    spec = load_spec(p)
    assert (spec.render.edge_mode, spec.render.board_mode) == ("path", "path")
    err = _warnings(capsys)
    assert len(err) == 1 and 'edge_mode = "path"' in err[0] and 'board_mode = "path"' in err[0]


def test_a_mode_no_image_uses_stays_path_and_the_identity_unchanged(tmp_path, capsys):
    """A spec of boards only (or targets only) keeps edge_mode (board_mode) "path", silently: the key changes no
    image, so its identity is the one it had before the default changed."""
    p = _tiny(tmp_path / "boards", modes="")
    text = p.read_text()
    p.write_text(text[:text.index("[[group]]")] + text[text.index('[[group]]\nname = "cal"'):])
    spec = load_spec(p)
    assert (spec.render.edge_mode, spec.render.board_mode) == ("path", "frame")
    assert "edge_mode" not in spec.render.to_dict() and _warnings(capsys) == []
    q = _tiny(tmp_path / "targets", modes="")
    q.write_text(q.read_text()[:q.read_text().index('[[group]]\nname = "cal"')])
    spec = load_spec(q)
    assert (spec.render.edge_mode, spec.render.board_mode) == ("frame", "path")
    assert "board_mode" not in spec.render.to_dict() and _warnings(capsys) == []


def test_every_shipped_spec_names_the_modes_its_images_use(capsys):
    """Each shipped spec names edge_mode if it has target images and board_mode if it has board images (so the
    default never changes a shipped render), and loads without a line on stderr."""
    from edgetruth.resources import shipped_spec, shipped_spec_names

    for name in shipped_spec_names():
        text = shipped_spec(name).read_text()
        spec = load_spec(name)
        kinds = {g.kind for g in spec.groups}
        if "target" in kinds:
            assert re.search(r'(?m)^edge_mode = "', text), name
        if kinds - {"target"}:
            assert re.search(r'(?m)^board_mode = "', text), name
    assert _warnings(capsys) == []



def test_the_benchmarks_own_spec_is_the_issues(tmp_path, capsys):
    """``edgetruth bench --only modes`` renders a new user's spec: 9 full-resolution T1 images at 0.5 / 1.5 / 2.5 m,
    spp 64, edge_spp 4096, no edge_mode key (so "frame", silently), and the same naming "path"."""
    from edgetruth.render.bench import DEFAULT_MODE_SPEC

    specs = {}
    for label, mode in (("default", ""), ("path", 'edge_mode = "path"')):
        p = tmp_path / f"{label}.toml"
        p.write_text(DEFAULT_MODE_SPEC.format(mode=mode).replace('name = "own_t1"', f'name = "own_{label}"'))
        specs[label] = load_spec(p)
    d, p = specs["default"], specs["path"]
    assert "edge_mode" not in DEFAULT_MODE_SPEC.format(mode="")
    assert (d.render.edge_mode, p.render.edge_mode) == ("frame", "path") and _warnings(capsys) == []
    assert (d.render.spp, d.render.edge_spp, d.camera.width_px, d.camera.height_px) == (64, 4096, 1280, 1024)
    assert sorted(j.distance_cm for j in d.jobs) == [50.0] * 3 + [150.0] * 3 + [250.0] * 3
    assert {j.target for j in d.jobs} == {"T1"} and d.n_images == p.n_images == 9
