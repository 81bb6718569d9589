"""``edgetruth evaluate DATASET...``: the ranging and edge-level evaluation of rendered datasets.

For datasets rendered with your own specs (``edgetruth render MYSPEC.toml -o DIR``):
every target image is undistorted with the calibration, its target found, its boundary
refined by every method and ranged (Z = fx S / l); the report compares each with the
exact ground truth, as ``edgetruth run`` does for the shipped study.
"""
from __future__ import annotations

import argparse
from pathlib import Path


def register(sub) -> None:
    from edgetruth.cli import add_backend_options, add_plugin_option, add_progress_option

    p = sub.add_parser("evaluate", help="rank every method on datasets you rendered (ranging + edge error report)",
                       description=__doc__.split("\n\n")[1], formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("datasets", nargs="+", metavar="DATASET", type=Path,
                   help="dataset directories (the -o of `edgetruth render`)")
    p.add_argument("--calibration", metavar="FILE|DIR", default=None,
                   help="calibration.json of an earlier run, or a dataset of checkerboard renders to calibrate from "
                        "(default: the checkerboards among the DATASETs)")
    p.add_argument("--methods", default=None, help="comma-separated method ids (default: all, plug-ins included)")
    p.add_argument("--thresholds", default=None, metavar="FILE",
                   help="entropy thresholds for the dynamic methods (default: the shipped ones)")
    p.add_argument("--camera-thresholds", default=None, metavar="FILE",
                   help="thresholds calibrated for the camera (calibrate-thresholds --dataset on renders disjoint "
                        "from these): the dynamic methods also run with them, as '(camera τ)' rows")
    p.add_argument("-o", "--output", metavar="DIR", type=Path, default=None,
                   help="report directory (default ./runs/<UTC stamp>-evaluate)")
    add_backend_options(p, "worker processes (default: the cores)")
    add_plugin_option(p)
    add_progress_option(p)
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from edgetruth import console
    from edgetruth.backends import check_backend_args, default_workers
    from edgetruth.cli import method_list
    from edgetruth.errors import InputError
    from edgetruth.evaluate import method_order as mo
    from edgetruth.evaluate.calibration import calibrate, load_calibration
    from edgetruth.evaluate.pipeline import check_run_dir, evaluate_datasets, prepare_run_dir, utc_stamp
    from edgetruth.fileio import write_json
    from edgetruth.render.reader import open_dataset
    from edgetruth.resources import default_runs_dir

    check_backend_args(args.backend, args.workers, args.address)
    methods = method_list(args.methods)
    mo.thresholds_in_use(args.thresholds)
    if args.camera_thresholds is not None:
        mo.thresholds_in_use(args.camera_thresholds)
    sets = [open_dataset(d) for d in args.datasets]  # each must be a dataset
    if not any(ds.targets() for ds in sets):
        raise InputError(f"{' '.join(map(str, args.datasets))}: no target images to evaluate; render a spec with "
                         "kind = \"target\" groups")
    if args.calibration is None and not any(ds.checkerboards() for ds in sets):
        raise InputError("no checkerboard images among the datasets; pass --calibration FILE|DIR "
                         "(a calibration.json, or a dataset of checkerboard renders)")
    if args.calibration is not None:
        from edgetruth.fileio import check_input_file

        p = Path(args.calibration)
        if not p.is_dir():
            check_input_file(p, "calibration JSON")
    out = check_run_dir(args.output or default_runs_dir() / f"{utc_stamp()}-evaluate", "evaluate")
    if args.calibration is not None:
        cal = load_calibration(args.calibration, progress=not args.no_progress)
        source = str(args.calibration)
    else:
        boards = [s for ds in sets for s in ds.checkerboards()]
        b = boards[0].truth["checkerboard"]
        cal = calibrate([(s.name, s.image.astype(float)) for s in boards], tuple(b["pattern_size"]),
                        float(b["square_m"]), [s.truth for s in boards],
                        progress=lambda it: console.track(it, "calibrate", "board", enabled=not args.no_progress))
        source = f"{len(boards)} checkerboards of the datasets"
    out = prepare_run_dir(out, "evaluate", {"datasets": [str(d) for d in args.datasets],
                                            "calibration": args.calibration, "methods": methods,
                                            "thresholds": args.thresholds,
                                            "camera_thresholds": args.camera_thresholds})
    write_json(out / "calibration.json", cal.to_dict())
    header = {"datasets": ", ".join(f"{d} ({ds.spec_name})" for d, ds in zip(args.datasets, sets)),
              "calibration": source, "UTC": utc_stamp()}
    report = evaluate_datasets(args.datasets, cal, out, methods=methods, thresholds=args.thresholds,
                               progress=not args.no_progress, backend=args.backend,
                               workers=args.workers or default_workers(), address=args.address, header=header,
                               camera_thresholds=args.camera_thresholds)
    console.say(f"evaluate: report {report}")
    return 0
