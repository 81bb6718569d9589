"""Choice of the Mitsuba variant: ``cuda_ad_rgb`` -> ``llvm_ad_rgb`` -> ``scalar_rgb``.

Each candidate is probed by rendering a tiny scene in a *subprocess*: Dr.Jit's LLVM
backend aborts the whole process (uncatchable) with a libLLVM older than 18, e.g.
Debian's libLLVM-15.  A pip-installed libLLVM (package ``karellen-llvm-core``, in
``<venv>/lib/libLLVM.so``) is used when present via ``DRJIT_LIBLLVM_PATH``, which must
be set before Dr.Jit is imported: importing this module does that.
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from edgetruth.errors import InputError

ORDER = ("cuda_ad_rgb", "llvm_ad_rgb", "scalar_rgb")
LLVM_HINT = ("for the ~4x faster llvm_ad_rgb: `pip install karellen-llvm-core` into this venv "
             "(or install Debian's libllvm19) and re-run")

_PROBE = r"""
import sys, mitsuba as mi
mi.set_variant(sys.argv[1])
scene = mi.load_dict({"type": "scene", "integrator": {"type": "direct"},
    "sensor": {"type": "perspective", "fov": 30, "film": {"type": "hdrfilm", "width": 8, "height": 8}},
    "e": {"type": "constant"}})
img = mi.render(scene, spp=2)
import numpy as np
v = float(np.asarray(img).mean())
assert np.isfinite(v) and v > 0, v
print("ok", v)
"""

_cache: dict[str, tuple[bool, str]] = {}


def pip_libllvm_path() -> Path | None:
    """``<venv>/lib/libLLVM.so`` from the ``karellen-llvm-core`` wheel, if installed."""
    p = Path(sys.prefix) / "lib" / "libLLVM.so"
    return p if p.exists() else None


def configure_llvm_env() -> None:
    """Point Dr.Jit at the pip libLLVM unless the user already chose one."""
    p = pip_libllvm_path()
    if p is not None and "DRJIT_LIBLLVM_PATH" not in os.environ:
        os.environ["DRJIT_LIBLLVM_PATH"] = str(p)


configure_llvm_env()


def probe_uncached(variant: str, env: dict | None = None, timeout_s: float = 120.0) -> tuple[bool, str]:
    """Render a tiny scene with ``variant`` in a subprocess: (works, one-line reason if not)."""
    try:
        r = subprocess.run([sys.executable, "-c", _PROBE, variant], capture_output=True, text=True,
                           timeout=timeout_s, env=env if env is not None else os.environ.copy())
    except subprocess.TimeoutExpired:
        return False, f"probe timed out after {timeout_s:.0f} s"
    if r.returncode == 0 and "ok" in r.stdout:
        return True, ""
    tail = r.stderr.strip().splitlines() or [f"exit code {r.returncode}"]
    return False, next((l for l in tail if "ERROR" in l or "Error" in l), tail[-1])[:160]


def probe(variant: str) -> tuple[bool, str]:
    """(works, reason) for ``variant``; cached per process."""
    if variant not in _cache:
        _cache[variant] = probe_uncached(variant)
    return _cache[variant]


def available(variant: str) -> bool:
    import mitsuba as mi
    return variant in mi.variants()


def choose_variant(requested: str | None = None, announce=print) -> str:
    """The variant to render with, set active in Mitsuba; prints one line saying which.

    ``requested`` (the ``--variant`` option) overrides the automatic choice.
    """
    import mitsuba as mi
    if requested:
        if requested not in mi.variants():
            raise InputError(f"--variant {requested}: not in this Mitsuba build (have: {', '.join(mi.variants())})")
        mi.set_variant(requested)
        announce(f"render: using Mitsuba variant {requested} (requested)")
        return requested
    skipped = []
    for v in ORDER:
        if not available(v):
            continue
        ok, reason = probe(v)
        if ok:
            mi.set_variant(v)
            msg = f"render: using Mitsuba variant {v}"
            if v == "scalar_rgb":
                why = "; ".join(f"{s}: {r}" for s, r in skipped if s.startswith("llvm"))
                msg += f" (slow fallback; {why}; {LLVM_HINT})"
            announce(msg)
            return v
        skipped.append((v, reason))
    raise InputError("no Mitsuba variant works here: " + "; ".join(f"{s}: {r}" for s, r in skipped))
