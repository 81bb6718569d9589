"""Every tutorial script in examples/ runs, at a size that fits CI, and says what it claims; each is a page of
the docs site and is linked from the README."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from tests.support.tools import ROOT, load_tool

EXAMPLES = sorted(p.name for p in (ROOT / "examples").glob("*.py"))


def run(name: str, *argv: str):
    return load_tool(f"examples/{name}", f"example_{name[:-3]}").main(list(argv))


def test_every_example_is_a_page_and_linked_from_the_readme():
    readme = (ROOT / "README.md").read_text()
    pages = {p.name: p.read_text() for p in (ROOT / "docs" / "tutorials").glob("*.md")}
    nav = (ROOT / "mkdocs.yml").read_text()
    assert EXAMPLES, "examples/ is empty"
    for name in EXAMPLES:
        assert f"(examples/{name})" in readme, f"README does not link examples/{name}"
        page = [p for p, text in pages.items() if f'--8<-- "examples/{name}"' in text]
        assert page, f"no docs/tutorials page includes examples/{name}"
        assert f"tutorials/{page[0]}" in nav, f"docs/tutorials/{page[0]} is not in mkdocs.yml's nav"
        assert re.search(rf"\(docs/tutorials/{re.escape(page[0])}\)", readme), f"README does not link {page[0]}"


def test_score_locator_scores_against_truth_and_bound():
    out = run("score_locator.py", "--images", "3")
    assert set(out) == {"canny_pixel", "my_parabola", "erf4p_fixed11"}
    # the pixel centre is ~0.29 px RMS from a random edge; a subpixel fit is far closer; nothing beats its bound
    assert out["canny_pixel"]["rmse_px"] > 0.2
    assert out["erf4p_fixed11"]["rmse_px"] < 0.1
    for m, r in out.items():
        assert r["rmse_px"] > r["bound_px"] > 0, m


def test_sweep_plots_rmse_against_blur(tmp_path):
    out = run("sweep.py", "--images", "2", "--levels", "2", "-o", str(tmp_path / "sweep.png"))
    assert (tmp_path / "sweep.png").stat().st_size > 1000
    assert out["blur_px"] == [0.5, 3.0]
    rmse = out["rmse_px"]["erf4p_fixed11"]
    assert rmse[1] > rmse[0]  # a wider blur, a larger error at the same noise
    assert all(b > 0 for b in out["bound_px"]) and out["bound_px"][1] > out["bound_px"][0]


def test_calibrate_board_on_the_shipped_photos():
    cal = run("calibrate_board.py", "--photos", "5")
    assert cal["n_views"] == 5
    assert 520 < cal["fx_px"] < 550  # OpenCV's left photos: fx ~534 px
    assert cal["reprojection_rms_px"] < 0.5


def test_render_scene_reads_its_truth(fast_variant):
    out = run("render_scene.py", "--scale", "8")
    assert len(out) == 2
    assert all(np.isfinite(v) and v < 1.0 for v in out.values())


# renders 2 images and runs evaluate --photos: ~5 s once the JIT cache is warm
def test_range_photos_ranges_against_the_reference(fast_variant):
    rows = run("range_photos.py", "--scale", "4", "--photos", "2")
    assert {r["method"] for r in rows} == {"canny_pixel", "erf4p_fixed11", "patch_psf_fit"}
    errs = [abs(float(r["error_cm"])) for r in rows if r["method"] == "patch_psf_fit"]
    assert len(errs) == 2 and max(errs) < 2.0  # within 2 cm at 60-150 cm on 160x128 px


def test_ray_scale_out_gives_the_same_bytes(fast_variant):
    pytest.importorskip("ray", reason="ray is not installed: pip install 'edgetruth[cluster]'")
    mod = load_tool("examples/ray_scale_out.py", "example_ray_scale_out")
    try:
        out = mod.main(["--images", "2"])
    except mod.RayUnavailable as exc:
        pytest.skip(str(exc))
    assert out == {"identical": True, "images": 2}


def test_the_readme_python_example_runs(capsys):
    block = re.search(r"## In Python\n\n```python\n(.*?)```", (ROOT / "README.md").read_text(), re.S).group(1)
    assert len(block.strip().splitlines()) <= 15
    exec(compile(block, "README.md", "exec"), {})
    out = capsys.readouterr().out
    rmse = float(re.search(r"RMSE ([0-9.]+) px", out).group(1))
    assert rmse < 0.1  # dynamic 4P on an analytic Ideal edge
