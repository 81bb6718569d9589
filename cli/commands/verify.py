"""``edgetruth verify DIR``: check a rendered dataset against its manifest.

Exit 0: every image the manifest (and the journal of a running or killed render) lists
is complete and every file hashes to its recorded SHA-256.  Exit 1: problems, one line
each (missing file, hash mismatch, temporary file of an interrupted run, files the
manifest does not list, damaged journal lines, images not yet rendered).  Exit 2: DIR is
not a dataset, or its manifest is damaged.  A killed run's journal is compacted into
the manifest first (a lossless rewrite; not while a render holds the directory).
"""
from __future__ import annotations

import argparse
from pathlib import Path

from edgetruth import console
from edgetruth.render.dataset.driver import compact_if_idle
from edgetruth.render.dataset.reader import check_dataset


def register(sub) -> None:
    p = sub.add_parser("verify", help="check a dataset's files against its manifest (hashes)",
                       description="Check every file of a dataset rendered by `edgetruth render` against the "
                                   "SHA-256 hashes in its manifest.json.  Exit 0 if all is well, 1 if "
                                   "anything is missing, damaged, left over or not yet rendered, 2 if DIR "
                                   "is not a dataset.")
    p.add_argument("dir", metavar="DIR", type=Path, help="dataset directory (holds manifest.json)")
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    d: Path = args.dir
    if compact_if_idle(d):  # a killed run's journal (unless a render is writing it now)
        console.say(f"verify: {d}: compacted journal.jsonl into manifest.json")
    problems, info = check_dataset(d)
    for line in problems:
        print(line)
    m = info["manifest"]
    if problems:
        print(f"verify: {d}: {len(problems)} problem(s); {info['complete']}/{info['n_images']} images of "
              f"{m.get('spec')!r} intact.  Re-run `edgetruth render` with the same spec and -o to repair "
              "(it re-renders only what is missing or damaged)")
        return 1
    console.say(f"verify: {d}: OK, {info['complete']}/{info['n_images']} images of {m.get('spec')!r}, "
                "every file matches its SHA-256")
    return 0
