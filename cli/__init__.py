"""``edgetruth`` command line: the roof of the house, a thin layer over the packages' functions.

Subcommands live in ``cli/commands/<name>.py`` (one module each, with a
``register(subparsers)`` function), so adding one touches no other file.  This is the
only package that imports the commands.

Conventions every command follows: bad input is one line on stderr naming the input
and the fix, exit code 2, with nothing already written touched; ``-q`` silences
everything but errors; progress bars draw only on a terminal.
"""
from __future__ import annotations

import argparse
import ast
import importlib
import os
import pkgutil
import sys
from pathlib import Path

from edgetruth import __version__, console
from edgetruth.errors import InputError


def add_plugin_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--plugin", action="append", default=[], metavar="MODULE",
                   help="import MODULE (a module name or a .py file) first: its @edgetruth.locate.register "
                        "methods join the built-in ones (repeatable; entry points in the 'edgetruth.methods' "
                        "group load by themselves)")


def add_progress_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--no-progress", action="store_true", help="no progress bars (they only draw on a terminal anyway)")


def add_backend_options(p: argparse.ArgumentParser, workers_help: str) -> None:
    p.add_argument("--backend", choices=("local", "ray"), default="local",
                   help="where the work runs: local processes (default) or a Ray cluster (docs/cluster.md)")
    p.add_argument("-j", "--workers", type=positive_int, default=None, metavar="N", help=workers_help)
    p.add_argument("--address", default=None, metavar="ADDR",
                   help="Ray cluster to join (ray://HOST:10001, HOST:6379 or auto; default: $RAY_ADDRESS, "
                        "else a local Ray instance)")


def add_undistort_option(p: argparse.ArgumentParser) -> None:
    """Where the ranging undistorts (``edgetruth.evaluate.ranging.images.UNDISTORT_MODES``)."""
    p.add_argument("--undistort", choices=("image", "points"), default="image",
                   help="image (default: the seed's pipeline): remap the image, then every method refines it; "
                        "points: every method refines the raw image and its points are undistorted, so no "
                        "resampling moves them (the report's Table 13c says what resampling does)")


#: how a colour photo becomes the gray image every method reads (edgetruth.image_io.GRAY_RULES)
CHANNEL_CHOICES = ("luma", "r", "g", "b")


def add_pattern_option(p: argparse.ArgumentParser, what: str, required: bool = False,
                       kinds: tuple[str, ...] = ("chessboard",)) -> None:
    """``--pattern COLSxROWS``: a chessboard's inner corners, as every command that reads one counts them
    (``edgetruth.evaluate.calibration.parse_pattern``); with ``kinds`` naming circle grids or ChArUco too, their
    forms (``edgetruth.evaluate.pattern.parse_board_pattern``); ``what`` says what the command does with
    the board."""
    forms = ["inner corners of a chessboard, per row x per column (OpenCV's patternSize; a board of 10 x 7 squares "
             "is 9x6)"]
    if "circles" in kinds:
        forms.append("circles:COLSxROWS or circles:COLSxROWS:asymmetric: a circle grid, COLS circles per row, ROWS "
                     "rows (cv2.findCirclesGrid's patternSize, e.g. circles:4x11:asymmetric)")
    if "charuco" in kinds:
        forms.append("charuco:COLSxROWS:DICT: a ChArUco board of COLS x ROWS squares with cv2.aruco's dictionary DICT "
                     "(e.g. charuco:5x7:DICT_4X4_50)")
    p.add_argument("--pattern", required=required, default=None,
                   metavar="COLSxROWS" if len(kinds) == 1 else "PATTERN",
                   help="; ".join(forms) + f"; {what}")


def add_square_m_option(p: argparse.ArgumentParser, what: str, required: bool = True) -> None:
    """``--square-m METRES``: a chessboard's printed square, as every command that reads one takes it
    (``parse_square_m``); ``what`` says what the side sets."""
    p.add_argument("--square-m", required=required, metavar="METRES",
                   help=f"side of one printed square in metres (e.g. 0.025); {what}")


def parse_square_m(text: str) -> float:
    """``--square-m``'s value: a positive number of metres below 1 km, else one ``InputError`` line."""
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not (v > 0 and v < 1e3):  # NaN fails too
        raise InputError(f"--square-m {text!r}: give the side of one square in metres, a positive number "
                         "(e.g. 0.025 for 25 mm)")
    return v


def add_image_options(p: argparse.ArgumentParser) -> None:
    """Options of every command that reads photos: how colour becomes gray."""
    p.add_argument("--channel", choices=CHANNEL_CHOICES, default="luma",
                   help="colour photos: 'luma' (default) = 0.299 R + 0.587 G + 0.114 B on the stored values "
                        "(ITU-R BT.601, OpenCV's rule), or take one channel r, g or b; gray images are read as they are")


