"""``edgetruth bench --against REV``: this working tree against a baseline commit, side by side.

Machines differ by ~2x in speed (the same ``make run``: 166 s on one, 306 s on another), so speed
figures are ratios to a baseline measured on one machine in one run.  This module checks the
baseline out beside the working tree (``git worktree add --detach`` into a temporary folder, removed
afterwards), and runs both with the same interpreter and venv, alternating which goes first:

- the main job, ``edgetruth run --study quick`` (``--limit``/``--skip-synthetic`` shrink it): its own
  stage times (the ``run: report ... s in all: render_s ...`` line both versions print) and its wall
  time, from a cold start like a fresh clone's: both sides run from fresh copies of their trees (the
  baseline's worktree, and the working tree's tracked and untracked-not-ignored files), whose
  ``__pycache__`` folders are removed before every run, and every run gets an empty numba cache
  (``NUMBA_CACHE_DIR``).  The venv's packages keep the bytecode ``pip install`` compiled: that is the
  venv's set-up, which the issue's figure leaves out (an empty ``PYTHONPYCACHEPREFIX``, as before stop
  29, also made numpy, scipy, matplotlib and Mitsuba's Python cold, and where ``PYTHONDONTWRITEBYTECODE``
  is set it recompiled them in every process: ~3.5 s of one core per process);
- the full study's rendering: a few ``study`` images (G1_T1 at the nearest, the middle and the
  farthest distance, each its own radiance render) in a fresh process, seconds per image and the
  per-stage split of ``render_spec``'s timings.

Each side imports its own code: a ``sitecustomize`` on ``PYTHONPATH`` (so that the spawned worker
processes inherit it) points the ``edgetruth`` package at that tree's folders (``edgetruth.render``
= ``render/``, ...: the layout of ``pyproject.toml``) ahead of the venv's editable install.  Every
printed figure is a median over ``--repeats`` and a ratio baseline / working tree (> 1: the working
tree is faster).  Timing noise on a shared machine is large: read the ratios, not the seconds.
"""
from __future__ import annotations

import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import edgetruth
from edgetruth.errors import InputError


#: ``run: report PATH (T s in all: render_s 1.0, calibrate_s 2.0, ...)`` -- the main job's last line.
_RUN_LINE = re.compile(r"run: report .*\(([\d.]+) s in all: ([^)]*)\)")
_JSON_TAG = "BENCH_JSON "

_SITECUSTOMIZE = '''\
# written by `edgetruth bench --against`: import edgetruth from {root!r} (its own folders)
import sys
from importlib.machinery import PathFinder

_ROOT = {root!r}


class _EdgetruthTree:
    """``edgetruth`` from the bench's tree; its sub-packages from ``edgetruth/`` and the top-level folders."""

    @classmethod
    def find_spec(cls, name, path=None, target=None):
        if name != "edgetruth":
            return None
        spec = PathFinder.find_spec(name, [_ROOT])
        if spec is not None:
            spec.submodule_search_locations = [_ROOT + "/edgetruth", _ROOT]
        return spec


sys.meta_path.insert(0, _EdgetruthTree)
'''

_RENDER_SNIPPET = '''\
import json, sys, time
t0 = time.perf_counter()
try:  # render/ has one sub-package per stage since stop 24; a baseline before it has flat modules
    from edgetruth.render.dataset.driver import render_spec
    from edgetruth.render.dataset.spec import load_spec
except ModuleNotFoundError:
    from edgetruth.render.driver import render_spec
    from edgetruth.render.spec import load_spec
spec = load_spec(sys.argv[3])
names = [g.name for g in spec.groups if g.kind == "target"]
group = "G1_T1" if "G1_T1" in names else names[0]  # the study's base cell
jobs = sorted((j for j in spec.jobs if j.group == group), key=lambda j: j.distance_cm)
n = int(sys.argv[2])
pick = [jobs[round(k * (len(jobs) - 1) / max(1, n - 1))] for k in range(n)]
t = {}
t1 = time.perf_counter()
render_spec(spec, sys.argv[1], progress=False, only=[j.index for j in pick], timings=t, announce=lambda s: None)
t2 = time.perf_counter()
import edgetruth.render
print("BENCH_JSON " + json.dumps({"names": [j.name for j in pick], "distances_cm": [j.distance_cm for j in pick],
      "setup_s": t1 - t0, "render_call_s": t2 - t1, "timings": t, "code": edgetruth.render.__file__}, default=str))
'''


def repo_root() -> Path:
    """The checkout this ``edgetruth`` runs from (its ``pyproject.toml`` and ``.git``); InputError otherwise."""
    root = Path(edgetruth.__file__).resolve().parent.parent
    if not (root / "pyproject.toml").is_file():
        raise InputError("bench --against: edgetruth is not running from a git checkout (an installed wheel has "
                         "no history to compare with); run it from a clone, e.g. `.venv/bin/edgetruth bench "
                         "--against 70b0339` there")
    r = subprocess.run(["git", "-C", str(root), "rev-parse", "--show-toplevel"], capture_output=True, text=True)
    if r.returncode != 0:
        raise InputError(f"bench --against: {root} is not a git checkout ({r.stderr.strip()}); run it from a clone")
    return Path(r.stdout.strip())


