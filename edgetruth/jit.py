"""Numba kernels that are compiled when first called: importing ``edgetruth.locate`` (or
``edgetruth.render``) does not import numba.

Every kernel of ``edgetruth.locate`` and ``edgetruth.render.scene.edge_coverage`` is declared with ``@njit(...)`` from this module (the options
are ``numba.njit``'s) and loops with ``prange`` from this module.  Until a kernel is first called
(or an attribute of it is read), nothing is imported or compiled: the name holds a placeholder.
Its first call imports numba, turns that kernel and every kernel it reaches (through the names of
its module and of the modules it names) into their ``numba.njit`` dispatchers, puts the
dispatchers into those modules in place of the placeholders, and calls it: numba then compiles or
loads from its on-disk cache exactly as for ``@numba.njit``.  Only the moment differs, never the
code numba compiles, so no number a method returns changes.

``variant(kernel, name, **options)``: a second kernel of the same code, compiled with other options
(e.g. fastmath).

One-thread processes: a ``parallel=True`` kernel whose code reaches no ``fastmath`` kernel (strict IEEE
arithmetic, each iteration on its own) gives the same bits compiled without ``parallel``, and numba's
parfor lowering is ~1/3 of a cold start's compile time (measured: 55.8 s -> 38.5 s for every kernel of
the main job, 47.0 s with the two kernels that reach fastmath left parallel).  So, called from Python in
a process that runs numba on one thread (``numba.get_num_threads() == 1``: a pool worker sharing the
cores), such a kernel runs a serial copy, ``<name>__serial`` with its own cache files; on more threads,
the parallel kernel.  A kernel reaching fastmath code is always parallel (reassociated sums may differ
between the two compiles, and a point must not depend on the thread count).

``before_compile(fn)``: ``fn()`` runs (once) before the first kernel of ``fn``'s module becomes a
dispatcher -- for a table the kernels read as a global (numba freezes it into the compiled code).

The on-disk cache (``cache=True``): numba writes it into the package's ``__pycache__``, or, where
that is not writable (a read-only site-packages), into its per-user folder (``~/.cache/numba``) --
numba's own rule; ``NUMBA_CACHE_DIR`` overrides both.  Where none of these is writable (no
writable home either), ``cache_folder()`` chooses ``$TMPDIR/edgetruth-numba-<uid>``, and where
even that fails the kernels compile in memory each run, and one line on stderr says so.
"""
from __future__ import annotations

import os
import stat
import sys
import tempfile
import threading
import types
from pathlib import Path


_LOCK = threading.RLock()
_numba = None  # the numba module, once a kernel has been called
_HOOKS: dict[str, list] = {}  # module name -> callbacks to run before its first kernel compiles
_HOOKS_RUN: set[str] = set()
_CACHE = {"checked": False, "off": False}  # "off": no writable cache folder anywhere


class _Prange:
    """``numba.prange`` until numba is imported (a called kernel's module then holds numba's own)."""

    def __call__(self, *args):
        return range(*args)

    def __repr__(self) -> str:
        return "<edgetruth.jit.prange: numba.prange once a kernel is called>"


prange = _Prange()


class LazyKernel:
    """A kernel declared with ``njit``: a placeholder until it is first called."""

    def __init__(self, py_func, options: dict):
        self.py_func = py_func
        self.options = dict(options)
        self.dispatcher = None
        self.__name__ = py_func.__name__
        self.__qualname__ = py_func.__qualname__
        self.__module__ = py_func.__module__
        self.__doc__ = py_func.__doc__
        self.__wrapped__ = py_func
        self.serial = None  # the serial copy's dispatcher (see the module's docstring), once materialised

    def __call__(self, *args, **kwargs):
        d = self.dispatcher
        if d is None:
            d = materialise(self)
        if self.serial is not None and _numba.get_num_threads() == 1:
            return self.serial(*args, **kwargs)
        return d(*args, **kwargs)

    def __getattr__(self, name):  # the dispatcher's own attributes (signatures, ...): compile first
        if name.startswith("__"):
            raise AttributeError(name)
        return getattr(materialise(self), name)

    def __repr__(self) -> str:
        state = "compiled on first call" if self.dispatcher is None else "a numba dispatcher"
        return f"<kernel {self.__module__}.{self.__qualname__}: {state}>"


