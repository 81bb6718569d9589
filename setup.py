"""Packages are found, not listed: each top-level source folder installs under the one ``edgetruth``
namespace (``render/`` -> ``edgetruth.render``, ...), with every folder below it that holds an
``__init__.py``.  A new sub-package needs no edit here or in pyproject.toml (which holds everything
else, package data included); tests/package/test_wheel.py checks the built wheel holds them all."""
from setuptools import find_packages, setup

#: package -> the folder it installs from (no top-level render/locate/evaluate in site-packages)
FOLDERS = {"edgetruth": "edgetruth", "edgetruth.cli": "cli", "edgetruth.render": "render", "edgetruth.locate": "locate",
           "edgetruth.evaluate": "evaluate", "edgetruth.scenes": "scenes", "edgetruth.assets": "assets"}


def packages() -> list[str]:
    out = []
    for pkg, folder in FOLDERS.items():
        out += [pkg, *(f"{pkg}.{sub}" for sub in find_packages(folder))]
    return out


setup(packages=packages(), package_dir=FOLDERS)