def resolve_commit(root: Path, rev: str) -> str:
    """The full commit id of ``rev``; a revision git does not know: InputError."""
    r = subprocess.run(["git", "-C", str(root), "rev-parse", "--verify", "--quiet", f"{rev}^{{commit}}"],
                       capture_output=True, text=True)
    if r.returncode != 0:
        raise InputError(f"--against {rev}: not a commit of {root}; give a commit id, tag or branch (git log)")
    return r.stdout.strip()


def add_worktree(root: Path, rev: str, dest: Path) -> str:
    """``git worktree add --detach dest rev``; returns the full commit id."""
    commit = resolve_commit(root, rev)
    subprocess.run(["git", "-C", str(root), "worktree", "add", "--detach", "--quiet", str(dest), commit],
                   check=True, capture_output=True)
    return commit


def remove_worktree(root: Path, dest: Path) -> None:
    subprocess.run(["git", "-C", str(root), "worktree", "remove", "--force", str(dest)], capture_output=True)
    subprocess.run(["git", "-C", str(root), "worktree", "prune"], capture_output=True)


def copy_working_tree(root: Path, dest: Path) -> None:
    """The files of the checkout ``root`` a fresh clone of its state would hold -- tracked (as they are now,
    uncommitted changes included) and untracked but not ignored -- copied into ``dest``: no bytecode, no
    numba cache, no build outputs."""
    r = subprocess.run(["git", "-C", str(root), "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
                       capture_output=True, check=True)
    for rel in sorted({p for p in r.stdout.decode().split("\0") if p}):
        src = root / rel
        if src.is_file():  # a tracked file deleted in the working tree is not copied
            (dest / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / rel)


def drop_bytecode(tree: Path) -> None:
    """Remove every ``__pycache__`` folder under ``tree``: the next run compiles the tree's modules afresh."""
    for p in sorted(Path(tree).rglob("__pycache__"), reverse=True):
        shutil.rmtree(p, ignore_errors=True)


def side_env(tree: Path, scratch: Path) -> dict:
    """The environment that makes a Python process (and its spawned workers) import edgetruth from
    ``tree``, with an empty numba cache under ``scratch`` (the tree's bytecode: ``drop_bytecode``)."""
    site = scratch / "site"
    site.mkdir(parents=True, exist_ok=True)
    (site / "sitecustomize.py").write_text(_SITECUSTOMIZE.format(root=str(Path(tree).resolve())))
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(site)] + [p for p in [env.get("PYTHONPATH")] if p])
    env["NUMBA_CACHE_DIR"] = str(scratch / "numba")
    env.pop("PYTHONPYCACHEPREFIX", None)  # the venv's packages keep their bytecode (see the module's docstring)
    return env


def parse_run_line(text: str) -> dict:
    """{"total_s": T, "render_s": ..., ...} from the main job's last line (the last match in ``text``)."""
    found = _RUN_LINE.findall(text)
    if not found:
        raise RuntimeError("no 'run: report ... s in all: ...' line in the output:\n" + text[-2000:])
    total, parts = found[-1]
    out = {"total_s": float(total)}
    for part in parts.split(","):
        k, _, v = part.strip().rpartition(" ")
        if k:
            out[k] = float(v)
    return out


def _run(cmd: list[str], env: dict, cwd: Path) -> tuple[float, str]:
    t0 = time.perf_counter()
    r = subprocess.run(cmd, env=env, cwd=str(cwd), capture_output=True, text=True)
    wall = time.perf_counter() - t0
    text = r.stdout + r.stderr
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} exited {r.returncode}:\n{text[-3000:]}")
    return wall, text


def main_job_once(tree: Path, scratch: Path, run_args: list[str], study: str = "quick") -> dict:
    env = side_env(tree, scratch)
    out = scratch / "run"
    wall, text = _run([sys.executable, "-m", "edgetruth", "run", "--study", study, "--no-progress", "-o", str(out),
                       *run_args], env, scratch)
    res = parse_run_line(text)
    res["wall_s"] = wall
    return res


def study_render_once(tree: Path, scratch: Path, n_images: int, spec: str = "study") -> dict:
    """``n_images`` of ``spec``'s base cell (G1_T1, else its first target group), nearest to farthest."""
    env = side_env(tree, scratch)
    wall, text = _run([sys.executable, "-c", _RENDER_SNIPPET, str(scratch / "study"), str(n_images), str(spec)], env,
                      scratch)
    line = [ln for ln in text.splitlines() if ln.startswith(_JSON_TAG)][-1]
    res = json.loads(line[len(_JSON_TAG):])
    if not str(Path(res["code"]).resolve()).startswith(str(Path(tree).resolve())):
        raise RuntimeError(f"bench: the render ran {res['code']}, not the code of {tree}")
    t = res["timings"]
    n = max(1, int(t.get("n_rendered", 0)))
    out = {"wall_s": wall, "s_per_image": res["render_call_s"] / n, "mi_render_s_per_image": t.get("render_s", 0) / n,
           "setup_s": res["setup_s"], "names": res["names"], "distances_cm": res["distances_cm"]}
    for k, v in (t.get("stage_s") or {}).items():
        out[f"stage {k} s_per_image"] = v / n
    return out