def njit(*args, **options):
    """``numba.njit`` with the same options, applied when the kernel is first called."""
    if args and callable(args[0]) and len(args) == 1 and not options:
        return _declare(args[0], {})
    if args:
        raise TypeError("njit: pass the options by keyword (as numba.njit(cache=True, ...))")
    return lambda fn: _declare(fn, options)


def _declare(fn, options: dict) -> LazyKernel:
    # a placeholder even when numba is already in use: what the kernel calls may still be placeholders
    return LazyKernel(fn, options)


def variant(kernel: LazyKernel, name: str, **options) -> LazyKernel:
    """A second kernel, ``name``, of ``kernel``'s code compiled with other options (e.g. ``fastmath``): its
    own dispatcher and cache files, no wrapper for numba to inline (copying and typing an inlined function
    again at every call site makes numba slow to compile)."""
    f = kernel.py_func
    g = types.FunctionType(f.__code__, f.__globals__, name, f.__defaults__, f.__closure__)
    g.__qualname__ = name
    g.__module__ = f.__module__
    g.__doc__ = f.__doc__
    return _declare(g, {**kernel.options, **options})


def before_compile(fn):
    """Run ``fn()`` once before the first kernel of ``fn``'s module is compiled (decorator)."""
    _HOOKS.setdefault(str(fn.__module__), []).append(fn)
    return fn


def _code_names(code: types.CodeType) -> set[str]:
    names = set(code.co_names)
    for c in code.co_consts:
        if isinstance(c, types.CodeType):
            names |= _code_names(c)
    return names


def _reach(kernel: LazyKernel, seen: dict) -> None:
    """Every placeholder ``kernel`` can call: the names in its code, looked up in its module (a module
    named there contributes its placeholders whose names the code holds: ``K.fit`` names "K" and "fit")."""
    if id(kernel) in seen:
        return
    seen[id(kernel)] = kernel
    for v in _named(kernel.py_func):
        if isinstance(v, LazyKernel):
            _reach(v, seen)


def _named(fn):
    """The objects ``fn``'s code can call by name: its module's globals of those names and, for a module
    among them, that module's attributes of those names (``K.fit(...)`` names both "K" and "fit")."""
    g = fn.__globals__
    names = _code_names(fn.__code__)
    for name in names:
        v = g.get(name)
        if isinstance(v, types.ModuleType):
            yield from (vars(v).get(n) for n in names)
        else:
            yield v


def _swap_globals(g: dict, made: dict) -> None:
    """Put the dispatchers (``made``: id of a placeholder -> its dispatcher) and numba's prange into ``g``;
    a kernel with a serial copy stays a placeholder (its Python callers choose per call)."""
    for name, v in list(g.items()):
        if isinstance(v, LazyKernel):
            if v.serial is not None:
                continue
            d = made.get(id(v)) or v.dispatcher
            if d is not None:
                g[name] = d
        elif v is prange:
            g[name] = _numba.prange


