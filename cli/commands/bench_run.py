"""``edgetruth bench --only run`` without ``--against``: the working tree's main jobs timed as a fresh clone runs
them -- ``edgetruth run`` (``make run``) and ``edgetruth run --study full`` -- against the goals of issue 49
(<= 60 s and <= 180 s on 2 cores).

Each runs in a fresh process from a fresh copy of the working tree (tracked and untracked-not-ignored files) with
no bytecode and an empty numba cache (``bench_against``'s cold start).  The CPU seconds are the process's and its
workers' (``os.times`` of the waited-for children): on shared cores they say more than the wall time.
"""
from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

from edgetruth.cli.commands.bench_against import copy_working_tree, drop_bytecode, main_job_once, repo_root

#: wall-clock goals on 2 cores, s (issue 49)
GOALS_S = {"quick": 60.0, "full": 180.0}
WHAT = {"quick": "make run (edgetruth run)", "full": "edgetruth run --study full"}


def run_alone(studies=("quick", "full"), run_args=(), say=print) -> list[str]:
    """One cold run per study; printable lines: wall and CPU seconds, the goal, and the job's own stage times."""
    root = repo_root()
    tmp = Path(tempfile.mkdtemp(prefix="edgetruth-bench-run-"))
    tree = tmp / "working"
    lines = []
    try:
        copy_working_tree(root, tree)
        for study in studies:
            drop_bytecode(tree)
            scratch = tmp / study
            c0 = os.times()
            r = main_job_once(tree, scratch, list(run_args), study=study)
            c1 = os.times()
            cpu = (c1.children_user - c0.children_user) + (c1.children_system - c0.children_system)
            stages = ", ".join(f"{k} {v:.1f}" for k, v in r.items() if k not in ("total_s", "wall_s"))
            line = (f"run bench: {WHAT[study]}{' ' + ' '.join(run_args) if run_args else ''}, cold (fresh tree, no "
                    f"bytecode, empty numba cache, {os.cpu_count()} cores): {r['wall_s']:.1f} s wall, {cpu:.1f} s CPU "
                    f"(goal <= {GOALS_S[study]:.0f} s wall on 2 cores); its stages, s: {stages}")
            say(line)
            lines.append(line)
            shutil.rmtree(scratch, ignore_errors=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return lines
