"""Every object of the documented public API (the `::: name` lines of docs/reference/*.md) has a numpydoc
docstring with the sections the site renders: a summary; Parameters naming exactly the signature's
parameters; Returns for a function that returns something; Parameters or Attributes for a class."""
from __future__ import annotations

import re
import tempfile
from pathlib import Path

import pytest

from tests.support.tools import ROOT, load_tool

griffe = pytest.importorskip("griffe", reason="the docs packages are in the test extra: pip install -e '.[test]'")


def directives() -> list[tuple[str, list[str] | None]]:
    """(object, the members its page lists, or None: every public one) for each ``::: name`` of the reference."""
    out = []
    for page in sorted((ROOT / "docs" / "reference").glob("*.md")):
        for m in re.finditer(r"^::: ([\w.]+)\n((?:    .*\n)*)", page.read_text(), flags=re.M):
            listed = re.search(r"members: \[([^\]]*)\]", m.group(2))
            out.append((m.group(1), [x.strip() for x in listed.group(1).split(",")] if listed else None))
    return out


def documented() -> list[str]:
    return [name for name, _ in directives()]


def load_package():
    """The package as griffe reads it for the site, laid out in a folder of this process's own (the docs
    build's build/apisrc may be rebuilt by another test worker meanwhile)."""
    hooks = load_tool("tools/docs_hooks.py", "docs_hooks")
    src = hooks.build_api_tree(out=Path(tempfile.mkdtemp(prefix="edgetruth_apisrc_")) / "apisrc")
    return griffe.load("edgetruth", search_paths=[str(src)], docstring_parser="numpy", resolve_aliases=True,
                       try_relative_path=False)


@pytest.fixture(scope="module")
def package():
    return load_package()


def sections(obj) -> dict:
    return {s.kind.value: s for s in obj.docstring.parse("numpy")}


def signature_names(fn) -> list[str]:
    out = []
    for p in fn.parameters:
        if p.name in ("self", "cls"):
            continue
        out.append(("**" if p.kind.value == "variadic keyword" else "*" if p.kind.value == "variadic positional"
                    else "") + p.name)
    return out


def test_the_reference_documents_the_public_api():
    names = documented()
    for must in ("edgetruth.locate.locate", "edgetruth.locate.refine", "edgetruth.locate.candidates",
                 "edgetruth.locate.register", "edgetruth.locate.Refinement", "edgetruth.locate.METHODS",
                 "edgetruth.render.open_dataset", "edgetruth.render.Sample", "edgetruth.render.load_spec",
                 "edgetruth.render.synthetic.scenarios.synthetic_image"):
        assert must in names, must


def rendered_objects() -> list[str]:
    """Every documented object, and the public methods and properties of every documented class."""
    pkg = load_package()
    out = []
    for name, members in directives():
        out.append(name)
        obj = pkg[name.removeprefix("edgetruth.")]
        obj = obj.final_target if obj.is_alias else obj
        if obj.is_class:
            for mn, m in obj.members.items():
                m = m.final_target if m.is_alias else m
                if mn.startswith("_") or (members is not None and mn not in members):
                    continue
                if m.is_function or (m.is_attribute and "property" in m.labels):
                    out.append(f"{name}.{mn}")
    return out


@pytest.mark.parametrize("name", rendered_objects())
def test_public_object_has_a_numpydoc_docstring(package, name):
    obj = package[name.removeprefix("edgetruth.")]
    obj = obj.final_target if obj.is_alias else obj
    assert obj.docstring and obj.docstring.value.strip(), f"{name}: no docstring"
    sec = sections(obj)
    assert "text" in sec, f"{name}: no summary line"
    if obj.is_function and "property" not in obj.labels:
        params = signature_names(obj)
        if params:
            assert "parameters" in sec, f"{name}: no Parameters section (numpydoc)"
            got = [p.name for p in sec["parameters"].value]
            want = [p.lstrip("*") for p in params]
            assert [g.lstrip("*") for g in got] == want, f"{name}: Parameters {got} but the signature has {params}"
        returns = obj.returns
        if returns is not None and str(returns) not in ("None",):
            assert "returns" in sec or "yields" in sec, f"{name}: no Returns section"
    elif obj.is_class:
        assert "parameters" in sec or "attributes" in sec, f"{name}: neither Parameters nor Attributes"
