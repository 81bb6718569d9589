"""Variant choice: subprocess probes, caching, overrides."""
from __future__ import annotations

import glob
import os

import pytest

from edgetruth.errors import InputError
from edgetruth.render import variants


def test_choice_is_working_and_announced():
    lines = []
    v = variants.choose_variant(announce=lines.append)
    assert v in variants.ORDER and len(lines) == 1 and v in lines[0]
    assert variants.probe(v) == (True, "")
    if v == "scalar_rgb":
        assert "karellen-llvm-core" in lines[0]  # the fallback says how to get the fast variant


def test_probe_is_cached(monkeypatch):
    variants.probe("scalar_rgb")
    monkeypatch.setattr(variants, "probe_uncached", lambda *a, **k: pytest.fail("probed twice"))
    assert variants.probe("scalar_rgb")[0]


def test_requested_variant_overrides_and_bad_name_is_input_error():
    import mitsuba as mi

    assert variants.choose_variant("scalar_rgb", announce=lambda s: None) == "scalar_rgb"
    assert mi.variant() == "scalar_rgb"
    with pytest.raises(InputError, match="not in this Mitsuba build"):
        variants.choose_variant("nonsense_rgb", announce=lambda s: None)
    variants.choose_variant(announce=lambda s: None)  # restore the best one for later tests


@pytest.mark.skipif(not glob.glob("/usr/lib/x86_64-linux-gnu/libLLVM-1[0-7].so*"),
                    reason="no libLLVM older than 18 on this machine to provoke the abort with")
def test_old_libllvm_abort_is_contained_in_the_probe():
    old = sorted(glob.glob("/usr/lib/x86_64-linux-gnu/libLLVM-1[0-7].so*"))[-1]
    ok, reason = variants.probe_uncached("llvm_ad_rgb", env={**os.environ, "DRJIT_LIBLLVM_PATH": old})
    assert not ok and reason  # this process is still alive to see it


def test_pip_libllvm_is_configured_when_present():
    p = variants.pip_libllvm_path()
    if p is None:
        pytest.skip("karellen-llvm-core is not installed in this environment")
    assert os.environ.get("DRJIT_LIBLLVM_PATH")


def test_requested_variant_that_does_not_run_here_is_input_error(monkeypatch):
    """A variant built into Mitsuba that cannot run here (cuda_ad_rgb on a machine without a GPU) is one
    InputError naming the variant, its reason and the fix, not a traceback from Mitsuba."""
    import mitsuba as mi

    before = mi.variant()
    monkeypatch.setattr(variants, "_cache", {"cuda_ad_rgb": (False, "ImportError: the CUDA backend hasn't been "
                                                             "initialized")})
    with pytest.raises(InputError,
                       match=r"--variant cuda_ad_rgb: does not run here \(ImportError.*leave --variant out"):
        variants.choose_variant("cuda_ad_rgb", announce=lambda s: None)
    assert mi.variant() == before  # nothing was switched


def test_requested_cuda_variant_on_the_cli_is_one_line_and_exit_2(tmp_path):
    """Where cuda_ad_rgb does not run (CI has no GPU), `edgetruth render --variant cuda_ad_rgb` says so in one
    line on stderr and exits 2, writing no image."""
    import subprocess
    import sys

    if variants.probe("cuda_ad_rgb")[0]:
        pytest.skip("cuda_ad_rgb runs on this machine")
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "edgetruth", "render", "quick", "--variant", "cuda_ad_rgb",
                        "--only", "0", "-j", "1", "-o", str(out)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "--variant cuda_ad_rgb: does not run here" in lines[0], r.stderr
    assert not list(out.glob("*.png"))
