"""``edgetruth`` command line: a thin layer over the packages' functions.

Subcommands live in ``edgetruth/commands/<name>.py`` (one module each, with a
``register(subparsers)`` function), so adding one touches no other file.
"""
from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys

from edgetruth import __version__
from edgetruth.errors import InputError
import edgetruth.commands as _commands


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="edgetruth",
        description="Physically-based ground truth for subpixel edge localisation and monocular ranging.",
    )
    parser.add_argument("--version", action="version", version=f"edgetruth {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for info in sorted(pkgutil.iter_modules(_commands.__path__), key=lambda m: m.name):
        module = importlib.import_module(f"edgetruth.commands.{info.name}")
        if hasattr(module, "register"):
            module.register(sub)
    return parser



def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)  # argparse itself exits 2 on bad usage
    if not getattr(args, "handler", None):
        parser.print_help()
        return 2
    try:
        return int(args.handler(args) or 0)
    except InputError as exc:
        print(f"edgetruth {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"edgetruth {args.command}: interrupted; re-run the same command to resume", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