def materialise(kernel: LazyKernel):
    """``kernel``'s dispatcher, after making dispatchers of everything it reaches (imports numba once)."""
    global _numba
    with _LOCK:
        if kernel.dispatcher is not None:
            return kernel.dispatcher
        if _numba is None:
            _configure_cache()
            import numba  # lazy: numba is heavy (edgetruth.jit compiles on first call)

            _numba = numba
        seen: dict = {}
        _reach(kernel, seen)
        todo = [k for k in seen.values() if k.dispatcher is None]
        for mod in sorted({str(k.__module__) for k in todo}):
            if mod not in _HOOKS_RUN:
                _HOOKS_RUN.add(mod)
                for hook in _HOOKS.get(mod, ()):
                    hook()
        made = {id(k): _numba.njit(**_cache_options(k.options))(k.py_func) for k in todo}
        for k in todo:
            _guard_compile(made[id(k)], k)
            _BY_DISPATCHER[id(made[id(k)])] = k
        for k in seen.values():  # compiled code calls these: they must be dispatchers in the globals
            if k is not kernel:
                k.serial = None
        if kernel.dispatcher is None and kernel.options.get("parallel") and not _reaches_fastmath(kernel):
            copy = variant(kernel, kernel.__name__ + "__serial", parallel=False)
            kernel.serial = _numba.njit(**_cache_options(copy.options))(copy.py_func)
            _guard_compile(kernel.serial, copy)
        for g in {id(k.py_func.__globals__): k.py_func.__globals__ for k in seen.values()}.values():
            _swap_globals(g, made)
        for k in todo:  # published last: a dispatcher another thread may call sees its globals in place
            k.dispatcher = made[id(k)]
        return kernel.dispatcher


_BY_DISPATCHER: dict = {}  # id of a dispatcher made here -> its placeholder


def _reaches_fastmath(kernel: LazyKernel) -> bool:
    """Whether ``kernel`` or any kernel its code can call (as ``_reach`` finds them: placeholders, the
    dispatchers made of them, numba's own dispatchers, through modules named in the code) has ``fastmath``."""
    todo, seen = [(kernel.py_func, kernel.options)], set()
    while todo:
        fn, options = todo.pop()
        if id(fn) in seen:
            continue
        seen.add(id(fn))
        if options.get("fastmath"):
            return True
        for w in _named(fn):
            w = _BY_DISPATCHER.get(id(w), w)
            if isinstance(w, LazyKernel):
                todo.append((w.py_func, w.options))
            elif _numba is not None and isinstance(w, _numba.core.dispatcher.Dispatcher):
                todo.append((w.py_func, w.targetoptions))
    return False


# --- one compilation per kernel across processes ----------------------------------------------------
_HELD = threading.local()  # the lock files this thread holds (a kernel's compile may compile its callees)
_LOCK_DIR: dict = {}


def _lock_folder() -> Path | None:
    """A private per-user folder for the compile locks (None: locks off; the kernels compile unguarded)."""
    if "dir" not in _LOCK_DIR:
        uid = os.getuid() if hasattr(os, "getuid") else os.environ.get("USERNAME", "user")
        folder = Path(tempfile.gettempdir()) / f"edgetruth-jit-locks-{uid}"
        _LOCK_DIR["dir"] = folder if _private(folder) and _writable(folder) else None
    return _LOCK_DIR["dir"]


def _guard_compile(dispatcher, kernel: LazyKernel) -> None:
    """Processes that need the same kernel at once (a pool's workers starting together, the warm-up process
    beside them) compile it once: a dispatcher's ``compile(sig)`` -- numba's cache lookup, then, on a miss,
    the compilation, whose result it writes to the cache -- runs under an exclusive file lock per kernel, so
    the others wait and then load it from the cache instead of compiling it again (on 2 cores, two workers
    compiling the same kernels took twice the time of one).  Only with the on-disk cache (without it
    each process must compile anyway), and only where ``fcntl`` exists."""
    if not kernel.options.get("cache") or _CACHE["off"]:
        return
    try:
        import fcntl  # lazy: optional
    except ImportError:  # Windows: no flock; the kernels compile unguarded, as numba does by default
        return
    folder = _lock_folder()
    if folder is None:
        return
    from numba.core import sigutils  # lazy: numba is heavy (edgetruth.jit compiles on first call)
    from numba.core.compiler_lock import \
        global_compiler_lock  # lazy: numba is heavy (edgetruth.jit compiles on first call)

    path = str(folder / f"{kernel.__module__}.{kernel.__qualname__}.lock")
    compile_sig = dispatcher.compile

    def compile(sig):
        if tuple(sigutils.normalize_signature(sig)[0]) in dispatcher.overloads:
            return compile_sig(sig)  # this process has it (a caller being typed asks again): no file to lock
        held = getattr(_HELD, "paths", None)
        if held is None:
            held = _HELD.paths = set()
        # numba's own (re-entrant, per-process) lock first: a thread of this process never waits on a file
        # another thread of it holds while that thread waits for numba's lock
        with global_compiler_lock:
            if path in held:
                return compile_sig(sig)
            with open(path, "a") as fh:
                fcntl.flock(fh, fcntl.LOCK_EX)
                held.add(path)
                try:
                    return compile_sig(sig)
                finally:
                    held.discard(path)
                    fcntl.flock(fh, fcntl.LOCK_UN)

    dispatcher.compile = compile  # numba calls self.compile(sig) for a new signature (a call, or a caller's typing)


