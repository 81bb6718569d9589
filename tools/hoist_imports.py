"""Hoist function-level imports to the module's top, and mark the ones that stay (``# lazy: <reason>``).

An import inside a function stays there only for a reason: a heavy or optional dependency (``HEAVY``; Mitsuba,
Dr.Jit, Ray, matplotlib, numba, ...), a module whose own top imports one, an import inside ``try`` (optional),
a name the tests patch on its module (the caller must look it up at call time), or a clash with a name of the
module.  Those get the trailing comment ``# lazy: <reason>`` (tests/package/test_lazy_imports.py checks every
function-level import carries one); every other import moves to the top (the import graph has no cycles, lazy
imports counted, so none appears).  Run from the repository root: ``python tools/hoist_imports.py DIR...``
(``--check``: list what it would do)."""
from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

FOLDERS = {"edgetruth": "edgetruth", "cli": "edgetruth.cli", "render": "edgetruth.render", "locate": "edgetruth.locate",
           "evaluate": "edgetruth.evaluate"}
#: libraries that stay lazy everywhere, and why
HEAVY = {"mitsuba": "Mitsuba is heavy", "drjit": "Dr.Jit is heavy", "ray": "Ray is heavy and optional",
         "matplotlib": "matplotlib is heavy", "numba": "numba is heavy (edgetruth.jit compiles on first call)",
         "torch": "torch is heavy", "OpenEXR": "OpenEXR is only needed to write EXR", "emva1288": "optional",
         "cloudpickle": "only when shipping plug-ins to workers", "tqdm": "tqdm only for progress bars",
         "scipy": "scipy is slow to import", "cv2": "OpenCV is slow to import", "tabulate": "only for tables",
         "multiprocessing": "multiprocessing only for pools", "concurrent": "only for pools"}
#: where importing the light floor itself must stay cheap (`import edgetruth.locate`, the render's spec reader):
#: scipy and cv2 stay lazy there; above (evaluate, the CLI's commands) they may go to the top
CHEAP = ("edgetruth", "render", "locate")
#: names the tests patch on their module: their callers look them up when they run
PATCHED = {"make_backend", "render_in_passes", "outward_offsets", "_detect", "calibrateCamera", "probe_uncached",
           "pip_libllvm_path", "POOL_FROM_IMAGES", "_optical_edge_block", "_writable", "set_state"}
MARK = re.compile(r"#\s*lazy:")


def modname(path: Path) -> str:
    parts = [p for p in path.with_suffix("").parts if p != "__init__"]
    return ".".join([FOLDERS[parts[0]], *parts[1:]])


def all_modules() -> dict[str, Path]:
    return {modname(f): f for top in FOLDERS for f in Path(top).rglob("*.py")}


def top_imports(tree: ast.Module) -> list:
    return [n for n in tree.body if isinstance(n, (ast.Import, ast.ImportFrom))]


def _targets(n, name: str, is_pkg: bool) -> list[str]:
    if isinstance(n, ast.Import):
        return [a.name for a in n.names]
    base = n.module or ""
    if n.level:
        pkg = name.split(".") if is_pkg else name.split(".")[:-1]
        pkg = pkg[:len(pkg) - n.level + 1]
        base = ".".join(pkg + ([base] if base else []))
    return [base] + [f"{base}.{a.name}" for a in n.names]


def heavy_modules(mods: dict[str, Path]) -> dict[str, str]:
    """Project module -> the heavy library its module-level imports load (transitively), for those that do."""
    direct: dict[str, set] = {}
    for m, f in mods.items():
        tree = ast.parse(f.read_text())
        ts = set()
        for n in top_imports(tree):
            ts |= set(_targets(n, m, f.name == "__init__.py"))
        direct[m] = ts
    out: dict[str, str] = {}
    changed = True
    while changed:
        changed = False
        for m, ts in direct.items():
            if m in out:
                continue
            for t in ts:
                root = t.split(".")[0]
                why = HEAVY.get(root) if root in HEAVY and root not in ("scipy", "cv2", "tqdm", "tabulate",
                                                                         "multiprocessing", "concurrent") else None
                if why is None and t in out:
                    why = out[t]
                if why:
                    out[m] = why
                    changed = True
                    break
    return out


def reason(n, name: str, folder: str, heavy: dict, in_try: bool, clash: bool, patched: bool) -> str | None:
    mods = [t for t in _targets(n, name, False)]
    roots = {t.split(".")[0] for t in mods}
    for r in roots:
        if r in HEAVY and (r not in ("scipy", "cv2", "tqdm") or folder in CHEAP):
            if r in ("scipy", "cv2") and folder not in CHEAP:
                continue
            return HEAVY[r]
    for t in mods:
        if t in heavy:
            return f"{t.rpartition('.')[2]} loads {heavy[t].split()[0]}"
    if in_try:
        return "optional"
    if patched:
        return "the tests patch it on its module"
    if clash:
        return "its name is taken in this module"
    return None


