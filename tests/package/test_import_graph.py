"""The house: one direction of imports, no cycles.

Ground floor (conventions, errors, file and image I/O, resources, console, backends) ->
``render`` and ``locate`` (independent of each other) -> ``evaluate`` -> the CLI on top,
the only package that imports the commands.  Imports inside functions count too: a lazy
import is still a dependency.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
#: source folder -> package it installs as (pyproject's package-dir)
SOURCES = {"edgetruth": "edgetruth", "cli": "edgetruth.cli", "render": "edgetruth.render", "locate": "edgetruth.locate",
           "evaluate": "edgetruth.evaluate"}
GROUND = ("edgetruth.conventions", "edgetruth.errors", "edgetruth.fileio", "edgetruth.image_io",
          "edgetruth.resources", "edgetruth.console", "edgetruth.backends", "edgetruth.jit", "edgetruth.opencv_threads",
          "edgetruth")


def modules() -> dict[str, Path]:
    out = {}
    for folder, pkg in SOURCES.items():
        for f in sorted((ROOT / folder).rglob("*.py")):
            rel = f.relative_to(ROOT / folder).with_suffix("")
            parts = [p for p in rel.parts if p != "__init__"]
            out[".".join([pkg, *parts])] = f
    return out


def imports(name: str, path: Path, known: set) -> set:
    tree = ast.parse(path.read_text(), str(path))
    is_pkg = path.name == "__init__.py"
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                pkg = name.split(".") if is_pkg else name.split(".")[:-1]
                pkg = pkg[:len(pkg) - node.level + 1]
                base = ".".join(pkg + ([base] if base else []))
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in known else base for a in node.names]
        else:
            continue
        for t in targets:
            while t and t not in known:  # a name inside a module: the module
                t = t.rpartition(".")[0]
            if t and t != name:
                out.add(t)
    return out


@pytest.fixture(scope="module")
def graph() -> dict[str, set]:
    mods = modules()
    known = set(mods)
    return {m: imports(m, p, known) for m, p in mods.items()}


def _layer(m: str) -> str:
    if m == "edgetruth.__main__":  # ``python -m edgetruth``: the command line
        return "cli"
    if m in GROUND:
        return "ground"
    for layer in ("render", "locate", "evaluate", "cli"):
        if m == f"edgetruth.{layer}" or m.startswith(f"edgetruth.{layer}."):
            return layer
    return "ground"


ALLOWED = {"ground": {"ground"}, "render": {"ground", "render"}, "locate": {"ground", "locate"},
           "evaluate": {"ground", "render", "locate", "evaluate"},
           "cli": {"ground", "render", "locate", "evaluate", "cli"}}


def test_every_source_folder_is_found(graph):
    assert {"edgetruth.render.dataset.spec", "edgetruth.locate.registry", "edgetruth.evaluate.main_job",
            "edgetruth.cli.commands.run"} <= set(graph)


def test_imports_go_one_way(graph):
    bad = [f"{m} ({_layer(m)}) imports {t} ({_layer(t)})" for m, ts in graph.items() for t in sorted(ts)
           if _layer(t) not in ALLOWED[_layer(m)]]
    assert not bad, "\n".join(bad)


def test_only_the_cli_imports_the_commands(graph):
    bad = [f"{m} imports {t}" for m, ts in graph.items() for t in ts
           if t.startswith("edgetruth.cli.commands") and not m.startswith("edgetruth.cli")]
    assert not bad, bad


def test_no_import_cycles(graph):
    """Tarjan's strongly connected components; a package importing its own submodules (to re-export
    them) is not a cycle unless a submodule imports the package back."""
    index, low, stack, on, sccs, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                sccs.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    assert not sccs, "import cycles:\n" + "\n".join(" <-> ".join(c) for c in sccs)


#: evaluate's study packages: rooms side by side on the evaluate floor.  Each imports its own modules and the
#: floor below (evaluate's shared modules: design tables, target finding, statistics, ...), never another study,
#: nor a module above the studies (one that imports a study: the main job, threshold calibration), which would be
#: a sideways import through the back door.  What combines two studies sits above both (or in the CLI).
STUDIES = ("edgetruth.evaluate.points", "edgetruth.evaluate.ranging", "edgetruth.evaluate.board",
           "edgetruth.evaluate.synthetic")


def _study(m: str) -> str | None:
    return next((s for s in STUDIES if m == s or m.startswith(s + ".")), None)


def _above_the_studies(graph) -> set:
    """evaluate's modules outside the studies that import a study, directly or through another such module."""
    upper: set = set()
    while True:
        more = {m for m, ts in graph.items() if m.startswith("edgetruth.evaluate") and _study(m) is None
                and m not in upper and any(_study(t) or t in upper for t in ts)}
        if not more:
            return upper
        upper |= more


def test_studies_do_not_import_each_other(graph):
    assert {"edgetruth.evaluate.main_job", "edgetruth.evaluate.threshold_calibration"} <= _above_the_studies(graph)
    upper = _above_the_studies(graph)
    bad = [f"{m} imports {t}" + (" (above the studies)" if t in upper else "") for m, ts in graph.items()
           if _study(m) for t in sorted(ts) if (_study(t) and _study(t) != _study(m)) or t in upper]
    assert not bad, "sideways imports between study packages:\n" + "\n".join(bad)