def _median(values):
    vals = [v for v in values if v is not None]
    return statistics.median(vals) if vals else float("nan")


def table_lines(title: str, base: list[dict], work: list[dict], keys: list[str]) -> list[str]:
    """One line per key: baseline and working-tree medians and their ratio."""
    lines = [title, f"  {'figure':<34} {'baseline':>10} {'working':>10} {'ratio':>8}"]
    num = lambda v: f"{v:>10.2f}" if v == v else f"{'-':>10}"  # noqa: E731 -- a stage one side lacks: '-'
    for k in keys:
        b, w = _median([r.get(k) for r in base]), _median([r.get(k) for r in work])
        ratio = f"{b / w:>7.2f}x" if w and w == w and b == b else f"{'-':>8}"
        lines.append(f"  {k:<34} {num(b)} {num(w)} {ratio}")
    return lines


def run_against(rev: str, repeats: int = 1, run_args: list[str] | None = None, study_images: int = 3,
                parts=("run", "render"), keep: Path | None = None, say=print, spec: str = "study") -> dict:
    """Time the working tree against ``rev`` (see the module's docstring); returns every measurement."""
    root = repo_root()
    run_args = list(run_args or [])
    resolve_commit(root, rev)  # a bad revision fails before anything is created
    tmp = Path(tempfile.mkdtemp(prefix="edgetruth-bench-against-", dir=keep))
    base_tree, work_tree = tmp / "baseline", tmp / "working"
    try:
        commit = add_worktree(root, rev, base_tree)
        copy_working_tree(root, work_tree)
    except BaseException:
        remove_worktree(root, base_tree)
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    head = subprocess.run(["git", "-C", str(root), "log", "-1", "--format=%h %s"], capture_output=True,
                          text=True).stdout.strip()
    dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
                           capture_output=True, text=True).stdout.strip()
    say(f"bench --against: baseline {commit[:12]} at {base_tree}; working tree {root} (HEAD {head[:60]}"
        + (", with uncommitted changes" if dirty else "") + f", copied to {work_tree}); {repeats} repeat(s), "
        "alternating order; cold numba cache and no bytecode of either tree per run")
    res: dict = {"baseline": commit, "working_tree": str(root), "run": {"baseline": [], "working": []},
                 "render": {"baseline": [], "working": []}}
    sides = {"baseline": base_tree, "working": work_tree}
    try:
        for k in range(repeats):
            order = ("baseline", "working") if k % 2 == 0 else ("working", "baseline")
            for part in parts:
                for side in order:
                    scratch = tmp / f"{part}-{side}-{k}"
                    drop_bytecode(sides[side])
                    if part == "run":
                        r = main_job_once(sides[side], scratch, run_args)
                        say(f"bench --against: run #{k + 1} {side}: {r['total_s']:.1f} s in all ("
                            + ", ".join(f"{a} {b:.1f}" for a, b in r.items() if a not in ("total_s", "wall_s")) + ")")
                    else:
                        r = study_render_once(sides[side], scratch, study_images, spec)
                        say(f"bench --against: study render #{k + 1} {side}: {r['s_per_image']:.2f} s/image "
                            f"({', '.join(r['names'])})")
                    res[part][side].append(r)
                    shutil.rmtree(scratch, ignore_errors=True)
    finally:
        remove_worktree(root, base_tree)
        if keep is None:
            shutil.rmtree(tmp, ignore_errors=True)
    lines = []
    if res["run"]["working"]:
        keys = [k for k in res["run"]["working"][0] if k != "wall_s"] + ["wall_s"]
        desc = " ".join(["edgetruth run --study quick", *run_args])
        lines += table_lines(f"main job ({desc}), seconds, medians of {repeats}; ratio = baseline / working",
                             res["run"]["baseline"], res["run"]["working"], keys)
    if res["render"]["working"]:
        w0 = res["render"]["working"][0]
        keys = ["s_per_image", "mi_render_s_per_image"] + sorted(k for k in w0 if k.startswith("stage "))
        lines += table_lines(f"full-study render (study, {len(w0['names'])} G1_T1 images at "
                             f"{', '.join(f'{d:.0f}' for d in w0['distances_cm'])} cm, one process each), seconds "
                             f"per image, medians of {repeats}; ratio = baseline / working",
                             res["render"]["baseline"], res["render"]["working"], keys)
    res["lines"] = lines
    return res