def process(path: Path, heavy: dict, check: bool) -> tuple[int, int]:
    text = path.read_text()
    tree = ast.parse(text)
    name = modname(path)
    folder = path.parts[0]
    lines = text.splitlines(keepends=True)
    top_names = {}
    for n in tree.body:
        if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            top_names[n.name] = ("def", n.name)
        elif isinstance(n, (ast.Assign, ast.AnnAssign)):
            for tg in (n.targets if isinstance(n, ast.Assign) else [n.target]):
                for x in ast.walk(tg):
                    if isinstance(x, ast.Name):
                        top_names[x.id] = ("assign", x.id)
        elif isinstance(n, (ast.Import, ast.ImportFrom)):
            for a in n.names:
                key = (a.asname or a.name).split(".")[0]
                top_names[key] = ("import", ast.unparse(n) if len(n.names) == 1 else _one(n, a))
    # function-level imports with their enclosing try (if any)
    found = []

    def walk(node, func, in_try):
        for field, value in ast.iter_fields(node):
            for child in value if isinstance(value, list) else [value]:
                if not isinstance(child, ast.AST):
                    continue
                t = in_try or (isinstance(node, ast.Try) and field in ("body", "handlers", "orelse"))
                if isinstance(child, (ast.Import, ast.ImportFrom)):
                    if func is not None:
                        found.append((child, t, func))
                    continue
                walk(child, child if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)) else func, t)

    walk(tree, None, False)
    hoist, marks, removed = [], {}, set()
    for n, in_try, func in found:
        if isinstance(n, ast.ImportFrom) and n.module == "__future__":
            continue
        last = lines[n.end_lineno - 1]
        if MARK.search(last):
            continue
        stmts = [_one(n, a) for a in n.names]
        bound = [(a.asname or a.name).split(".")[0] for a in n.names]
        clash = any(b in top_names and top_names[b] != ("import", s) for b, s in zip(bound, stmts)) \
            or bool(set(bound) & _rebound(func, n))
        patched = isinstance(n, ast.ImportFrom) and any(a.name in PATCHED for a in n.names)
        why = reason(n, name, folder, heavy, in_try, clash, patched)
        if why:
            marks[n.end_lineno] = why
        else:
            hoist += [s for s in stmts if not (s.split()[-1] in top_names and top_names[s.split()[-1]] == ("import", s))]
            removed |= set(range(n.lineno, n.end_lineno + 1))
    if check:
        for n, _, _ in found:
            if n.end_lineno in marks:
                print(f"{path}:{n.lineno}: lazy: {marks[n.end_lineno]}: {ast.unparse(n)}")
        return len(hoist), len(marks)
    out = []
    for i, line in enumerate(lines, 1):
        if i in removed:
            continue
        if i in marks:
            body, nl = line.rstrip("\n"), "\n" if line.endswith("\n") else ""
            line = (body + f"  # lazy: {marks[i]}" if "#" not in body else body + f"; lazy: {marks[i]}") + nl
        if not line.strip() and i - 1 in removed and out and out[-1].rstrip().endswith((":", '"""')):
            continue  # the blank line after a function's imports, now right after its def or docstring
        out.append(line)
    text2 = "".join(out)
    if hoist:
        text2 = _add_top(text2, sorted(set(hoist)), name)
    if text2 != text:
        path.write_text(text2)
    return len(hoist), len(marks)


def _rebound(func, imp) -> set:
    """Names ``func`` binds in its own scope other than by the import ``imp`` (parameters, assignments, loops,
    ``with``/``except`` targets, other imports, nested defs): hoisting an import of one would leave it local and
    unbound."""
    out = set()
    args = func.args
    for a in [*args.posonlyargs, *args.args, *args.kwonlyargs, args.vararg, args.kwarg]:
        if a is not None:
            out.add(a.arg)

    def visit(node):
        for child in ast.iter_child_nodes(node):
            if child is imp:
                continue
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                out.add(child.name)
                continue
            if isinstance(child, (ast.Lambda, ast.ListComp, ast.SetComp, ast.DictComp, ast.GeneratorExp)):
                continue
            if isinstance(child, ast.Name) and isinstance(child.ctx, (ast.Store, ast.Del)):
                out.add(child.id)
            elif isinstance(child, (ast.Import, ast.ImportFrom)):
                out.update((a.asname or a.name).split(".")[0] for a in child.names)
            elif isinstance(child, ast.ExceptHandler) and child.name:
                out.add(child.name)
            elif isinstance(child, (ast.Global, ast.Nonlocal)):
                out.update(child.names)
            visit(child)

    visit(func)
    return out


def _one(n, a) -> str:
    al = f" as {a.asname}" if a.asname else ""
    if isinstance(n, ast.Import):
        return f"import {a.name}{al}"
    return f"from {'.' * n.level}{n.module or ''} import {a.name}{al}"


