"""Fixtures shared by every test package."""
from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def fast_variant() -> str:
    """The Mitsuba variant for tests that render full frames; skips them on scalar_rgb, where the
    Python distortion sensor runs once per sample (hours for these tests).  `make` installs the pip
    libLLVM that enables llvm_ad_rgb; `edgetruth.render.variants` says how when it is missing."""
    from edgetruth.render.variants import choose_variant

    v = choose_variant(announce=lambda s: None)
    if v.startswith("scalar"):
        pytest.skip("needs llvm_ad_rgb or cuda_ad_rgb (only scalar_rgb works here): install karellen-llvm-core "
                    "or libllvm >= 18")
    return v
