"""Sample passes (``render/scene/sample_passes.py``): a GPU render is the same bytes run to run.

On CUDA a pixel gets one atomic add per warp its samples touch, and three or more adds land in any order.
The split is checked without a GPU:
- the warps a pixel's samples span, against laying the lanes out one by one;
- on a cuda variant every pass spans at most two warps and the passes sum to the spp; a render of 64 spp or
  fewer that already does (the boards' 64, the frames' 16) stays one pass, with its own seed;
- CPU variants always render in one pass (their bytes, and the shipped results, unchanged);
- the passes are weighted by their spp, in a fixed order, with seeds that depend on (seed, pass) alone;
- the orthogonal sampler keeps one pass (it rounds 64 up to 11^2, and is not bit-reproducible anyway);
- an image's JSON says so where its renders are split (``render.sample_passes``), and has no such key elsewhere;
- a real render split as on a GPU (llvm, an emissive square whose pixel values are its exact coverage)
  matches that coverage as closely as the one-pass render of the same spp does.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from edgetruth.render.scene import sample_passes as sp


def _warps_by_lanes(spp: int, pixels: int = 64) -> int:
    lanes = np.arange(pixels * spp)
    pixel, warp = lanes // spp, lanes // sp.WARP_LANES
    return max(len(np.unique(warp[pixel == p])) for p in range(pixels))


@pytest.mark.parametrize("spp", [1, 2, 16, 31, 32, 33, 34, 40, 48, 50, 63, 64, 65, 96, 100, 128, 1000])
def test_warps_spanned_is_the_lane_layouts(spp):
    assert sp.warps_spanned(spp) == _warps_by_lanes(spp)


@pytest.mark.parametrize("spp", [1, 16, 64, 256, 1024, 4096, 16384, 100, 97, 130, 1000])
def test_cpu_variants_render_in_one_pass(spp):
    for variant in ("llvm_ad_rgb", "scalar_rgb", "llvm_ad_mono"):
        assert sp.pass_spps(spp, variant) == [spp]


@pytest.mark.parametrize("spp", list(range(1, 300)) + [1024, 4096, 16384, 65536])
def test_cuda_passes_span_two_warps_at_most_and_sum_to_the_spp(spp):
    passes = sp.pass_spps(spp, "cuda_ad_rgb")
    assert sum(passes) == spp
    assert all(_warps_by_lanes(n, pixels=40) <= 2 for n in set(passes))
    if _warps_by_lanes(spp, pixels=40) <= 2:
        assert passes == [spp]  # nothing to split: 16 and 64 spp render as before
    assert len(passes) <= -(-spp // sp.MAX_PASS_SPP) + 1


def test_the_study_settings_split_into_passes_of_64():
    assert sp.pass_spps(1024, "cuda_ad_rgb") == [64] * 16
    assert sp.pass_spps(4096, "cuda_ad_rgb") == [64] * 64
    assert sp.pass_spps(64, "cuda_ad_rgb") == [64]
    assert sp.pass_spps(100, "cuda_ad_rgb") == [64, 36]  # 36 consecutive lanes touch two warps at most
    assert sp.pass_spps(114, "cuda_ad_rgb") == [64, 32, 18]  # 50 would touch three


def test_the_orthogonal_sampler_keeps_one_pass():
    assert sp.pass_spps(2209, "cuda_ad_rgb", "orthogonal") == [2209]
    assert sp.pass_spps(1024, "cuda_ad_rgb", "multijitter") == [64] * 16


def test_passes_are_weighted_by_their_spp_in_a_fixed_order():
    calls = []

    def fake(seed, n):  # a "pixel mean" that carries its pass's seed and spp
        calls.append((seed, n))
        return np.full((2, 3), float(n) + (seed % 7), np.float32)

    out = sp.render_in_passes(fake, 12345, 100, "cuda_ad_rgb")
    assert [n for _, n in calls] == [64, 36]
    assert [s for s, _ in calls] == [sp.pass_seed(12345, 0), sp.pass_seed(12345, 1)]
    expect = sum(n * (float(n) + (s % 7)) for s, n in calls) / 100.0
    assert out.dtype == np.float32 and np.allclose(out, expect, rtol=1e-7)
    calls.clear()
    one = sp.render_in_passes(fake, 12345, 64, "cuda_ad_rgb")
    assert calls == [(12345, 64)] and one[0, 0] == 64 + 12345 % 7  # one pass: the caller's seed, untouched


def test_pass_seeds_depend_on_seed_and_pass_alone():
    seeds = [sp.pass_seed(s, k) for s in (0, 1, 2**31 - 1) for k in range(64)]
    assert len(set(seeds)) == len(seeds)
    assert all(0 <= s < 2**31 for s in seeds)
    assert sp.pass_seed(7, 3) == sp.pass_seed(7, 3)


@pytest.mark.slow
def test_a_render_split_as_on_a_gpu_matches_the_exact_coverage(fast_variant, monkeypatch):
    """An emissive square through a perfect lens: each pixel's value is the share of it the square covers
    (``edge_coverage.pixel_coverage``, exact).  At 256 spp split into 4 x 64 as on a GPU, the error against that
    is the one-pass render's, within sampling (their RMS within 35 % of each other, the mean within 4 SE of 0):
    a pass dropped or weighted wrong would double it or bias it.  The independent sampler, for which one pass
    and four are the same estimator (a stratified one stratifies each pass alone: multijitter's RMS here is
    1.42x the one pass's; over 16 seeds the split's mean error is (-0.6 ± 5.4)e-4)."""
    from edgetruth.render.optics.camera import load_camera
    from edgetruth.render.scene import edge_coverage as ec
    from edgetruth.render.scene import emissive
    from edgetruth.render.scene.outline import OutlineCurve
    from edgetruth.render.scene.pose import Pose

    cam = replace(load_camera(), distortion=(0.0,) * 5).ideal_optics()
    pose = Pose(1.5, 0.0123, -0.0071, 0.0, 0.0, roll_deg=7.0)
    crop = (565, 405, 120, 120)  # the square's top-left corner: two sides and the corner
    ys, xs = np.mgrid[crop[1]:crop[1] + crop[3], crop[0]:crop[0] + crop[2]].astype(float)
    truth = ec.pixel_coverage(cam, OutlineCurve(cam, pose, "square", 0.13, standoff_m=0.0), xs, ys)
    edge = (truth > 0.02) & (truth < 0.98)
    assert edge.sum() >= 150

    def render():
        return emissive.render_emissive(cam, [("square", 0.065, pose)], spp=256, seed=11, crop=crop,
                                        sampler="independent")

    one = render()
    real = sp.render_in_passes
    monkeypatch.setattr(emissive, "render_in_passes",
                        lambda f, seed, spp, variant, sampler: real(f, seed, spp, "cuda_ad_rgb", sampler))
    split, again = render(), render()
    assert np.array_equal(split, again)  # the passes' seeds and order are fixed
    assert not np.array_equal(split, one)  # other seeds: the split really ran
    e_one, e_split = (one - truth)[edge], (split - truth)[edge]
    assert np.abs(split - truth)[~edge].max() < 0.03  # whole pixels: exact up to the 2 % band's edge
    rms_one, rms_split = np.sqrt(np.mean(e_one ** 2)), np.sqrt(np.mean(e_split ** 2))
    assert 1 / 1.35 < rms_split / rms_one < 1.35, (rms_one, rms_split)
    assert abs(e_split.mean()) < 4 * rms_split / np.sqrt(edge.sum())


def test_the_json_names_the_passes_where_renders_are_split():
    assert sp.sample_passes_note("llvm_ad_rgb", "multijitter") == {}
    assert sp.sample_passes_note("scalar_rgb", "independent") == {}
    assert sp.sample_passes_note("cuda_ad_rgb", "orthogonal") == {}
    note = sp.sample_passes_note("cuda_ad_rgb", "multijitter")["sample_passes"]
    assert "passes of at most 64" in note and "more than two 32-lane warps" in note and "sample_passes.py" in note
    assert sp.splits("cuda_ad_rgb", "multijitter") and not sp.splits("cuda_ad_rgb", "orthogonal")
    assert not sp.splits("llvm_ad_rgb", "multijitter")
