"""Which rows (or image records) make each table's cells: the paired design's base cell, the levels
of each factor on the same pose slots, and the groups outside any design (Tables 13-17, the factor
tables and the per-point tables alike), and the constants the ranging and per-point studies share: the
distance intervals, the reference method and the seed's method sets.  Both studies import it; neither
imports the other."""
from __future__ import annotations

from dataclasses import dataclass, field

#: the distance intervals of the tables (cm; the last one closed)
INTERVALS_CM = ((50, 100), (100, 150), (150, 200), (200, 250), (250, 300))
#: the method every other is compared with (the seed's proposed one)
REFERENCE_METHOD = "dynamic_erf_4p"
#: The seed's Table 13 methods, and the representative set of Tables 16-17.
SEED_TABLE13 = ("canny_pixel", "canny_devernay", "hagara_aef2011", "sigmoid_logistic_fit2023", "ser_cis",
                "dynamic_erf_4p")
SEED_ROBUSTNESS = ("canny_pixel", "erf4p_fixed11", "ser_cis", "dynamic_erf_4p")


def interval_label(distance_cm: float) -> str:
    """The table interval a distance (cm) falls in ("50-100", ...; "<50" and ">300" outside)."""
    for a, b in INTERVALS_CM:
        if a <= distance_cm < b or (b == INTERVALS_CM[-1][1] and distance_cm == b):
            return f"{a}-{b}"
    return "<50" if distance_cm < INTERVALS_CM[0][0] else ">300"


def level_of(row, factor: str) -> str | None:
    """The level of ``factor`` in a row's ``levels`` field (``snr=G2;target=T1``), or None."""
    for part in str(row.get("levels", "")).split(";"):
        k, _, v = part.partition("=")
        if k == factor:
            return v
    return None


#: the design factors behind Tables 16 (SNR levels G1-G4) and 17 (targets T1-T4); any other factor
#: gets a table of its own, named after it (``factor_tables``)
TABLE_FACTORS = {"G": ("snr", "illumination"), "T": ("target",)}
#: the seed's titles of the two tables above
SEED_TITLES = {"G": "Table 16 — SNR groups G1–G4", "T": "Table 17 — targets T1–T4"}


def main_rows(rows):
    """Rows of Tables 13-15 and claims 1-4: a paired design's base cell (every factor at its first
    level: the seed's standard experiment); else the ``standard`` spec when present; else every row."""
    base = [r for r in rows if r.get("levels") and r.get("off_base", "") == ""]
    return base or [r for r in rows if r.get("spec") == "standard"] or list(rows)


def design_factors(rows) -> dict[str, list[str]]:
    """Every factor of the paired design(s) in ``rows`` with its levels, in the spec's order: the base
    level first, then the others as their cells first appear (cells are rendered, and rows come
    back, in the spec's order)."""
    seen: dict[str, list[str]] = {}
    base: dict[str, str] = {}
    for r in rows:
        if not r.get("levels"):
            continue
        for part in str(r["levels"]).split(";"):
            k, _, v = part.partition("=")
            if not k:
                continue
            lv = seen.setdefault(k, [])
            if v not in lv:
                lv.append(v)
            if r.get("off_base", "") == "":
                base.setdefault(k, v)
    return {k: ([base[k]] if k in base else []) + [v for v in lv if v != base.get(k)] for k, lv in seen.items()}


def factor_rows(rows, factor: str):
    """The cells of a paired design that move only ``factor`` off the base (every level on the same
    pose slots), with ``group`` = the level."""
    return [dict(r, group=level_of(r, factor)) for r in rows
            if r.get("levels") and r.get("off_base", "") in ("", factor) and level_of(r, factor)]


def table_factor(rows, prefix: str) -> str | None:
    """The design factor behind Table 16 (prefix G) or 17 (T) in ``rows``, or None."""
    for factor in TABLE_FACTORS[prefix]:
        if any(level_of(r, factor) for r in rows if r.get("levels")):
            return factor
    return None


def group_rows(rows, prefix: str):
    """Rows of Table 16 (prefix G) or 17 (prefix T), with ``group`` = the level.  A paired design: the
    cells that move only that factor off the base (every level on the same pose slots).  Otherwise
    the ``snr`` / ``targets`` spec, else every row outside a design whose group is G1..G4 / T1..T4."""
    factor = table_factor(rows, prefix)
    if factor is not None:
        sel = factor_rows(rows, factor)
        if sel:
            return sel
    spec = {"G": "snr", "T": "targets"}[prefix]
    sel = [r for r in rows if r.get("spec") == spec]
    if not sel:
        sel = [r for r in rows if not r.get("levels")]
    return [r for r in sel if str(r["group"]).startswith(prefix) and len(str(r["group"])) == 2]


@dataclass
class FactorTable:
    """One table across the levels of a factor: ``key`` is G or T for the seed's Tables 16/17 (and
    the per-point E4G/E4T), else the factor's own name; ``rows`` carry ``group`` = the level."""

    factor: str
    key: str
    levels: list[str]
    rows: list = field(default_factory=list)

    @property
    def paired(self) -> bool:
        """The levels share pose slots (cells of a paired design)."""
        return bool(self.rows) and all(r.get("levels") for r in self.rows)

    @property
    def title(self) -> str:
        return SEED_TITLES.get(self.key) or f"Factor {self.factor}: " + " vs ".join(self.levels)

    def cell_label(self, level: str) -> str:
        """How a level is named in a table of cells (the window shares): G2, T3, fnum=F8."""
        return level if self.key in SEED_TITLES else f"{self.factor}={level}"


def factor_tables(rows) -> list[FactorTable]:
    """Every table across a factor's levels that ``rows`` hold: Table 16 (G), Table 17 (T), then each
    other factor of the design with two or more levels, in the spec's order.  Each level's rows in
    the spec's order; the seed's tables keep their sorted level names when they are not a design's."""
    out = []
    used = set()
    order = design_factors(rows)
    for prefix in SEED_TITLES:
        sel = group_rows(rows, prefix)
        if not sel:
            continue
        factor = table_factor(rows, prefix)
        if factor is not None and factor_rows(rows, factor):
            used.add(factor)
            levels = [v for v in order[factor] if any(r["group"] == v for r in sel)]
        else:
            factor = {"G": "snr", "T": "target"}[prefix]
            levels = sorted({r["group"] for r in sel})
        out.append(FactorTable(factor, prefix, levels, sel))
    for factor, levels in order.items():
        if factor in used or len(levels) < 2:
            continue
        sel = factor_rows(rows, factor)
        present = [v for v in levels if any(r["group"] == v for r in sel)]
        if len(present) >= 2:
            out.append(FactorTable(factor, factor, present, sel))
    return out


def plain_groups(rows) -> FactorTable | None:
    """The groups outside any design (each drew its own poses), with ``group`` = the group's name,
    when a report would not show them by group otherwise: a design is there too (its base cell is
    then Tables 13-15), or there are two or more such groups.  Groups the fallback Tables 16/17
    already show (G1..G4, T1..T4 outside a design) are left out."""
    shown = {r["group"] for prefix in SEED_TITLES for r in group_rows(rows, prefix) if not r.get("levels")}
    plain = [r for r in rows if not r.get("levels") and r.get("group", "") not in shown]
    names = sorted({str(r.get("group", "")) for r in plain})
    designed = any(r.get("levels") for r in rows)
    if not plain or (not designed and len(names) < 2):
        return None
    return FactorTable("group", "group", names, [dict(r, group=str(r.get("group", ""))) for r in plain])
