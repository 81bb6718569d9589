"""MkDocs hooks for `make docs` (mkdocs.yml `hooks:`).

The package's folders install under one namespace by setuptools' package-dir (``render/`` ->
``edgetruth.render``, ...). griffe, which reads the docstrings for the API reference without importing
anything, follows folders, so ``on_startup`` lays out that namespace as copies and links under ``build/apisrc/``
(git-ignored), read from setup.py's own mapping (``FOLDERS``): the reference is of the source as checked out.
"""
from __future__ import annotations

import ast
import os
import shutil
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
API_SRC = ROOT / "build" / "apisrc"


def package_folders(root: Path = ROOT) -> dict:
    """setup.py's ``FOLDERS``: package -> the folder it installs from (read, not run)."""
    for node in ast.parse((root / "setup.py").read_text()).body:
        target = node.target if isinstance(node, ast.AnnAssign) else (node.targets[0] if isinstance(node, ast.Assign)
                                                                       else None)
        if isinstance(target, ast.Name) and target.id == "FOLDERS":
            return ast.literal_eval(node.value)
    raise RuntimeError("setup.py has no FOLDERS mapping")


def build_api_tree(root: Path = ROOT, out: Path = API_SRC) -> Path:
    """Link each ``edgetruth.*`` package of setup.py's ``FOLDERS`` to its folder under ``out``."""
    mapping = package_folders(root)
    if out.exists():
        shutil.rmtree(out)
    top = out / "edgetruth"
    top.mkdir(parents=True)
    for entry in (root / mapping["edgetruth"]).iterdir():  # the package's own modules
        if entry.suffix == ".py":
            shutil.copy2(entry, top / entry.name)  # copied: griffe resolves a linked __init__.py to its folder
        elif entry.is_dir() and entry.name != "__pycache__":
            os.symlink(entry, top / entry.name)
    # the sub-packages that live in their own folders, shortest name first (parents before children)
    for name, folder in sorted(mapping.items(), key=lambda kv: kv[0].count(".")):
        parts = name.split(".")[1:]
        if not parts:
            continue
        dest = top.joinpath(*parts)
        if dest.is_symlink() or dest.exists():
            continue  # inside a folder already linked (e.g. locate/methods under locate/)
        dest.parent.mkdir(parents=True, exist_ok=True)
        os.symlink(root / folder, dest)
    return out


def on_startup(command, dirty):  # noqa: ARG001 -- MkDocs' hook signature
    build_api_tree()


#: Pages other work adds, named in the nav: until one lands, the build generates a marked placeholder in its
#: place (never written to docs/), so the strict build does not fail on it and no stub competes with the page.
PENDING_PAGES = {
    "photos.md": ("Ranging your own photos", "issue 46"),
    "patterns.md": ("Circle grids and ChArUco", "issue 48"),
    "architecture.md": ("Architecture", "issue 49"),
}


def on_files(files, config):
    from mkdocs.structure.files import File

    for src, (title, issue) in PENDING_PAGES.items():
        if files.get_file_from_path(src) is None:
            text = (f"# {title}\n\n!!! note \"Placeholder\"\n    This page is not written yet ({issue}); "
                    "the build generates this note in its place.\n")
            files.append(File.generated(config, src, content=text))
    return files
