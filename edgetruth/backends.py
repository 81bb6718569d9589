"""Where work runs: a map of a pure task function over argument tuples, in-process, on a
local process pool, or on a Ray cluster.

    from edgetruth.backends import make_backend
    with make_backend("local", workers=4) as be:
        for result in be.map_unordered(fn, [(spec, 0), (spec, 1), ...]):
            ...   # results arrive as tasks finish (any order)

``fn`` must be a module-level function (it is pickled by reference) and a pure
function of its arguments; it may keep per-process caches (e.g. loaded Mitsuba
scenes), because each worker process lives for the whole map.  Results are
consumed by the *driver* (the calling process), which is therefore the only
place that should write shared state such as a manifest.

``args_list`` may be any iterable, even a lazy one of a million tuples: it is consumed
as tasks finish, with at most ``window`` tasks in flight (default
``WINDOW_PER_WORKER`` x the workers), so the driver's memory does not grow with the
number of tasks.  Large data every task needs (a spec) goes to each worker *once*,
through the initializer (``initializer(*initargs)`` runs once per worker process),
not with every task.

Backends:

- ``local`` with ``workers=1``: runs in the calling process (no pool, no pickling).
- ``local`` with ``workers>1``: a ``spawn`` process pool (never ``fork``: Dr.Jit and
  CUDA are not fork-safe).  Workers die with the driver (Linux ``PR_SET_PDEATHSIG``),
  so a ``kill -9`` of the driver leaves no orphan writing files.
- ``ray``: an existing cluster (``address``, or ``RAY_ADDRESS``) or a local Ray
  instance.  Each task asks for ``num_cpus`` CPUs and, when the cluster has GPUs and
  ``gpu=True``, one GPU.
"""
from __future__ import annotations

import itertools
import os
import pickle
import signal
import socket
import sys
import time
import uuid
from typing import Any, Callable, Iterable, Iterator

import numpy as np

from edgetruth.errors import InputError


BACKENDS = ("local", "ray")
#: Tasks in flight per worker: enough that no worker waits for the driver, few enough that
#: the driver holds almost nothing.
WINDOW_PER_WORKER = 4
RAY_INSTALL_HINT = "Ray is not installed; install it with: pip install 'edgetruth[cluster]'"


