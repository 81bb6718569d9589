"""``edgetruth run``: the whole study in one command (what ``make run`` calls).

render (specs) -> calibrate (Zhang, OpenCV) -> undistort -> find targets -> every method
-> ranging statistics -> ``report.md``; plus the synthetic study's quick preset, linked
from the report.  Output: ``./runs/<UTC stamp>/`` (or ``-o DIR``; an earlier run's
directory resumes it).

* ``--study quick`` (default): the ``quick`` spec (a paired design of target images +
  boards, half resolution) and ``thresholds_quick`` (renders of its own seeds on which the
  dynamic window's thresholds are calibrated for the camera): minutes on 2 cores.
* ``--study full``: ``calibration`` + ``study`` + ``thresholds`` at full resolution (an hour
  or more on a CPU); ``--limit N`` keeps N target images per group (spread over the distance
  range) and ``--calib-limit N`` N boards, for a tiny end-to-end check.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from edgetruth.cli import (add_plugin_option, add_progress_option, add_undistort_option, method_list, methods_help,
                           positive_int)
from edgetruth.evaluate.main_job import STUDIES, run_main_job


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "run", help="render, calibrate, locate (all methods), evaluate and report, in one go",
        description=__doc__.split("\n\n")[1], formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--study", choices=sorted(STUDIES), default="quick", help="which specs to run (default quick)")
    p.add_argument("-o", "--output", metavar="DIR", type=Path, default=None,
                   help="run directory (default ./runs/<UTC stamp>); an earlier run's directory resumes it")
    p.add_argument("--limit", metavar="N", type=positive_int, default=None,
                   help="at most N target images per group (evenly spread over distance)")
    p.add_argument("--calib-limit", metavar="N", type=int, default=None,
                   help="at most N calibration boards (>= 4)")
    p.add_argument("--methods", default=None, metavar="LIST", help=methods_help())
    p.add_argument("--thresholds", default=None, metavar="FILE",
                   help="entropy thresholds for the dynamic methods (default: the shipped ones)")
    p.add_argument("--camera-thresholds", default=None, metavar="FILE",
                   help="thresholds calibrated for the camera (calibrate-thresholds --dataset) to run the dynamic "
                        "methods with as well (default: calibrate them on the study's threshold renders)")
    p.add_argument("--variant", default=None, help="Mitsuba variant (default: best that works here)")
    p.add_argument("-j", "--workers", type=positive_int, default=None, metavar="N",
                   help="worker processes for the renders, the evaluation and the synthetic study (default: the cores)")
    p.add_argument("--skip-synthetic", action="store_true", help="do not run the synthetic study's quick preset")
    add_undistort_option(p)
    add_plugin_option(p)
    add_progress_option(p)
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    _, code = run_main_job(args.study, args.output, args.limit, args.calib_limit, method_list(args.methods),
                           args.variant, args.skip_synthetic, progress=not args.no_progress,
                           thresholds=args.thresholds, workers=args.workers,
                           camera_thresholds=args.camera_thresholds, undistort=args.undistort)
    return code