# --- the on-disk cache ------------------------------------------------------------------------------
def _writable(folder: Path) -> bool:
    """Can this process create files in ``folder`` (creating it if needed)?  Tried, as numba does, rather
    than asked of ``os.access``, which answers yes to root whatever the mode bits say."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=folder).close()
        return True
    except OSError:
        return False


def _private(folder: Path) -> bool:
    """``folder`` (in a shared temporary directory) is this user's alone, or can be made so: numba's cache
    files are pickles, which nobody else may plant."""
    try:
        folder.mkdir(mode=0o700, exist_ok=True)
        st = os.lstat(folder)
    except OSError:
        return False
    if not hasattr(os, "getuid"):
        return True

    return stat.S_ISDIR(st.st_mode) and st.st_uid == os.getuid() and not st.st_mode & 0o077


def _numba_user_folder() -> Path:
    """Numba's own per-user cache folder (its ``UserWideCacheLocator``: appdirs' user cache dir)."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    if sys.platform == "darwin":
        base = os.path.join(os.path.expanduser("~"), "Library", "Caches")
    elif sys.platform == "win32":
        base = os.environ.get("LOCALAPPDATA") or tempfile.gettempdir()
    return Path(base) / "numba"


def cache_folder() -> Path | None:
    """Where the kernels' cache goes: None = numba's own choice (``NUMBA_CACHE_DIR``, the package's
    ``__pycache__`` or numba's per-user folder, whichever is writable first), else a per-user folder
    under the temporary directory; raises OSError if nothing is writable."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return None
    here = Path(__file__).resolve().parent
    in_tree = [here / "__pycache__", here / "methods" / "__pycache__"]
    if all(_writable(p) for p in in_tree) or _writable(_numba_user_folder()):
        return None
    uid = os.getuid() if hasattr(os, "getuid") else os.environ.get("USERNAME", "user")
    fallback = Path(tempfile.gettempdir()) / f"edgetruth-numba-{uid}"
    if _private(fallback) and _writable(fallback):
        return fallback
    raise OSError(f"no writable folder for numba's cache (tried {in_tree[0].parent}, {_numba_user_folder()} "
                  f"and {fallback})")


def _configure_cache() -> None:
    if _CACHE["checked"]:
        return
    _CACHE["checked"] = True
    try:
        folder = cache_folder()
    except OSError as exc:
        _CACHE["off"] = True  # compile in memory
        from edgetruth import console  # lazy: optional

        console.warn(f"{exc}: the kernels compile again in every run (~5 s); set NUMBA_CACHE_DIR to a "
                     "writable folder to keep them")
        return
    if folder is not None:
        os.environ["NUMBA_CACHE_DIR"] = str(folder)  # read when numba.config is first imported
        if "numba" in sys.modules:
            sys.modules["numba"].config.CACHE_DIR = str(folder)


def _cache_options(options: dict) -> dict:
    if _CACHE["off"] and options.get("cache"):  # no writable cache folder anywhere
        return {**options, "cache": False}
    return options
