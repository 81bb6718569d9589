"""Declarative key tables for spec and camera TOML: type, unit, default, range and meaning of every key.

One table per TOML table (``[spec]``, ``[[group]]``, ``[sensor]``, ``[camera]``, ...),
declared next to the typed object it fills.  ``parse_table`` checks a parsed TOML
table against its keys in one pass (unknown keys, types, ranges, choices) and
returns the values with defaults filled in; every problem is one ``InputError``
naming the file, the table, the key and the fix.  ``docs/spec.md`` is generated
from the same tables (``edgetruth.render.dataset.spec_doc``), so the documentation cannot
drift from what the loader accepts.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any, Callable

from edgetruth.errors import InputError

NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,99}$")
REQUIRED = object()


@dataclass(frozen=True)
class Key:
    name: str
    type: str  # "int", "float", "str", "bool", "name", "table", "tables" (a list of tables), "range2" (a [lo, hi]
    # pair), "ranges" ([[lo, hi], ...]), "vec3" ([x, y, z], each in [lo, hi]), "vec2" ([x, y], each in [lo, hi]),
    # "points2" ([[x, y], ...], three or more, each coordinate in [lo, hi]), "floats" ([a, b, ...], one or more
    # numbers, each in [lo, hi])
    default: Any
    unit: str
    meaning: str
    lo: float | None = None  # inclusive bounds for numbers (and for each element of ranges)
    hi: float | None = None
    choices: tuple | None = None
    #: may a [[group]] override it (camera and sensor keys)
    per_group: bool = False
    check: Callable[[Any], str | None] | None = None  # extra rule: returns the fix, or None when fine

    def describe_range(self) -> str:
        if self.choices:
            return ", ".join(map(str, self.choices))
        if self.lo is None and self.hi is None:
            return ""
        lo = "-inf" if self.lo is None else f"{self.lo:g}"
        hi = "inf" if self.hi is None else f"{self.hi:g}"
        return f"[{lo}, {hi}]"


def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_num(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _in(k: Key, v: float) -> bool:
    return (k.lo is None or v >= k.lo) and (k.hi is None or v <= k.hi)


def check_value(k: Key, v, where: str):
    """``v`` converted to the key's type, or an InputError naming ``where``, the key and the fix."""
    def bad(fix: str):
        raise InputError(f"{where}: {k.name} = {v!r}: {fix}")

    rng = k.describe_range()
    if k.type == "int":
        if not _is_int(v) or not _in(k, v):
            bad(f"must be an integer in {rng}" + (f" ({k.unit})" if k.unit else ""))
    elif k.type == "float":
        if not _is_num(v) or not _in(k, v):
            bad(f"must be a finite number in {rng}" + (f" {k.unit}" if k.unit else ""))
        v = float(v)
    elif k.type == "bool":
        if not isinstance(v, bool):
            bad("must be true or false")
    elif k.type == "str":
        if not isinstance(v, str):
            bad("must be a string")
    elif k.type == "name":
        if not (isinstance(v, str) and NAME_RE.match(v) and ".." not in v):
            bad("use 1-100 letters, digits, '_', '-', '.' (it names files and directories)")
    elif k.type == "range2":
        if not (isinstance(v, list) and len(v) == 2 and all(_is_num(x) for x in v) and v[0] <= v[1]
                and all(_in(k, x) for x in v)):
            bad(f"give [near, far] with near <= far, each in {rng} {k.unit}")
        v = (float(v[0]), float(v[1]))
    elif k.type == "ranges":
        if not (isinstance(v, list) and v and all(isinstance(r, list) and len(r) == 2 and all(_is_num(x) for x in r)
                                                  and r[0] <= r[1] and all(_in(k, x) for x in r) for r in v)):
            bad(f"give [[near, far], ...] with near <= far, each in {rng} {k.unit}")
        v = tuple((float(a), float(b)) for a, b in v)
    elif k.type == "vec3":
        if not (isinstance(v, list) and len(v) == 3 and all(_is_num(x) and _in(k, x) for x in v)):
            bad(f"give [x, y, z], each a number in {rng}" + (f" {k.unit}" if k.unit else ""))
        v = tuple(float(x) for x in v)
    elif k.type == "vec2":
        if not (isinstance(v, list) and len(v) == 2 and all(_is_num(x) and _in(k, x) for x in v)):
            bad(f"give [x, y], each a number in {rng}" + (f" {k.unit}" if k.unit else ""))
        v = tuple(float(x) for x in v)
    elif k.type == "points2":
        if not (isinstance(v, list) and len(v) >= 3 and all(isinstance(p, list) and len(p) == 2 and
                                                            all(_is_num(x) and _in(k, x) for x in p) for p in v)):
            bad(f"give three or more points [[x, y], ...], each a number in {rng}" + (f" {k.unit}" if k.unit else ""))
        v = tuple((float(p[0]), float(p[1])) for p in v)
    elif k.type == "floats":
        if not (isinstance(v, list) and v and all(_is_num(x) and _in(k, x) for x in v)):
            bad(f"give [a, b, ...], each a number in {rng}" + (f" {k.unit}" if k.unit else ""))
        v = tuple(float(x) for x in v)
    elif k.type == "table":
        if not isinstance(v, dict):
            bad("must be a table { key = value, ... }")
    elif k.type == "tables":
        if not (isinstance(v, list) and v and all(isinstance(x, dict) for x in v)):
            bad("must be a list of one or more tables [{ key = value, ... }, ...]")
    else:  # pragma: no cover - a key table bug
        raise AssertionError(k.type)
    if k.choices is not None and v not in k.choices:
        bad(f"choose one of {', '.join(map(str, k.choices))}")
    if k.check is not None:
        fix = k.check(v)
        if fix:
            bad(fix)
    return v


def parse_table(table, keys: list[Key], where: str, defaults: bool = True) -> dict:
    """Check ``table`` against ``keys``; returns {name: value} (with defaults unless ``defaults=False``)."""
    if not isinstance(table, dict):
        raise InputError(f"{where}: must be a table, got {type(table).__name__}")
    by_name = {k.name: k for k in keys}
    unknown = sorted(set(table) - set(by_name))
    if unknown:
        raise InputError(f"{where}: unknown key(s) {', '.join(unknown)}; known keys: {', '.join(by_name)}")
    out = {}
    for k in keys:
        if k.name in table:
            out[k.name] = check_value(k, table[k.name], where)
        elif k.default is REQUIRED:
            raise InputError(f"{where}: missing key {k.name} ({k.meaning}); add it")
        elif defaults:
            out[k.name] = k.default
    return out
