"""Errors that reach the user as one line and exit code 2."""
from __future__ import annotations


class InputError(ValueError):
    """Bad user input: an image, a config value, a path.  The message names the
    input and the fix; the CLI prints it as one line and exits with code 2."""


def require(condition: bool, message: str) -> None:
    if not condition:
        raise InputError(message)
