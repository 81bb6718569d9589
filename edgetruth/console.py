"""What long work shows a person: progress bars on a terminal only, and informational lines unless quiet.

Bars draw on stderr, and only when stderr is a terminal (no carriage-return spam in
CI logs or pipes); ``set_quiet(True)`` (the CLI's ``-q``) silences bars and ``say``;
``set_progress(False)`` (``--no-progress``) silences bars only.
"""
from __future__ import annotations

import sys


_state = {"quiet": False, "progress": True}


def set_quiet(quiet: bool) -> None:
    _state["quiet"] = bool(quiet)


def set_progress(enabled: bool) -> None:
    _state["progress"] = bool(enabled)


def quiet() -> bool:
    return _state["quiet"]


def say(message: str) -> None:
    """An informational line on stdout (silenced by ``-q``)."""
    if not _state["quiet"]:
        print(message, flush=True)


def warn(message: str) -> None:
    """A one-line warning on stderr (silenced by ``-q``)."""
    if not _state["quiet"]:
        print(f"warning: {message}", file=sys.stderr, flush=True)


def bars_enabled(requested: bool = True) -> bool:
    return bool(requested) and _state["progress"] and not _state["quiet"] and sys.stderr.isatty()


def bar(total: int | None = None, desc: str = "", unit: str = "it", enabled: bool = True, initial: int = 0):
    """A tqdm bar on stderr (a silent stand-in when bars are off: same methods, no output)."""
    from tqdm import tqdm  # lazy: tqdm only for progress bars

    return tqdm(total=total, desc=desc, unit=unit, initial=initial, file=sys.stderr, dynamic_ncols=True,
                disable=not bars_enabled(enabled))


def track(iterable, desc: str = "", unit: str = "it", enabled: bool = True, total: int | None = None):
    """Iterate ``iterable`` with a bar (on a terminal only)."""
    from tqdm import tqdm  # lazy: tqdm only for progress bars

    return tqdm(iterable, desc=desc, unit=unit, total=total, file=sys.stderr, dynamic_ncols=True,
                disable=not bars_enabled(enabled))
