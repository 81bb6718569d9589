"""tools/device/prepare.py: the pruned Mitsuba wheel the GPU check carries keeps every RGB variant and
what loads it, and its RECORD lists exactly the files it holds."""
from __future__ import annotations

import zipfile

import pytest

from tests.support.tools import load_tool


@pytest.fixture(scope="module")
def prepare():
    return load_tool("tools/device/prepare.py", "device_prepare")


KEPT = ["mitsuba/__init__.py", "mitsuba/libmitsuba.so", "mitsuba/config.py",
        "mitsuba/cuda_ad_rgb.cpython-312-x86_64-linux-gnu.so", "mitsuba/llvm_ad_rgb.cpython-312-x86_64-linux-gnu.so",
        "mitsuba/scalar_rgb.cpython-312-x86_64-linux-gnu.so", "mitsuba/plugins/diffuse.so",
        "mitsuba/plugins/roughplastic.so", "mitsuba/plugins/rectangle.so", "mitsuba/plugins/direct.so",
        "mitsuba/data/srgb.coeff", "mitsuba/python/util.py"]
DROPPED = ["mitsuba/cuda_ad_spectral.cpython-312-x86_64-linux-gnu.so",
           "mitsuba/llvm_ad_mono_polarized.cpython-312-x86_64-linux-gnu.so",
           "mitsuba/scalar_spectral.cpython-312-x86_64-linux-gnu.so", "mitsuba/include/mitsuba/core/fwd.h",
           "mitsuba/plugins/volpathmis.so", "mitsuba/plugins/sunsky.so", "mitsuba/plugins/timed_sunsky.so",
           "mitsuba/plugins/ellipsoidsmesh.so", "mitsuba/plugins/sdfgrid.so", "mitsuba/data/sunsky/x.bin"]


def test_pruned_wheel_keeps_rgb_variants_and_rewrites_record(prepare, tmp_path):
    src, dst = tmp_path / "in.whl", tmp_path / "out.whl"
    record = "mitsuba-3.9.1.dist-info/RECORD"
    with zipfile.ZipFile(src, "w") as z:
        for name in KEPT + DROPPED:
            z.writestr(name, b"x" * 1000)
        z.writestr(record, "".join(f"{n},sha256=abc,1000\n" for n in KEPT + DROPPED) + f"{record},,\n")
    n, saved = prepare.prune_wheel(src, dst)
    with zipfile.ZipFile(dst) as z:
        names = set(z.namelist())
        listed = {line.split(",")[0] for line in z.read(record).decode().splitlines()}
    assert n == len(DROPPED) and saved > 0
    assert names == set(KEPT) | {record}
    assert listed == names
