"""The built-in methods: one module per method (or method family); importing this package imports
every module here, and each registers its methods via ``edgetruth.locate.registry.register``."""
import importlib as _importlib
import pkgutil as _pkgutil

for _info in sorted(_pkgutil.iter_modules(__path__), key=lambda m: m.name):
    if not _info.name.startswith("_"):
        _importlib.import_module(f"{__name__}.{_info.name}")
