"""``edgetruth.backends`` and ``edgetruth render --backend/--workers``: same dataset everywhere."""
from __future__ import annotations

import itertools
import sys
import time
from pathlib import Path

import pytest

from edgetruth.backends import WINDOW_PER_WORKER, check_backend_args, default_workers, make_backend
from edgetruth.cli import main
from edgetruth.errors import InputError
from edgetruth.render.testing import write_tiny_spec


def _files(d: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(d.iterdir())}


def test_serial_and_pool_map_every_task_once():
    args = [(2, i) for i in range(7)]
    with make_backend("local", workers=1) as be:
        assert sorted(be.map_unordered(pow, args)) == [2 ** i for i in range(7)]
    with make_backend("local", workers=2) as be:
        assert be.concurrency == 2
        assert sorted(be.map_unordered(pow, args)) == [2 ** i for i in range(7)]


@pytest.mark.parametrize("workers", [1, 2])
def test_tasks_are_consumed_lazily_with_a_bounded_window(workers):
    """A million tasks cost nothing up front: at most ``window`` are in flight beyond the results taken."""
    consumed = []

    def tasks():
        for i in itertools.count():
            consumed.append(i)
            yield (2, i)

    with make_backend("local", workers=workers) as be:
        it = be.map_unordered(pow, tasks(), window=3)
        got = [next(it) for _ in range(10)]
        it.close()
        assert be.window() == max(2, WINDOW_PER_WORKER * be.concurrency)
    assert set(got) <= {2 ** i for i in consumed} and len(set(got)) == 10
    assert len(consumed) <= 10 + 3  # taken + window


def test_pool_task_error_reaches_the_driver():
    with make_backend("local", workers=2) as be:
        with pytest.raises(ZeroDivisionError):
            list(be.map_unordered(divmod, [(1, 1), (1, 0)]))


def test_an_aborted_pool_leaves_no_thread_traceback(monkeypatch):
    """A task's error aborts the pool (its queued tasks cancelled, its workers killed): the error reaches the driver
    and nothing else does -- CPython 3.11's pool thread used to raise InvalidStateError on the cancelled ones,
    printed as a traceback after the one-line error (`edgetruth render -j 2` on a pose no draw could meet)."""
    import threading

    seen = []
    monkeypatch.setattr(threading, "excepthook", lambda a: seen.append(a.exc_type))
    for _ in range(3):
        with pytest.raises(ZeroDivisionError):
            with make_backend("local", workers=2) as be:
                list(be.map_unordered(_slow_divmod, [(1, 1), (1, 0)] + [(1, 1)] * 20, window=12))
        time.sleep(0.5)  # the pool's own thread notices the killed workers
    assert seen == []


def _slow_divmod(a, b):
    time.sleep(0.2)
    return divmod(a, b)


@pytest.mark.parametrize("kw, match", [
    ({"backend": "dask"}, "--backend"),
    ({"workers": 0}, "--workers"),
    ({"workers": -2}, "--workers"),
    ({"address": "head:6379"}, "--address applies to --backend ray"),
])
def test_bad_backend_arguments(kw, match):
    with pytest.raises(InputError, match=match):
        check_backend_args(**kw)


def test_default_workers_is_the_core_count():
    assert default_workers() >= 1


def test_backend_ray_without_ray_says_how_to_install(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray -> ImportError
    spec = write_tiny_spec(tmp_path)
    out = tmp_path / "out"
    assert main(["render", str(spec), "-o", str(out), "--backend", "ray"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "pip install 'edgetruth[cluster]'" in err
    assert not out.exists()


def test_local_pool_and_in_process_give_identical_datasets(tmp_path):
    from edgetruth.render.dataset.driver import render_spec

    spec = write_tiny_spec(tmp_path, spp=4)
    render_spec(spec, tmp_path / "serial", progress=False, announce=lambda s: None, workers=1)
    render_spec(spec, tmp_path / "pool", progress=False, announce=lambda s: None, workers=2)
    assert _files(tmp_path / "serial") == _files(tmp_path / "pool")


def test_one_render_pool_serves_several_specs_with_the_same_bytes(tmp_path):
    """The main job's shared pool: its workers render two specs in turn (started once) and write what an
    in-process render writes; a spec the pool was not made for is an input error, before any rendering."""
    from edgetruth.render.dataset.driver import RenderPool, render_spec
    from edgetruth.render.dataset.spec import load_spec

    for d in "abc":
        (tmp_path / d).mkdir()
    a = load_spec(write_tiny_spec(tmp_path / "a", spp=4))
    b = load_spec(write_tiny_spec(tmp_path / "b", spp=16))
    assert a.identity_sha256 != b.identity_sha256
    with RenderPool([a, b], 2) as pool:
        for sp, name in ((a, "a"), (b, "b")):
            render_spec(sp, tmp_path / f"pool_{name}", progress=False, announce=lambda s: None, workers=2, pool=pool)
        first = pool.backend
        with pytest.raises(InputError, match="made without spec"):
            render_spec(load_spec(write_tiny_spec(tmp_path / "c", spp=64)), tmp_path / "pool_c", progress=False,
                        announce=lambda s: None, workers=2, pool=pool)
        assert pool.backend is first  # the same workers throughout
    for sp, name in ((a, "a"), (b, "b")):
        render_spec(sp, tmp_path / f"serial_{name}", progress=False, announce=lambda s: None, workers=1)
        assert _files(tmp_path / f"serial_{name}") == _files(tmp_path / f"pool_{name}")


def test_ray_and_local_backends_give_identical_manifests(tmp_path):
    ray = pytest.importorskip("ray", reason="ray is not installed: pip install 'edgetruth[cluster]'")
    from edgetruth.render.dataset.driver import render_spec

    spec = write_tiny_spec(tmp_path, spp=4)
    t0 = time.perf_counter()
    render_spec(spec, tmp_path / "local", progress=False, announce=lambda s: None, workers=2)
    t_local = time.perf_counter() - t0
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        t0 = time.perf_counter()
        timings: dict = {}
        render_spec(spec, tmp_path / "ray", progress=False, announce=lambda s: None, backend="ray",
                    timings=timings)
        t_ray = time.perf_counter() - t0
        assert timings["n_rendered"] == 3
    finally:
        ray.shutdown()
    a, b = _files(tmp_path / "local"), _files(tmp_path / "ray")
    assert a["manifest.json"] == b["manifest.json"]
    assert a == b  # and every file
    print(f"tiny spec: local pool (2 workers) {t_local:.1f} s, ray (2 CPUs, running instance) {t_ray:.1f} s")


def _numba_threads_in_worker(_):
    import os

    import numba

    return numba.get_num_threads(), os.environ.get("NUMBA_NUM_THREADS")


def test_pool_workers_share_the_cores_among_their_numba_threads():
    """Each of a local pool's workers gets cores // workers numba threads (not one per core each: on 2 cores
    two workers of 2 threads ran the quick ranging 2x slower than two of 1)."""
    from edgetruth.backends import make_backend, worker_threads

    assert worker_threads(1) >= worker_threads(2) >= 1 and worker_threads(10 ** 6) == 1
    with make_backend("local", 2) as be:
        got = list(be.map_unordered(_numba_threads_in_worker, [(i,) for i in range(4)]))
    assert {g[0] for g in got} == {worker_threads(2)}
