"""``edgetruth bench``: the performance figures (refinement throughput, rendering speed), and with
``--against REV`` this working tree timed side by side with a baseline commit."""
from __future__ import annotations

import json

from edgetruth.cli import positive_int
from edgetruth.cli.commands.bench_against import run_against as against
from edgetruth.cli.commands.bench_run import run_alone
from edgetruth.cli.startup_bench import run_bench as startup_bench
from edgetruth.errors import InputError
from edgetruth.evaluate.bend_bench import run_bench as bend_bench
from edgetruth.fileio import atomic_write_text
from edgetruth.render.bench import default_mode_lines, run_bench as render_bench


def register(sub) -> None:
    p = sub.add_parser("bench", help="print performance figures (medians, ratios from one run)",
                       description="Start-up costs (edgetruth --version, import edgetruth.locate, edgetruth locate "
                                   "on 100 images in one call), refinement throughput per method on a 1280x1024 "
                                   "mosaic, the bent-board check of `edgetruth calibrate` (block against dense "
                                   "solver), and rendering speed per Mitsuba variant (what `make bench` runs).  "
                                   "With --against REV: the baseline commit REV checked out beside this working "
                                   "tree (a temporary git worktree) and both timed in one run, alternating: the "
                                   "main job `edgetruth run` per stage (cold caches, as a fresh clone) and the "
                                   "full study's rendering per image; medians and ratios baseline / working.")
    p.add_argument("--only", choices=["startup", "locate", "calibrate", "render", "modes", "run"], default=None,
                   help="run one part only (modes: a user's own spec with the default edge_mode against \"path\", "
                        "also part of render; run: make run and the full study, cold, against their goals; with "
                        "--against, the main job side by side)")
    p.add_argument("--repeats", type=positive_int, default=None,
                   help="timed repeats per figure (medians; default 7, with --against 1)")
    p.add_argument("--against", metavar="REV", default=None,
                   help="time this working tree against commit REV side by side (e.g. 70b0339, the issue-19 "
                        "baseline); needs a git checkout")
    p.add_argument("--limit", metavar="N", type=positive_int, default=None,
                   help="run: pass --limit N to the main jobs (N target images per group)")
    p.add_argument("--skip-synthetic", action="store_true",
                   help="run: pass --skip-synthetic to the main jobs")
    p.add_argument("--study-images", metavar="N", type=positive_int, default=3,
                   help="--against: full-study images rendered per side (default 3: near, middle, far)")
    p.add_argument("--json", metavar="FILE", default=None, help="--against: write every measurement to FILE")
    p.set_defaults(handler=run)


def run(args) -> int:
    if args.against is not None:
        return run_against(args)
    if args.only == "modes":
        print("\n".join(default_mode_lines()), flush=True)
        return 0
    repeats = args.repeats or 7
    if args.only in (None, "startup"):
        print("\n".join(startup_bench(repeats=repeats)), flush=True)
    if args.only in (None, "locate"):
        from edgetruth.evaluate.refine_bench import run_bench  # lazy: refine_bench loads numba

        print("\n".join(run_bench(repeats=repeats)), flush=True)
    if args.only in (None, "calibrate"):
        print("\n".join(bend_bench(repeats=min(repeats, 3))), flush=True)
    if args.only in (None, "render"):
        print("\n".join(render_bench()), flush=True)
    if args.only in (None, "run"):
        run_args = (["--limit", str(args.limit)] if args.limit else []) + (["--skip-synthetic"] if args.skip_synthetic
                                                                           else [])
        run_alone(run_args=run_args, say=lambda s: print(s, flush=True))
    return 0


def run_against(args) -> int:
    if args.only not in (None, "run", "render"):
        raise InputError(f"--only {args.only} with --against: choose run or render (or leave --only out for both)")
    parts = ("run", "render") if args.only is None else (args.only,)
    run_args = (["--limit", str(args.limit)] if args.limit else []) + (["--skip-synthetic"] if args.skip_synthetic
                                                                       else [])
    res = against(args.against, repeats=args.repeats or 1, run_args=run_args, study_images=args.study_images,
                  parts=parts, say=lambda s: print(s, flush=True))
    print("\n".join(res["lines"]), flush=True)
    if args.json:
        atomic_write_text(args.json, json.dumps({k: v for k, v in res.items() if k != "lines"}, indent=1,
                                                default=str) + "\n")
    return 0
