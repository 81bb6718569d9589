"""Start-up: what ``edgetruth --version`` and ``import edgetruth.locate`` load (times are `make bench` lines,
not asserted here), the numba kernels compiled on first call, and where their cache goes."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
HEAVY = ("numba", "scipy", "mitsuba", "drjit", "matplotlib", "ray", "tqdm", "OpenEXR")


def _loaded(code: str, tmp_path) -> dict:
    """The modules a fresh interpreter has loaded after ``code`` (run from a folder outside the checkout)."""
    probe = code + "\nimport json, sys\nprint(json.dumps(sorted(sys.modules)))"
    r = subprocess.run([sys.executable, "-c", probe], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    return set(json.loads(r.stdout.strip().splitlines()[-1]))


def test_version_builds_no_parser_and_imports_nothing_heavy(tmp_path):
    mods = _loaded("from edgetruth.cli import main\ntry:\n    main(['--version'])\nexcept SystemExit:\n    pass",
                   tmp_path)
    assert "numpy" not in mods and not any(m.startswith("edgetruth.cli.commands") for m in mods)


@pytest.mark.parametrize("argv", [["--version"], ["-q", "--version"], ["--quiet", "--version"]])
def test_version_answers_like_argparse(argv, capsys):
    from edgetruth import __version__
    from edgetruth.cli import main

    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 0 and capsys.readouterr().out.strip() == f"edgetruth {__version__}"


def test_import_locate_loads_neither_numba_nor_the_renderer(tmp_path):
    mods = _loaded("import edgetruth.locate", tmp_path)
    assert not [h for h in HEAVY if h in mods]


def test_methods_listing_needs_no_numba(tmp_path):
    mods = _loaded("from edgetruth import locate\nassert len(locate.METHODS) >= 20", tmp_path)
    assert "numba" not in mods


def test_first_call_compiles_and_puts_the_dispatcher_in_place():
    from edgetruth import locate
    from edgetruth.locate import erf_kernels as K
    from edgetruth import jit

    img = np.full((32, 32), 50.0)
    img[:, 16:] = 150.0
    pts = locate.locate(img, "dynamic_erf_4p")
    assert len(pts) and pts.converged.all()
    import numba
    from numba.core.registry import CPUDispatcher

    assert isinstance(K.fit_one, CPUDispatcher)  # what compiled code calls: numba's own dispatcher now
    assert not isinstance(K.fit_one, jit.LazyKernel) and jit.prange is not numba.prange
    assert K.prange is numba.prange
    # a strict parallel kernel stays the placeholder: its Python callers choose its parallel dispatcher or
    # its serial copy per call (edgetruth.jit; tests/locate/test_serial_kernels.py)
    assert isinstance(K.refine_erf, jit.LazyKernel) and isinstance(K.refine_erf.dispatcher, CPUDispatcher)
    assert isinstance(K.refine_erf.serial, CPUDispatcher)


def test_a_lazy_kernel_behaves_like_numba_njit():
    from edgetruth import jit

    @jit.njit(cache=False)
    def inner(x):
        return 2.0 * x

    assert isinstance(inner, jit.LazyKernel) and "compiled on first call" in repr(inner)
    # a kernel's module globals are what numba resolves: a module of its own here
    g = {"inner": inner, "prange": jit.prange}
    exec("def run(a, out):\n    for i in prange(a.shape[0]):\n        out[i] = inner(a[i])\n", g)
    k = jit.njit(cache=False, parallel=True)(g["run"])
    a = np.arange(5.0)
    out = np.zeros(5)
    k(a, out)
    assert np.array_equal(out, 2 * a) and len(k.signatures) == 1
    assert g["inner"] is inner.dispatcher and g["prange"] is not jit.prange  # numba's own, in place
    assert inner(3.0) == 6.0


def test_cache_folder_rules(monkeypatch, tmp_path):
    from edgetruth import jit

    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    monkeypatch.setattr(jit, "_writable", lambda p: True)
    assert jit.cache_folder() is None  # numba's own choice: the package's __pycache__
    home = str(tmp_path / "home")
    monkeypatch.setattr(jit, "_writable", lambda p: str(p).startswith(home))
    monkeypatch.setenv("HOME", home)
    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    assert jit.cache_folder() is None  # numba's per-user folder, ~/.cache/numba
    monkeypatch.setattr(jit, "_writable", lambda p: str(p).startswith(str(tmp_path / "tmp")))
    monkeypatch.setattr(jit.tempfile, "gettempdir", lambda: str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    mine = jit.cache_folder()
    assert mine.parent == tmp_path / "tmp" and mine.stat().st_mode & 0o777 == 0o700  # a private one under TMPDIR
    mine.chmod(0o777)  # anyone could plant pickles there: not used
    with pytest.raises(OSError, match="no writable folder"):
        jit.cache_folder()
    monkeypatch.setattr(jit, "_writable", lambda p: False)
    with pytest.raises(OSError, match="no writable folder"):
        jit.cache_folder()
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "mine"))
    assert jit.cache_folder() is None  # the user's choice wins


def test_unwritable_everything_compiles_in_memory_with_one_line(tmp_path):
    """No writable cache folder anywhere: the kernels still run (cache off), and stderr says so once."""
    code = ("from edgetruth import jit\n"
            "jit._writable = lambda p: False\n"
            "import numpy as np\nfrom edgetruth import locate\n"
            "img = np.full((32, 32), 50.0); img[:, 16:] = 150.0\n"
            "print(len(locate.locate(img, 'glm1984')))\n")
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env["TMPDIR"] = str(tmp_path)
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=600,
                       env=env)
    assert r.returncode == 0, r.stderr
    assert int(r.stdout.strip()) > 0
    lines = [line for line in r.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "NUMBA_CACHE_DIR" in lines[0], r.stderr


_LOCK_CHILD = r'''
import os, sys, time
sys.path.insert(0, sys.argv[1])
import lockkern  # a module of kernels declared with edgetruth.jit.njit(cache=True)
import numpy as np
while not os.path.exists(sys.argv[2]):  # start together
    time.sleep(0.01)
print(lockkern.total(np.arange(5.0)),
      sum(lockkern.total.stats.cache_misses.values()), sum(lockkern.total.stats.cache_hits.values()))
'''


def test_processes_that_need_one_kernel_at_once_compile_it_once(tmp_path):
    """Two processes calling a kernel together (a pool's workers starting): one compiles it under the kernel's
    file lock and writes numba's cache, the other waits and loads it from the cache (edgetruth.jit)."""
    import os
    import subprocess
    import sys
    import time

    (tmp_path / "lockkern.py").write_text(
        "from edgetruth.jit import njit\n\n\n@njit(cache=True)\ndef total(a):\n    s = 0.0\n"
        "    for i in range(a.size):\n        s += a[i] * a[i] - a[i] / (1.0 + a[i])\n    return s\n")
    go = tmp_path / "go"
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache"), "TMPDIR": str(tmp_path / "tmp")}
    (tmp_path / "tmp").mkdir()
    procs = [subprocess.Popen([sys.executable, "-c", _LOCK_CHILD, str(tmp_path), str(go)], env=env,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for _ in range(2)]
    time.sleep(3.0)  # both have imported numba's placeholders and wait
    go.write_text("")
    outs = [p.communicate(timeout=120) for p in procs]
    assert all(p.returncode == 0 for p in procs), outs
    rows = [tuple(float(v) for v in o[0].split()) for o in outs]
    assert all(r[0] == rows[0][0] for r in rows)
    misses, hits = sum(r[1] for r in rows), sum(r[2] for r in rows)
    assert (misses, hits) == (1, 1), rows  # one compiled, the other loaded what it wrote
    assert list((tmp_path / "tmp").glob("edgetruth-jit-locks-*/lockkern.total.lock"))