def test_the_sideways_check_finds_a_sideways_import():
    """The check itself can fail: a study importing another, directly or through a module above both."""
    base = {"edgetruth.evaluate.main_job": {"edgetruth.evaluate.points.scores"},
            "edgetruth.evaluate.threshold_calibration": {"edgetruth.evaluate.points.scores"},
            "edgetruth.evaluate.points.scores": {"edgetruth.evaluate.design"}, "edgetruth.evaluate.design": set()}
    test_studies_do_not_import_each_other(base)  # the floor and the top: allowed
    with pytest.raises(AssertionError, match="evaluate.points.report imports edgetruth.evaluate.ranging.images"):
        test_studies_do_not_import_each_other(
            {**base, "edgetruth.evaluate.points.report": {"edgetruth.evaluate.ranging.images"}})
    with pytest.raises(AssertionError, match=r"ranging.main imports edgetruth.evaluate.threshold_calibration \(above"):
        test_studies_do_not_import_each_other(
            {**base, "edgetruth.evaluate.ranging.main": {"edgetruth.evaluate.threshold_calibration"}})


#: the board study's rooms, one per stage, bottom to top: each imports the rooms below it and the board's shared
#: modules (model, reference, inputs), never a room above it, the study that drives them, or the twin
BOARD = "edgetruth.evaluate.board"
BOARD_ROOMS = ("sides", "detect", "calibrate", "measure", "tone", "report")
BOARD_SHARED = ("model", "reference", "inputs")


def _board_room(m: str) -> str | None:
    if not m.startswith(BOARD + "."):
        return None
    part = m.split(".")[3]
    return part if part in BOARD_ROOMS or part in BOARD_SHARED else ("twin" if part == "twin" else "study")


def test_board_rooms_import_downwards(graph):
    rooms = {_board_room(m) for m in graph}
    assert set(BOARD_ROOMS) <= rooms
    bad = []
    for m, ts in graph.items():
        a = _board_room(m)
        if a not in BOARD_ROOMS:
            continue
        for t in sorted(ts):
            b = _board_room(t)
            if b is None or b == a or b in BOARD_SHARED:
                continue
            if b not in BOARD_ROOMS or BOARD_ROOMS.index(b) > BOARD_ROOMS.index(a):
                bad.append(f"{m} ({a}) imports {t} ({b})")
    assert not bad, "board rooms importing upwards:\n" + "\n".join(bad)


def test_the_board_check_finds_an_upward_import():
    ok = {f"{BOARD}.measure.rows": {f"{BOARD}.sides.lines", f"{BOARD}.model"}}
    test_board_rooms_import_downwards({**ok, **{f"{BOARD}.{r}.x": set() for r in BOARD_ROOMS}})
    with pytest.raises(AssertionError, match=r"board.sides.lines \(sides\) imports edgetruth.evaluate.board.tone.fit"):
        test_board_rooms_import_downwards({**ok, **{f"{BOARD}.{r}.x": set() for r in BOARD_ROOMS},
                                           f"{BOARD}.sides.lines": {f"{BOARD}.tone.fit"}})


def test_the_graph_check_finds_a_cycle():
    """The check itself can fail: a two-module cycle is reported."""
    with pytest.raises(AssertionError, match="a <-> b"):
        test_no_import_cycles({"a": {"b"}, "b": {"a"}, "c": {"a"}})


#: render's stages and what each may import (besides the ground floor): spec -> scene -> camera
#: (optics) -> sensor -> files, one way. The floor is render's own shared modules; the tools on top
#: (bench, mc_noise, testing, the package itself) may import any stage.
RENDER_FLOOR = {"edgetruth.render.schema", "edgetruth.render.variants", "edgetruth.render.edge_truth"}
RENDER_ALLOWED = {"floor": {"floor"}, "synthetic": {"floor", "synthetic"}, "optics": {"floor", "optics"},
                  "sensor": {"floor", "sensor"}, "scene": {"floor", "optics", "scene"},
                  "dataset": {"floor", "optics", "scene", "sensor", "dataset"},
                  "tools": {"floor", "synthetic", "optics", "scene", "sensor", "dataset", "tools"}}


def _render_stage(m: str) -> str:
    if m in RENDER_FLOOR:
        return "floor"
    stage = m.split(".")[2] if m.count(".") >= 2 else "tools"
    return stage if stage in RENDER_ALLOWED and stage != "floor" else "tools"


def test_render_stages_import_one_way(graph):
    stages = {_render_stage(m) for m in graph if m.startswith("edgetruth.render.")}
    assert {"synthetic", "optics", "scene", "sensor", "dataset", "floor", "tools"} <= stages
    bad = [f"{m} ({_render_stage(m)}) imports {t} ({_render_stage(t)})" for m, ts in graph.items()
           if m.startswith("edgetruth.render") for t in sorted(ts)
           if t.startswith("edgetruth.render") and _render_stage(t) not in RENDER_ALLOWED[_render_stage(m)]]
    assert not bad, "\n".join(bad)


def test_the_twin_sits_over_the_board_study(graph):
    """``evaluate.board.twin`` (derive, study, report and their measurements) builds on the board study; nothing
    of the board study, and nothing outside the CLI, imports the twin."""
    twin = "edgetruth.evaluate.board.twin"
    assert {f"{twin}.derive", f"{twin}.study", f"{twin}.report"} <= set(graph)
    bad = [f"{m} imports {t}" for m, ts in graph.items() for t in sorted(ts)
           if t.startswith(twin) and not (m.startswith(twin) or m.startswith("edgetruth.cli"))]
    assert not bad, "\n".join(bad)
