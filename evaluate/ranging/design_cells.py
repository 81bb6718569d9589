"""Which rows (or image records) make each table's cells: the paired design's base cell and the
levels of one factor on the same pose slots (Tables 13-17 and the per-point tables alike)."""
from __future__ import annotations


def level_of(row, factor: str) -> str | None:
    """The level of ``factor`` in a row's ``levels`` field (``snr=G2;target=T1``), or None."""
    for part in str(row.get("levels", "")).split(";"):
        k, _, v = part.partition("=")
        if k == factor:
            return v
    return None


#: the design factors behind Tables 16 (SNR levels G1-G4) and 17 (targets T1-T4)
TABLE_FACTORS = {"G": ("snr", "illumination"), "T": ("target",)}


def main_rows(rows):
    """Rows of Tables 13-15 and claims 1-4: a paired design's base cell (every factor at its first
    level: the seed's standard experiment); else the ``standard`` spec when present; else every row."""
    base = [r for r in rows if r.get("levels") and r.get("off_base", "") == ""]
    return base or [r for r in rows if r.get("spec") == "standard"] or list(rows)


def group_rows(rows, prefix: str):
    """Rows of Table 16 (prefix G) or 17 (prefix T), with ``group`` = the level.  A paired design: the
    cells that move only that factor off the base (every level on the same pose slots).  Otherwise
    the ``snr`` / ``targets`` spec, else every row whose group is G1..G4 / T1..T4."""
    for factor in TABLE_FACTORS[prefix]:
        sel = [dict(r, group=level_of(r, factor)) for r in rows
               if r.get("levels") and r.get("off_base", "") in ("", factor) and level_of(r, factor)]
        if sel:
            return sel
    spec = {"G": "snr", "T": "targets"}[prefix]
    sel = [r for r in rows if r.get("spec") == spec]
    if not sel:
        sel = list(rows)
    return [r for r in sel if str(r["group"]).startswith(prefix) and len(str(r["group"])) == 2]