def positive_int(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if n < 1:
        raise argparse.ArgumentTypeError(f"{n} must be at least 1")
    return n


#: ``--methods`` / ``-m`` help: the method-options syntax, the same on every command
METHOD_SYNTAX = ("a method's options go after its id, joined by ':' (METHOD:key=value[:key=value]), e.g. "
                 "pae2013:variant=floating:order=1; values are read as true/false, none, integers, numbers or "
                 "text and checked against the method's signature (`edgetruth methods` lists the methods).  "
                 "Options are added to those the studies use (pae2013 runs variant=smoothed unless told otherwise)")


def methods_help(what: str = "comma-separated method ids (default: all, plug-ins included)") -> str:
    return f"{what}; {METHOD_SYNTAX}; a method given twice with different options gives one row each"


def method_list(text: str | None) -> list[str] | None:
    """``--methods a,b:key=value`` -> ['a', 'b:key=value'] (each checked against the registry and the
    method's signature, written the canonical way), None for all."""
    from edgetruth.evaluate.method_order import method_specs  # lazy: the dispatcher stays light (--help)

    return method_specs(text)


class OneLineParser(argparse.ArgumentParser):
    """argparse with the house's error form: bad usage is one line on stderr (argparse's own message,
    which names the option, and where to read the usage), exit 2; subcommands' parsers inherit it."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message}; see `{self.prog} --help`\n")


def _commands() -> list[tuple[str, str, str | None]]:
    """(command, module, one-line help) of every module in ``cli/commands`` with a ``register`` function, read
    from its source (the ``add_parser`` call), so that listing the commands imports none of them; help None where
    the source does not spell it as a literal (that command's module is then imported to list it)."""
    from edgetruth.cli import commands  # lazy: --version loads no part of the commands

    out = []
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        path = Path(commands.__path__[0]) / f"{info.name}.py"
        tree = ast.parse(path.read_text(encoding="utf-8"))
        reg = next((n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == "register"), None)
        if reg is None:
            continue
        call = next((c for c in ast.walk(reg) if isinstance(c, ast.Call) and isinstance(c.func, ast.Attribute)
                     and c.func.attr == "add_parser" and c.args and isinstance(c.args[0], ast.Constant)), None)
        name = call.args[0].value if call else info.name.replace("_", "-")
        help_ = next((k.value.value for k in (call.keywords if call else ()) if k.arg == "help"
                      and isinstance(k.value, ast.Constant)), None)
        out.append((name, f"edgetruth.cli.commands.{info.name}", help_))
    return out


def _command_of(argv: list[str]) -> str:
    """The command ``argv`` names ("" for none: ``edgetruth --help``): its first word after the global options."""
    for tok in argv:
        if tok in ("-q", "--quiet"):
            continue
        return "" if tok.startswith("-") else tok
    return ""


def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    """The command line's parser.  With ``argv``, only the command it names is imported and registered in full
    (a command's module imports what it drives at its top); the others are listed by name and help.  Without,
    every command is registered (what the tests of the conventions read)."""
    parser = OneLineParser(
        prog="edgetruth",
        description="Physically-based ground truth for subpixel edge localisation and monocular ranging.",
    )
    parser.add_argument("--version", action="version", version=f"edgetruth {__version__}",
                        help="print the version and exit")
    parser.add_argument("-q", "--quiet", action="store_true", help="print errors only (no progress, no summaries)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    wanted = None if argv is None else _command_of(argv)
    for name, module, help_ in _commands():
        if wanted is None or name == wanted or help_ is None:
            importlib.import_module(module).register(sub)
        else:
            sub.add_parser(name, help=help_)
    return parser


def _asks_version(argv: list[str]) -> bool:
    """``--version`` among the global options before any command: answered without building the parser
    (which imports every command module)."""
    for tok in argv:
        if tok == "--version":
            return True
        if tok not in ("-q", "--quiet"):
            return False
    return False


def _empty_output(argv: list[str]) -> str | None:
    """The option of an empty ``-o ''`` (argparse would take it, and ``Path('')`` is the current folder)."""
    for i, tok in enumerate(argv):
        if tok == "--":
            break
        if tok in ("-o", "--output") and i + 1 < len(argv) and argv[i + 1] == "":
            return tok
        if tok == "--output=":
            return "--output"
    return None


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if _asks_version(argv):  # as argparse's version action: print, exit 0
        print(f"edgetruth {__version__}")
        raise SystemExit(0)
    parser = build_parser(argv)
    args, extra = parser.parse_known_args(argv)  # argparse itself exits 2 on bad usage
    if extra:  # argparse would blame the top-level parser; name the command whose options they are not
        where = f"edgetruth {args.command}" if getattr(args, "command", None) else "edgetruth"
        print(f"{where}: error: unrecognized arguments: {' '.join(extra)}; see `{where} --help`", file=sys.stderr)
        return 2
    empty = _empty_output(argv)
    if empty and getattr(args, "handler", None):
        print(f"edgetruth {args.command}: error: {empty} '': an empty path; give a file or folder name",
              file=sys.stderr)
        return 2
    if not getattr(args, "handler", None):
        parser.print_help()
        return 2
    console.set_quiet(args.quiet)
    console.set_progress(not getattr(args, "no_progress", False))
    try:
        if getattr(args, "plugin", None):
            from edgetruth.locate.plugins import load_plugins  # lazy: only with --plugin

            load_plugins(args.plugin)
        return int(args.handler(args) or 0)
    except InputError as exc:
        print(f"edgetruth {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"edgetruth {args.command}: interrupted; re-run the same command to resume", file=sys.stderr)
        return 130
    except BrokenPipeError:  # the reader went away (`edgetruth methods | head`): no traceback, the shell's SIGPIPE code
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # so that Python's own flush at exit does not raise again
        return 141


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
