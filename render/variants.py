"""Choice of the Mitsuba variant: ``cuda_ad_rgb`` -> ``llvm_ad_rgb`` -> ``scalar_rgb``.

Each candidate is probed by rendering a tiny scene in a *subprocess*: Dr.Jit's LLVM
backend aborts the whole process (uncatchable) with a libLLVM older than 18, e.g.
Debian's libLLVM-15.  A pip-installed libLLVM (package ``karellen-llvm-core``, a dependency
of edgetruth on Linux x86_64, the one platform it has wheels for) is used when present via
``DRJIT_LIBLLVM_PATH``, which must be set before Dr.Jit is imported: importing this module
does that.  It is found in the running interpreter's prefix (``<sys.prefix>/lib/libLLVM.so``:
a venv, or wherever pip put the wheel's data files, e.g. ``--user``), else through the
installed package's own file list, with no help from the Makefile or the environment.  Where
only ``scalar_rgb`` works, one line on stderr says exactly what to install.
"""
from __future__ import annotations

import os
import platform
import subprocess
import sys
from pathlib import Path

from edgetruth.errors import InputError

ORDER = ("cuda_ad_rgb", "llvm_ad_rgb", "scalar_rgb")
PIP_LLVM = "karellen-llvm-core"  # a pip-packaged libLLVM 23 (wheels for manylinux_2_28 x86_64 only)

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
    """The libLLVM of the ``karellen-llvm-core`` wheel, if installed: ``<sys.prefix>/lib/libLLVM.so``
    (a venv or a plain prefix install), else the library among the package's recorded files
    (``--user``, ``--prefix`` or other schemes; the versioned file if the link was not made)."""
    p = Path(sys.prefix) / "lib" / "libLLVM.so"
    if p.exists():
        return p
    from importlib import metadata

    try:
        files = metadata.distribution(PIP_LLVM).files or []
    except metadata.PackageNotFoundError:
        return None
    found = [Path(f.locate()) for f in files if Path(str(f)).name.startswith("libLLVM.so")]
    found = sorted((q for q in found if q.exists()), key=lambda q: (q.name != "libLLVM.so", q.name))
    return found[0].resolve() if found else None


def llvm_hint() -> str:
    """One line: exactly what to install on this platform for the fast ``llvm_ad_rgb`` variant."""
    system, machine = platform.system(), platform.machine().lower()
    if system == "Linux" and machine in ("x86_64", "amd64"):
        have = pip_libllvm_path()
        if have is not None:
            return (f"{PIP_LLVM} is installed ({have}) but llvm_ad_rgb does not run with it: set "
                    "DRJIT_LIBLLVM_PATH to another libLLVM >= 18 (Debian/Ubuntu: apt install libllvm19)")
        return (f"for the ~4x faster llvm_ad_rgb install a libLLVM >= 18: {sys.executable} -m pip install "
                f"{PIP_LLVM} (or, with root, apt install libllvm19), then re-run")
    if system == "Linux":
        return ("for the ~4x faster llvm_ad_rgb install a libLLVM >= 18 (Debian/Ubuntu: apt install libllvm19; "
                "Fedora: dnf install llvm-libs) or set DRJIT_LIBLLVM_PATH to one, then re-run")
    if system == "Darwin":
        return ("for the ~4x faster llvm_ad_rgb: brew install llvm, then export "
                "DRJIT_LIBLLVM_PATH=$(brew --prefix llvm)/lib/libLLVM.dylib and re-run")
    return ("for the ~4x faster llvm_ad_rgb install LLVM >= 18 and set DRJIT_LIBLLVM_PATH to its "
            "LLVM-C library (Windows: LLVM-C.dll), then re-run")


def libllvm_state() -> str:
    """Which libLLVM Dr.Jit is pointed at, in a few words (for the fallback line)."""
    chosen = os.environ.get("DRJIT_LIBLLVM_PATH")
    if chosen:
        return f"DRJIT_LIBLLVM_PATH={chosen}"
    return f"{PIP_LLVM} not installed, system libLLVM"


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


_warned: set[str] = set()


def _warn(message: str) -> None:
    """The install hint on stderr, once per process (renders, benches and workers may choose again)."""
    from edgetruth import console

    if message not in _warned:
        _warned.add(message)
        console.warn(message)


def choose_variant(requested: str | None = None, announce=print, warn=_warn) -> str:
    """The variant to render with, set active in Mitsuba; ``announce`` gets one line saying which.

    ``requested`` (the ``--variant`` option) overrides the automatic choice.  When only the slow
    ``scalar_rgb`` works, ``warn`` (stderr, by default) gets one more line: what to install.
    """
    import mitsuba as mi
    if requested:
        if requested not in mi.variants():
            raise InputError(f"--variant {requested}: not in this Mitsuba build (have: {', '.join(mi.variants())})")
        # A JIT variant can be built in yet not run here (cuda_ad_* with no GPU or driver: set_variant raises;
        # llvm_ad_* with an old libLLVM: the process aborts), so it is probed like the automatic choice.
        ok, reason = (True, "") if requested.startswith("scalar_") else probe(requested)
        if not ok:
            raise InputError(f"--variant {requested}: does not run here ({reason}); leave --variant out to "
                             "render with the best variant that does")
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
                msg += f" (slow fallback; {why or 'no llvm variant in this Mitsuba build'}; {libllvm_state()})"
            announce(msg)
            if v == "scalar_rgb" and warn is not None:
                warn(f"render: {llvm_hint()}")
            return v
        skipped.append((v, reason))
    raise InputError("no Mitsuba variant works here: " + "; ".join(f"{s}: {r}" for s, r in skipped))