def _group(mod: str) -> int:
    root = mod.split(".")[0]
    if mod == "__future__":
        return 0
    return 3 if root == "edgetruth" or mod.startswith(".") else (1 if root in sys.stdlib_module_names else 2)


def _from_stmt(mod: str, names: list[str], indent: str = "") -> str:
    stmt = f"{indent}from {mod} import {', '.join(names)}"
    if len(stmt) > 120:
        stmt = _wrap(f"{indent}from {mod} import (" + ", ".join(names) + ")", len(indent) + len(mod) + 13)
    return stmt + "\n"


def _add_top(text: str, stmts: list[str], name: str) -> str:
    """Add ``stmts`` to the module's top imports: names join an existing ``from X import`` of the same module,
    the rest go after the last import of their group (standard library, third party, the project)."""
    tree = ast.parse(text)
    first_code = next((n for n in tree.body if not isinstance(n, (ast.Import, ast.ImportFrom, ast.Expr))), None)
    before = [n for n in tree.body if isinstance(n, (ast.Import, ast.ImportFrom))
              and (first_code is None or n.lineno < first_code.lineno)]
    existing = set()
    for n in before:
        existing |= {_one(n, a) for a in n.names}
    lines = text.splitlines(keepends=True)
    add_from: dict[str, list[str]] = {}
    add_import: list[str] = []
    for s in stmts:
        if s in existing:
            continue
        if s.startswith("import "):
            add_import.append(s)
        else:
            add_from.setdefault(s.split()[1], []).append(s.split(" import ", 1)[1])
    replace: dict[int, tuple[int, str]] = {}  # first line -> (last line, new text)
    after: dict[int, list[str]] = {}  # line -> statements to insert after it
    for mod, names in add_from.items():
        node = next((n for n in before if isinstance(n, ast.ImportFrom) and
                     f"{'.' * n.level}{n.module or ''}" == mod), None)
        if node is not None:
            old = [a.name + (f" as {a.asname}" if a.asname else "") for a in node.names]
            tail = lines[node.end_lineno - 1].rstrip("\n")
            comment = "  " + tail[tail.index("#"):] if "#" in tail else ""
            allnames = sorted(set(old) | set(names), key=lambda x: (x.lower(), x))
            replace[node.lineno] = (node.end_lineno, _from_stmt(mod, allnames).rstrip("\n") + comment + "\n")
        else:
            add_import.append(("from", mod, sorted(set(names), key=lambda x: (x.lower(), x))))
    for item in add_import:
        mod = item[1] if isinstance(item, tuple) else item.split()[1]
        g = _group(mod)
        same = [n for n in before if _group(n.module if isinstance(n, ast.ImportFrom) and not n.level
                                           else ("." if isinstance(n, ast.ImportFrom) else n.names[0].name)) == g]
        stmt = _from_stmt(mod, item[2]) if isinstance(item, tuple) else item + "\n"
        if same:
            at, sep = same[-1].end_lineno, ""
        else:
            lower = [n for n in before if _group(n.module if isinstance(n, ast.ImportFrom) and not n.level
                                                 else ("." if isinstance(n, ast.ImportFrom) else n.names[0].name)) < g]
            doc = tree.body[0] if tree.body and isinstance(tree.body[0], ast.Expr) else None
            at = lower[-1].end_lineno if lower else (doc.end_lineno if doc else 0)
            sep = "\n"
        after.setdefault(at, []).append((sep, stmt))
    out, i = [], 1
    while i <= len(lines):
        if i in replace:
            end, new = replace[i]
            out.append(new)
            i = end + 1
            if end in after:
                i_after = end
            else:
                continue
            i_line = i_after
        else:
            out.append(lines[i - 1])
            i_line = i
            i += 1
        if i_line in after:
            items = after[i_line]
            seps = {sep for sep, _ in items}
            if "\n" in seps:
                out.append("\n")
            out += sorted(stmt for _, stmt in items)
    if 0 in after:
        out = ["\n"] + sorted(stmt for _, stmt in after[0]) + out
    return "".join(out)


def _wrap(stmt: str, indent: int) -> str:
    out, line = [], ""
    for part in re.split(r"(?<=,) ", stmt):
        if len(line) + len(part) + 1 > 118 and line:
            out.append(line.rstrip())
            line = " " * indent
        line += part + " "
    out.append(line.rstrip())
    return "\n".join(out)


def main(argv: list[str]) -> int:
    check = "--check" in argv
    dirs = [a for a in argv if not a.startswith("--")]
    heavy = heavy_modules(all_modules())
    tot_h = tot_m = 0
    for d in dirs:
        for f in sorted(Path(d).rglob("*.py")) if Path(d).is_dir() else [Path(d)]:
            h, m = process(f, heavy, check)
            tot_h += h
            tot_m += m
    print(f"hoisted {tot_h}, marked lazy {tot_m}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
