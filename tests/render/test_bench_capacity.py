"""The capacity plan ``make bench`` prints (``render.bench.capacity_lines``, docs/cluster.md), from given measurements.

- On a CPU variant a full frame costs 1280 x 1024 x 64 samples at the per-core rate (the window's rate over the
  cores) plus the fixed part outside mi.render, per CPU core, and the GPU line says no GPU was measured.
- On a cuda variant the window's rate is the GPU's whole: the frame time and frames/h are per GPU, and the GPU
  line gives R, the rate docs/cluster.md's formula needs.
"""
from __future__ import annotations

import re

from edgetruth.render.bench import FULL_FRAME, capacity_lines

PATCHES = {3000: {"ms_per_image": 28.0, "mi_render": 13.0, "journal": 0.1, "write": 0.5, "image_bytes": 42_300.0,
                  "manifest_bytes": 467.0, "resume_us_per_image": 200.0}}


def _frames(variant, rate):
    return {"variant": variant, "samples_per_s": rate, "cores": 2, "overhead_s": 0.25, "bytes": 6.4e6,
            "compact_us": 18.0, "ray_tasks_per_s": None}


def test_cpu_frames_are_per_core():
    lines = capacity_lines(PATCHES, _frames("llvm_ad_rgb", 5.8e6))
    w, h, spp = FULL_FRAME
    frame_s = w * h * spp / (5.8e6 / 2) + 0.25  # 29.2 s
    line = next(s for s in lines if "full frames" in s)
    assert f"~{frame_s:.0f} s per frame per core" in line and "2.9 M samples/s per core" in line
    assert f"{3600 / frame_s:.0f} frames/h per CPU core" in line
    assert any("no GPU here" in s for s in lines)


def test_gpu_frames_are_per_gpu_and_give_r():
    lines = capacity_lines(PATCHES, _frames("cuda_ad_rgb", 2.0e9))
    w, h, spp = FULL_FRAME
    frame_s = w * h * spp / 2.0e9 + 0.25  # 0.29 s: the fixed part is most of it
    line = next(s for s in lines if "full frames" in s)
    assert f"~{frame_s:.2f} s per frame per GPU" in line and f"{3600 / frame_s:.0f} frames/h per GPU" in line
    assert "per core" not in line
    gpu = next(s for s in lines if "GPU worker" in s)
    assert "R = 2000.0 M samples/s" in gpu and "no GPU here" not in gpu
    assert re.search(r"at most [\d,]+ tiny images/h", gpu)
