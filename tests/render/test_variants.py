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
