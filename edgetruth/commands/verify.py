"""``edgetruth verify DIR``: check a rendered dataset against its manifest.

Exit 0: every image the manifest lists is complete and every file hashes to its
recorded SHA-256.  Exit 1: problems, one line each (missing file, hash mismatch,
temporary file of an interrupted run, files the manifest does not list, images
not yet rendered).  Exit 2: DIR is not a dataset.
"""
from __future__ import annotations

import argparse
import re
from pathlib import Path

from edgetruth.errors import InputError

_SHA = re.compile(r"^[0-9a-f]{64}$")


def register(sub) -> None:
    p = sub.add_parser("verify", help="check a dataset's files against its manifest (hashes)",
                       description="Check every file of a dataset rendered by `edgetruth render` against the "
                                   "SHA-256 hashes in its manifest.json.  Exit 0 if all is well, 1 if "
                                   "anything is missing, damaged, left over or not yet rendered, 2 if DIR "
                                   "is not a dataset.")
    p.add_argument("dir", metavar="DIR", type=Path, help="dataset directory (holds manifest.json)")
    p.set_defaults(handler=run)


def load_manifest(d: Path) -> dict:
    """The manifest of dataset ``d``, checked for shape; InputError otherwise."""
    from render.dataset import MANIFEST
    from render.files import read_json

    if not d.exists():
        raise InputError(f"{d}: no such directory; pass the -o directory of `edgetruth render`")
    if not d.is_dir():
        raise InputError(f"{d}: not a directory; pass the -o directory of `edgetruth render`")
    mpath = d / MANIFEST
    if not mpath.is_file():
        raise InputError(f"{d}: no {MANIFEST}, so not an edgetruth dataset; render one with "
                         f"`edgetruth render SPEC -o {d}`")
    try:
        m = read_json(mpath)
    except InputError:
        raise InputError(f"{mpath}: not valid JSON; re-run `edgetruth render` for this spec into a new "
                         "directory (or delete the manifest to re-render everything)") from None
    ok = (isinstance(m, dict) and isinstance(m.get("images"), dict) and isinstance(m.get("n_images"), int)
          and all(isinstance(e, dict) and isinstance(e.get("files"), dict)
                  and all(isinstance(f, dict) and isinstance(f.get("path"), str) and _SHA.match(str(f.get("sha256", "")))
                          for f in e["files"].values())
                  for e in m["images"].values()))
    if not ok:
        raise InputError(f"{mpath}: not an edgetruth manifest (missing or malformed images/files/sha256 "
                         "entries); re-render into a new directory")
    return m


def check(d: Path) -> tuple[list[str], dict]:
    """(problems, manifest) for dataset ``d``; one human-readable line per problem."""
    from render.dataset import MANIFEST, is_temporary
    from render.files import sha256_file

    m = load_manifest(d)
    problems: list[str] = []
    listed = {MANIFEST}
    complete = 0
    for name, entry in m["images"].items():
        ok = bool(entry.get("complete"))
        if not ok:
            problems.append(f"incomplete: {name} (manifest entry not marked complete)")
        for f in entry["files"].values():
            rel = f["path"]
            listed.add(rel)
            p = d / rel
            if Path(rel).is_absolute() or ".." in Path(rel).parts:
                problems.append(f"bad path: {name}: {rel!r} is outside the dataset")
                ok = False
            elif not p.is_file():
                problems.append(f"missing: {rel}")
                ok = False
            elif sha256_file(p) != f["sha256"]:
                problems.append(f"hash mismatch: {rel} (file changed or damaged since it was rendered)")
                ok = False
        complete += ok
    for p in sorted(d.iterdir()):
        if is_temporary(p):
            problems.append(f"extra-temp: {p.name} (left by an interrupted run)")
        elif p.name not in listed and p.is_file():
            problems.append(f"extra: {p.name} (not in the manifest)")
    n = m["n_images"]
    if len(m["images"]) < n:
        problems.append(f"not rendered: {n - len(m['images'])} of {n} images")
    return problems, {"manifest": m, "complete": complete, "n_images": n}


def run(args: argparse.Namespace) -> int:
    d: Path = args.dir
    problems, info = check(d)
    for line in problems:
        print(line)
    m = info["manifest"]
    if problems:
        print(f"verify: {d}: {len(problems)} problem(s); {info['complete']}/{info['n_images']} images of "
              f"{m.get('spec')!r} intact.  Re-run `edgetruth render` with the same spec and -o to repair "
              "(it re-renders only what is missing or damaged)")
        return 1
    print(f"verify: {d}: OK, {info['complete']}/{info['n_images']} images of {m.get('spec')!r}, "
          "every file matches its SHA-256")
    return 0
