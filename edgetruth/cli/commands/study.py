"""``edgetruth study synthetic``: the seed's synthetic study on analytic ground truth."""
from __future__ import annotations

import datetime as _dt
from pathlib import Path


def register(sub) -> None:
    from edgetruth.cli import add_backend_options, add_plugin_option, add_progress_option, positive_int

    p = sub.add_parser("study", help="run a study and write its report",
                       description="The seed's synthetic study (Tables 3-8, Figures 4-7) on analytic edges "
                                   "with exact ground truth; re-running into the same directory resumes.")
    p.add_argument("kind", choices=["synthetic"], help="which study")
    p.add_argument("--preset", choices=["quick", "full"], default="quick",
                   help="quick: 24 images per scenario (~1 min); full: 200 per scenario (the seed's scale)")
    p.add_argument("--images-per-scenario", type=positive_int, default=None, help="override the preset's image count")
    p.add_argument("--methods", default=None, help="comma-separated method ids (default: all, plug-ins included)")
    p.add_argument("--thresholds", default=None, metavar="FILE",
                   help="entropy thresholds for the dynamic methods (default: the shipped ones)")
    p.add_argument("-o", "--output", default=None, help="output directory (default ./runs/<UTC stamp>-synthetic); "
                   "re-running into the same directory resumes")
    add_backend_options(p, "local worker processes (default 1 = in-process; timings are cleanest with 1)")
    add_plugin_option(p)
    add_progress_option(p)
    p.set_defaults(handler=run)


def run(args) -> int:
    from edgetruth import console
    from edgetruth.cli import method_list
    from edgetruth.evaluate.synthetic_study import run_synthetic_study
    from edgetruth.resources import default_runs_dir

    out = Path(args.output) if args.output else default_runs_dir() / (
        _dt.datetime.now(_dt.timezone.utc).strftime("%Y%m%d-%H%M%S") + "-synthetic")
    report = run_synthetic_study(out, args.preset, method_list(args.methods), progress=not args.no_progress,
                                 images_per_scenario=args.images_per_scenario, backend=args.backend,
                                 workers=args.workers or 1, address=args.address, thresholds=args.thresholds)
    console.say(f"report: {report}")
    return 0
