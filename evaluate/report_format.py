"""Markdown cells and tables of the reports: one way to print a number, an interval, a table."""
from __future__ import annotations

import numpy as np


def num(v, nd=3) -> str:
    """A number with ``nd`` decimals, or an em dash when it is missing."""
    return "—" if v is None or not np.isfinite(v) else f"{v:.{nd}f}"


def signed(v, nd=3) -> str:
    """A signed number (a bias) with ``nd`` decimals, or an em dash when it is missing."""
    return "—" if v is None or not np.isfinite(v) else f"{v:+.{nd}f}"


def table(header, body) -> str:
    """A Markdown table."""
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    out += ["| " + " | ".join(str(c) for c in row) + " |" for row in body]
    return "\n".join(out)


def ci(ci, nd=3) -> str:
    """A confidence interval ``[lo, hi]``, or an em dash."""
    lo, hi = ci
    return "—" if not (np.isfinite(lo) and np.isfinite(hi)) else f"[{lo:.{nd}f}, {hi:.{nd}f}]"
