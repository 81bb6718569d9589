"""The fast renderer from a plain install: karellen-llvm-core is a dependency where it has wheels, its
libLLVM is found in the interpreter's own prefix, and where only scalar_rgb works one line on stderr
says exactly what to install.  (A wheel installed into a clean venv rendering with llvm_ad_rgb is
checked in tests/package/test_wheel.py.)"""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

from edgetruth.render import variants

ROOT = Path(__file__).resolve().parents[2]


def test_the_pip_libllvm_is_a_dependency_with_platform_markers():
    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover
        import tomli as tomllib
    deps = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]
    dep = next(d for d in deps if d.startswith("karellen-llvm-core"))
    assert "sys_platform == 'linux'" in dep and "platform_machine == 'x86_64'" in dep


@pytest.mark.parametrize("system,machine,words", [
    ("Linux", "x86_64", ["-m pip install karellen-llvm-core", "libllvm19"]),
    ("Linux", "aarch64", ["libllvm19", "DRJIT_LIBLLVM_PATH"]),
    ("Darwin", "arm64", ["brew install llvm", "DRJIT_LIBLLVM_PATH"]),
    ("Windows", "AMD64", ["DRJIT_LIBLLVM_PATH", "LLVM-C.dll"]),
])
def test_the_hint_says_what_to_install_here(monkeypatch, system, machine, words):
    monkeypatch.setattr(variants.platform, "system", lambda: system)
    monkeypatch.setattr(variants.platform, "machine", lambda: machine)
    monkeypatch.setattr(variants, "pip_libllvm_path", lambda: None)
    hint = variants.llvm_hint()
    assert "\n" not in hint and all(w in hint for w in words), hint


def test_scalar_fallback_is_one_line_on_stderr(monkeypatch, capsys):
    import mitsuba as mi

    lines, before = [], mi.variant()
    with monkeypatch.context() as m:
        m.setattr(variants, "_warned", set())  # once per process: this test's own
        m.setattr(variants, "available", lambda v: True)
        m.setattr(variants, "probe", lambda v: (v == "scalar_rgb", "" if v == "scalar_rgb" else "LLVM ERROR: old"))
        try:
            assert variants.choose_variant(announce=lines.append) == "scalar_rgb"
        finally:
            if before:
                mi.set_variant(before)
    err = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "slow fallback" in lines[0] and "LLVM ERROR: old" in lines[0]
    assert len(err) == 1 and err[0].startswith("warning: render: ") and "install" in err[0], err


def test_no_line_on_stderr_when_the_fast_variant_works(capsys):
    v = variants.choose_variant(announce=lambda s: None)
    if v == "scalar_rgb":
        pytest.skip("only scalar_rgb works here")
    assert capsys.readouterr().err == ""


def test_the_pip_libllvm_is_found_from_the_package_record(monkeypatch, tmp_path):
    """Found without a venv layout (``--user`` or ``--prefix`` installs): through the package's file list."""
    here = variants.pip_libllvm_path()
    if here is None:
        pytest.skip("karellen-llvm-core is not installed here")
    monkeypatch.setattr(variants.sys, "prefix", str(tmp_path))
    found = variants.pip_libllvm_path()
    assert found is not None and found.resolve() == here.resolve()