def default_workers() -> int:
    """The cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def _die_with_parent() -> None:
    """Linux: deliver SIGKILL to this process when its parent dies."""
    if sys.platform.startswith("linux"):
        try:
            import ctypes  # lazy: optional

            libc = ctypes.CDLL("libc.so.6", use_errno=True)
            PR_SET_PDEATHSIG = 1
            libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
        except Exception:  # pragma: no cover - best effort
            pass


def worker_threads(workers: int) -> int:
    """The numba threads of each of ``workers`` pool processes: this machine's cores shared among them
    (each process would otherwise start one thread per core, and ``workers`` x cores threads on the
    cores make the numba kernels slower than one process: measured 2 workers x 2 threads 33.0 s against
    2 x 1 15.5 s for the quick run's ranging on 2 cores)."""
    return max(1, default_workers() // max(1, int(workers)))


class numba_threads:
    """``with numba_threads(n):`` numba runs on at most ``n`` threads in this process inside the block
    (``numba.set_num_threads``), and on as many as before after it."""

    def __init__(self, threads: int):
        self.threads = max(1, int(threads))
        self._before = None

    def __enter__(self):
        import numba  # lazy: numba is heavy (edgetruth.jit compiles on first call)

        self._before = numba.get_num_threads()
        numba.set_num_threads(min(self.threads, numba.config.NUMBA_NUM_THREADS))
        return self

    def __exit__(self, *exc) -> None:
        import numba  # lazy: numba is heavy (edgetruth.jit compiles on first call)

        numba.set_num_threads(self._before)


def _limit_numba_threads(threads: int) -> None:
    """At most ``threads`` numba threads in this process (before numba is imported: its environment
    variable; after: ``numba.set_num_threads``); a smaller ``NUMBA_NUM_THREADS`` of the user's stays."""
    env = os.environ.get("NUMBA_NUM_THREADS", "")
    if env.isdigit() and 0 < int(env) <= threads:
        return
    if "numba" in sys.modules:
        import numba  # lazy: numba is heavy (edgetruth.jit compiles on first call)

        numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
    else:
        os.environ["NUMBA_NUM_THREADS"] = str(threads)


def _worker_init(parent_pid, initializer, initargs, threads: int = 0) -> None:
    _die_with_parent()
    if threads:
        _limit_numba_threads(threads)
    if os.getppid() != parent_pid:  # the driver died while this worker was starting: nobody to serve
        os._exit(1)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the driver's to handle
    if initializer is not None:
        initializer(*initargs)


class Backend:
    """A context manager with ``map_unordered(fn, args_list) -> iterator of results``."""

    name = "base"
    concurrency = 1
    #: Whether tasks run in processes that see this machine's file system.
    shares_filesystem = True
    #: Whether tasks run in the calling process (its global state, e.g. thread pools, is theirs).
    in_process = False

    _initializer: Callable | None = None
    _initargs: tuple = ()

    def __enter__(self) -> "Backend":
        return self

    def __exit__(self, exc_type, *exc) -> None:
        self.close(abort=exc_type is not None)

    def set_initializer(self, initializer: Callable | None, initargs: tuple = ()) -> None:
        """``initializer(*initargs)`` runs once in every worker process before its first task
        (set it before the first ``map_unordered``)."""
        self._initializer, self._initargs = initializer, tuple(initargs)

    def close(self, abort: bool = False) -> None:
        """Release the workers; ``abort`` stops running tasks instead of waiting for them."""

    def window(self) -> int:
        """How many tasks ``map_unordered`` keeps in flight by default."""
        return max(2, WINDOW_PER_WORKER * self.concurrency)

    def map_unordered(self, fn: Callable, args_list: Iterable[tuple], window: int | None = None) -> Iterator[Any]:
        raise NotImplementedError


class SerialBackend(Backend):
    name = "local"
    in_process = True

    def __init__(self, initializer=None, initargs=()):
        self.set_initializer(initializer, initargs)
        self._ran_init = False

    def map_unordered(self, fn, args_list, window=None):
        if self._initializer is not None and not self._ran_init:
            self._initializer(*self._initargs)
            self._ran_init = True
        for args in args_list:
            yield fn(*args)


class PoolBackend(Backend):
    name = "local"

    def __init__(self, workers: int, initializer=None, initargs=(), threads: int | None = None):
        self.concurrency = workers
        self.set_initializer(initializer, initargs)
        self._pool = None
        self.threads = threads  # numba threads per worker; None: ``worker_threads(workers)``

    def map_unordered(self, fn, args_list, window=None):
        import multiprocessing as mp  # lazy: multiprocessing only for pools
        from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait  # lazy: only for pools

        if self._pool is None:  # created on first use, with the initializer set by then
            self._pool = ProcessPoolExecutor(max_workers=self.concurrency, mp_context=mp.get_context("spawn"),
                                             initializer=_worker_init,
                                             initargs=(os.getpid(), self._initializer, self._initargs,
                                                       self.threads or worker_threads(self.concurrency)))
        todo = iter(args_list)
        pending = {self._pool.submit(fn, *args) for args in itertools.islice(todo, window or self.window())}
        try:
            while pending:
                done, pending = wait(pending, return_when=FIRST_COMPLETED)
                for fut in done:
                    for args in itertools.islice(todo, 1):  # one in, one out: the workers stay busy
                        pending.add(self._pool.submit(fn, *args))
                    yield fut.result()
        finally:
            for fut in pending:
                fut.cancel()

    def close(self, abort: bool = False) -> None:
        if self._pool is None:
            return
        if abort:
            # CPython <= 3.11 marks every work item of a broken pool failed, cancelled ones too, which raises
            # InvalidStateError in its management thread (a traceback after our one-line error). The items stay
            # (that thread still looks them up by id); their futures become stand-ins that take the failure quietly
            items = getattr(self._pool, "_pending_work_items", None)
            for item in list((items or {}).values()):
                if item.future.cancelled():
                    item.future = _CancelledWork()
            for proc in list((getattr(self._pool, "_processes", None) or {}).values()):
                proc.kill()
        self._pool.shutdown(wait=not abort, cancel_futures=True)
        self._pool = None


def _CancelledWork():
    """A cancelled work item's future for a pool being aborted: cancelled, and deaf to the failure the broken
    pool's thread then sets on every item it still holds (concurrent.futures loads only here)."""
    from concurrent.futures import Future  # lazy: only for pools

    class CancelledWork(Future):
        def set_exception(self, exception) -> None:
            pass

    f = CancelledWork()
    f.cancel()
    return f


def import_ray():
    """``ray``, or an InputError saying how to install it."""
    try:
        import ray  # noqa: F401; lazy: Ray is heavy and optional
    except ImportError:
        raise InputError(RAY_INSTALL_HINT) from None
    return ray


class RayBackend(Backend):
    name = "ray"

    def __init__(self, address: str | None = None, num_cpus_per_task: float = 1, gpu: bool = True,
                 initializer=None, initargs=(), local_cpus: int | None = None):
        ray = import_ray()
        self._ray = ray
        self._owns = False
        if not ray.is_initialized():
            kw: dict = {"include_dashboard": False, "log_to_driver": True}
            try:
                if address:
                    ray.init(address=address, **kw)
                elif os.environ.get("RAY_ADDRESS"):
                    ray.init(**kw)
                else:
                    ray.init(num_cpus=local_cpus or default_workers(), **kw)
            except (ConnectionError, ValueError, RuntimeError) as exc:
                raise InputError(f"--address {address or os.environ.get('RAY_ADDRESS')}: cannot connect to a "
                                 f"Ray cluster ({str(exc).splitlines()[0][:160]}); check the address "
                                 "(ray://HOST:10001 or HOST:6379) or leave it out for a local Ray instance") from None
            self._owns = True
        res = ray.cluster_resources()
        self.n_gpus = float(res.get("GPU", 0) or 0)
        self.n_cpus = float(res.get("CPU", 1) or 1)
        self.num_gpus = 1 if (gpu and self.n_gpus) else 0
        self.num_cpus = num_cpus_per_task
        self.concurrency = int(self.n_gpus) if self.num_gpus else max(1, int(self.n_cpus // max(num_cpus_per_task, 1e-9)))
        self._initializer, self._initargs = initializer, initargs
        # only a Ray instance this process started has no other node, now or later (an existing
        # cluster may have or gain nodes that do not see this machine's files)
        self.shares_filesystem = self._owns and not address and not os.environ.get("RAY_ADDRESS")
        #: finished tasks per Ray node id
        self.tasks_per_node: dict[str, int] = {}

    def map_unordered(self, fn, args_list, window=None):
        ray = self._ray
        # a task that dies with its node (or worker) runs again elsewhere
        remote = ray.remote(num_cpus=self.num_cpus, num_gpus=self.num_gpus, max_retries=3)(_ray_call)
        # the initializer and its arguments (a spec) go to the object store once, pickled into a
        # uint8 array: every task names it, each node receives it once, a task reads it without a
        # copy, and each worker process unpickles it once (the token says whether it has)
        token = blob = None
        if self._initializer is not None:
            import cloudpickle  # lazy: only to ship plug-ins (as Ray would: an initializer from __main__ travels too)

            token = uuid.uuid4().hex
            blob = ray.put(np.frombuffer(cloudpickle.dumps((self._initializer, self._initargs)), np.uint8))
        todo = iter(args_list)
        refs = [remote.remote(fn, token, blob, args) for args in itertools.islice(todo, window or self.window())]
        checked = time.monotonic()
        try:
            while refs:
                done, refs = ray.wait(refs, num_returns=1)
                if window is None and time.monotonic() - checked > 5.0:  # nodes join or leave
                    self._refresh_concurrency()
                    checked = time.monotonic()
                want = (window or self.window()) - len(refs)
                refs += [remote.remote(fn, token, blob, args) for args in itertools.islice(todo, max(0, want))]
                node, result = ray.get(done[0])
                self.tasks_per_node[node] = self.tasks_per_node.get(node, 0) + 1
                yield result
        finally:
            for r in refs:
                ray.cancel(r, force=True)

    def _refresh_concurrency(self) -> None:
        res = self._ray.cluster_resources()  # the live nodes'
        n = float(res.get("GPU", 0) or 0) if self.num_gpus else float(res.get("CPU", 1) or 1) / max(self.num_cpus, 1e-9)
        self.concurrency = max(1, int(n))

    def close(self, abort: bool = False) -> None:
        if self._owns and self._ray.is_initialized():
            self._ray.shutdown()
        self._owns = False


_initialised: set = set()


def _ray_call(fn, token, blob, args):
    """In a Ray worker: run the map's initializer once per process (``blob``: the pickled
    (initializer, initargs), read-only from the object store), then ``fn(*args)``; returns
    (this node's id, the result)."""
    import ray  # lazy: Ray is heavy and optional

    if token is not None and token not in _initialised:
        initializer, initargs = pickle.loads(memoryview(blob))
        initializer(*initargs)
        _initialised.add(token)
    return ray.get_runtime_context().get_node_id(), fn(*args)


def check_backend_args(backend: str = "local", workers: int | None = None, address: str | None = None) -> None:
    """Validate backend options (and that Ray is importable) without starting anything."""
    if backend not in BACKENDS:
        raise InputError(f"--backend {backend!r}: choose one of {', '.join(BACKENDS)}")
    if workers is not None and (not isinstance(workers, int) or workers < 1):
        raise InputError(f"--workers {workers}: must be a positive integer (default: {default_workers()} cores)")
    if address and backend != "ray":
        raise InputError("--address applies to --backend ray only; add --backend ray or drop --address")
    if backend == "ray":
        import_ray()
        if address:
            check_reachable(address)


def check_reachable(address: str, timeout_s: float = 3.0) -> None:
    """A TCP connect to a ``HOST:PORT`` or ``ray://HOST:PORT`` address (Ray itself retries for
    minutes before giving up on a wrong address); ``auto``/``local`` are left to Ray."""
    if address in ("auto", "local"):
        return
    hostport = address.split("://", 1)[-1].rstrip("/")
    host, sep, port = hostport.rpartition(":")
    if not sep or not port.isdigit() or not host:
        raise InputError(f"--address {address!r}: expected HOST:PORT (GCS, e.g. head:6379), "
                         "ray://HOST:PORT (Ray client, e.g. ray://head:10001) or auto")
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=timeout_s):
            pass
    except OSError as exc:
        raise InputError(f"--address {address}: nothing answers there ({exc.strerror or exc}); start the cluster "
                         "(`ray start --head`) or fix the address; leave --address out for a local Ray instance") from None


def make_backend(backend: str = "local", workers: int | None = None, address: str | None = None,
                 gpu: bool = True, initializer: Callable | None = None, initargs: tuple = ()) -> Backend:
    """A backend by name.  ``workers``: local pool size (default: the cores; 1 = in-process) or,
    for Ray without ``address``, the CPUs of the local Ray instance.  ``initializer(*initargs)``
    runs once in every worker process before its first task."""
    check_backend_args(backend, workers, address)
    if backend == "ray":
        return RayBackend(address=address, gpu=gpu, initializer=initializer, initargs=initargs, local_cpus=workers)
    n = default_workers() if workers is None else int(workers)
    if n == 1:
        return SerialBackend(initializer, initargs)
    return PoolBackend(n, initializer, initargs)
