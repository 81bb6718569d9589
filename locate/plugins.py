"""User methods: entry points, ``--plugin MODULE``, and shipping them to worker processes.

A user's method is a function ``fn(image, cand, **options) -> Refinement`` registered
with ``@edgetruth.locate.register("my_method")``.  edgetruth finds it in three ways:

- an installed package declares an entry point in the group ``edgetruth.methods``::

      [project.entry-points."edgetruth.methods"]
      my_method = "my_pkg.edge:refine"      # a function: registered under the entry point's name
      my_pkg = "my_pkg.edge"                # a module: importing it registers its methods

- ``--plugin MODULE`` on every command that runs methods: an importable module name or a
  path to a ``.py`` file, imported before the command starts;
- registered in the calling process (a notebook, a script's ``__main__``).

Worker processes (local pool, Ray) import the same plugins, and receive the functions
registered in the caller by value (cloudpickle), so a method defined in a notebook runs
in workers too.
"""
from __future__ import annotations

import importlib
import importlib.util
import sys
from importlib import metadata
from pathlib import Path

from edgetruth.errors import InputError
from edgetruth.locate.registry import METHODS, Method, register

ENTRY_POINT_GROUP = "edgetruth.methods"
_loaded: dict[str, object] = {}
_path_added: list[str] = []  # folders put on sys.path to import a plug-in by name (python -m's rule)
_entry_points_loaded = False


def load_entry_points() -> list[str]:
    """Import every ``edgetruth.methods`` entry point once and register each function under its name.

    ``import edgetruth.locate`` calls this, so an installed package's methods are there in every process.

    Returns
    -------
    list of str
        The entry points' names (the method ids they register).

    Raises
    ------
    edgetruth.errors.InputError
        An entry point that does not load (naming it and the package to fix).
    """
    global _entry_points_loaded
    names = []
    for ep in metadata.entry_points(group=ENTRY_POINT_GROUP):
        names.append(ep.name)
        if _entry_points_loaded:
            continue
        try:
            obj = ep.load()
        except Exception as exc:
            raise InputError(f"entry point {ep.name} = {ep.value!r} (group {ENTRY_POINT_GROUP}) does not load: "
                             f"{type(exc).__name__}: {exc}; fix or uninstall the package that declares it") from None
        if callable(obj) and not isinstance(obj, type(sys)):
            register(ep.name, family="user")(obj)
    _entry_points_loaded = True
    return names


def load_plugin(ref: str):
    """Import a plug-in once, as ``--plugin REF`` does: its ``register`` calls add its methods.

    Parameters
    ----------
    ref : str
        A module name (imported from the current folder first, as ``python -m`` does) or a path to a
        ``.py`` file.

    Returns
    -------
    module
        The imported module (the same object on later calls).

    Raises
    ------
    edgetruth.errors.InputError
        No such file or module, or a module whose own import fails (the two are told apart).
    """
    if ref in _loaded:
        return _loaded[ref]
    p = Path(ref)
    try:
        if p.suffix == ".py" or "/" in ref:
            if not p.is_file():
                raise InputError(f"--plugin {ref}: no such file; give a .py file or an importable module name")
            name = f"edgetruth_plugin_{p.stem}"
            spec = importlib.util.spec_from_file_location(name, p)
            module = importlib.util.module_from_spec(spec)
            sys.modules[name] = module
            spec.loader.exec_module(module)
        else:
            module = _import_by_name(ref)
    except InputError:
        raise
    except Exception as exc:  # the user's code: any error while importing it
        raise InputError(f"--plugin {ref}: importing it raised {type(exc).__name__}: {exc}; "
                         "fix the module (the error is inside it)") from None
    _loaded[ref] = module
    return module


def _import_by_name(ref: str):
    """Import module ``ref`` as ``python -m`` would find it: the import path, then the current folder
    (a console script's path does not hold the current folder).  A module that is found but fails
    to import its own dependencies is the user's code failing, not a missing module."""
    if importlib.util.find_spec(ref.split(".")[0]) is None:
        cwd = str(Path.cwd())
        if cwd not in sys.path:
            sys.path.insert(0, cwd)
            _path_added.append(cwd)
        importlib.invalidate_caches()
        if importlib.util.find_spec(ref.split(".")[0]) is None:
            raise InputError(f"--plugin {ref}: no module named {ref.split('.')[0]!r} on the import path nor in the "
                             f"current folder {cwd}; run from the module's folder, give its .py path, or "
                             "pip install the package that holds it")
    return importlib.import_module(ref)


def load_plugins(refs=()) -> None:
    """Entry points, then each ``--plugin`` reference."""
    load_entry_points()
    for ref in refs or ():
        load_plugin(ref)


def _ship(m: Method) -> bool:
    """Methods a worker does not get by importing the built-ins and the plugins: registered in the
    calling process (cloudpickle sends those of ``__main__`` -- a script, a notebook -- by value and
    those of importable modules by reference)."""
    if m.builtin:
        return False
    return getattr(m.fn, "__module__", "") not in {getattr(v, "__name__", None) for v in _loaded.values()}


def _worker_ref(ref: str, module) -> str:
    """How a worker imports a plug-in: its name, or its file when it was found in this process's
    current folder (a worker may start elsewhere)."""
    f = getattr(module, "__file__", None)
    if f and any(str(Path(f).resolve()).startswith(str(Path(d).resolve()) + "/") for d in _path_added):
        return f
    return ref


def worker_payload(methods=None) -> tuple:
    """Initializer arguments that make a worker know the same methods as this process."""
    import cloudpickle

    wanted = list(METHODS) if methods is None else list(methods)
    extra = {k: METHODS[k] for k in wanted if k in METHODS and _ship(METHODS[k])}
    return (tuple(_worker_ref(r, m) for r, m in _loaded.items()), cloudpickle.dumps(extra) if extra else b"")


def init_worker(plugin_refs: tuple = (), shipped: bytes = b"") -> None:
    """In a worker process: import the plugins, then register the methods shipped by value."""
    import pickle

    import edgetruth.locate.methods  # noqa: F401  (the built-in methods)

    load_plugins(plugin_refs)
    if shipped:
        for mid, m in pickle.loads(shipped).items():
            if mid not in METHODS:
                METHODS[mid] = m


def backend_initializer(backend: str, workers: int | None, methods=None) -> tuple:
    """``(initializer, initargs)`` for ``edgetruth.backends.make_backend``: workers of a pool or a Ray
    cluster learn this process's plug-ins and user methods; in-process work needs nothing."""
    if backend == "local" and (workers or 1) <= 1:
        return None, ()
    return init_worker, worker_payload(methods)
