"""``edgetruth study synthetic``: the seed's synthetic study on analytic ground truth."""
from __future__ import annotations

import datetime as _dt
from pathlib import Path


def register(sub) -> None:
    p = sub.add_parser("study", help="run a study and write its report")
    p.add_argument("kind", choices=["synthetic"], help="which study")
    p.add_argument("--preset", choices=["quick", "full"], default="quick",
                   help="quick: 24 images per scenario (~1 min); full: 200 per scenario (the seed's scale)")
    p.add_argument("--images-per-scenario", type=int, default=None, help="override the preset's image count")
    p.add_argument("--methods", default=None, help="comma-separated method ids (default: all)")
    p.add_argument("-o", "--output", default=None, help="output directory (default runs/<UTC stamp>-synthetic); "
                   "re-running into the same directory resumes")
    p.add_argument("--backend", choices=["local", "ray"], default="local",
                   help="where the image blocks run (default: this process)")
    p.add_argument("-j", "--workers", type=int, default=1,
                   help="local worker processes (1 = in-process; timings are cleanest with 1)")
    p.add_argument("--address", default=None, help="Ray cluster address (default: a local Ray instance)")
    p.add_argument("--no-progress", action="store_true")
    p.set_defaults(handler=run)


def run(args) -> int:
    from edgetruth.paths import RUNS_DIR
    from evaluate.synthetic_study import run_synthetic_study

    out = Path(args.output) if args.output else RUNS_DIR / (
        _dt.datetime.now(_dt.timezone.utc).strftime("%Y%m%d-%H%M%S") + "-synthetic")
    methods = [m.strip() for m in args.methods.split(",")] if args.methods else None
    report = run_synthetic_study(out, args.preset, methods, progress=not args.no_progress,
                                 images_per_scenario=args.images_per_scenario, backend=args.backend,
                                 workers=args.workers, address=args.address)
    print(f"report: {report}")
    return 0
