"""``edgetruth evaluate DATASET...``: the ranging and edge-level evaluation of rendered datasets;
``edgetruth evaluate --photos DIR --distances FILE.csv --calibration FILE|DIR``: ranging on real photos.

For datasets rendered with your own specs (``edgetruth render MYSPEC.toml -o DIR``):
every target image is undistorted with the calibration, its target found, its boundary
refined by every method and ranged (Z = fx S / l); the report compares each with the
exact ground truth, as ``edgetruth run`` does for the shipped study.  For real photos
(--photos), a CSV gives each photo's reference distance, target shape, size, group and
polarity (docs/formats.md, "Distances CSV for real photos"): the same chain and the same
ranging tables, paired tests and verdicts against those distances (no per-point tables:
a photo has no exact outline).
"""
from __future__ import annotations

import argparse
from pathlib import Path

from edgetruth import console
from edgetruth.backends import check_backend_args, default_workers
from edgetruth.cli import (add_backend_options, add_image_options, add_plugin_option, add_progress_option,
                           add_undistort_option, method_list, methods_help)
from edgetruth.errors import InputError
from edgetruth.evaluate import method_order as mo
from edgetruth.evaluate.calibration import calibrate, load_calibration
from edgetruth.evaluate.main_job import evaluate_datasets
from edgetruth.evaluate.ranging.focal_length import exif_fx
from edgetruth.evaluate.ranging.photos import (camera_without_board, check_photos, evaluate_photos, read_distances,
                                               resolve_references, unlisted_photos)
from edgetruth.evaluate.run_dir import check_run_dir, prepare_run_dir, utc_stamp
from edgetruth.evaluate.threshold_calibration import check_disjoint
from edgetruth.fileio import check_input_file, write_json
from edgetruth.render.dataset.reader import open_dataset
from edgetruth.resources import default_runs_dir


def register(sub) -> None:
    p = sub.add_parser("evaluate", help="rank every method on datasets you rendered (ranging + edge error report)",
                       description=__doc__.split("\n\n")[1], formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("datasets", nargs="*", metavar="DATASET", type=Path,
                   help="dataset directories (the -o of `edgetruth render`); or none, with --photos")
    p.add_argument("--photos", metavar="DIR", type=Path, default=None,
                   help="real photos instead of datasets: the folder holding them (with --distances and --calibration)")
    p.add_argument("--distances", metavar="FILE.csv", type=Path, default=None,
                   help="with --photos: one row per photo: image, distance_cm, size_m, shape, group[, height_m, "
                        "polarity] (docs/formats.md)")
    p.add_argument("--calibration", metavar="FILE|DIR", default=None,
                   help="calibration.json (of a run or `edgetruth calibrate`), or a dataset of checkerboard renders "
                        "to calibrate from (default: the checkerboards among the DATASETs; required with --photos)")
    p.add_argument("--methods", default=None, metavar="LIST", help=methods_help())
    p.add_argument("--thresholds", default=None, metavar="FILE",
                   help="entropy thresholds for the dynamic methods (default: the shipped ones)")
    p.add_argument("--camera-thresholds", default=None, metavar="FILE",
                   help="thresholds calibrated for the camera (calibrate-thresholds --dataset on renders disjoint "
                        "from these): the dynamic methods also run with them, as '(camera τ)' rows")
    p.add_argument("-o", "--output", metavar="DIR", type=Path, default=None,
                   help="report directory (default ./runs/<UTC stamp>-evaluate)")
    p.add_argument("--reference-photo", metavar="IMAGE[=DISTANCE_CM]", action="append", default=[],
                   help="with --photos, instead of (or with) --calibration: a photo at a known distance sets the focal "
                        "length, fx = Z·l/S for each method, and is left out of the error tables; IMAGE is a row of "
                        "the CSV (its distance is used; a different =DISTANCE_CM is refused) or another photo of the "
                        "same target (=DISTANCE_CM needed); repeatable (the CSV's reference column does the same)")
    p.add_argument("--exif-focal-length", action="store_true",
                   help="with --photos, instead of --calibration: fx of each photo from its EXIF (FocalLength with "
                        "FocalPlaneXResolution or FocalLengthIn35mmFilm; approximate, the report says so); the "
                        "principal point at the image centre, no distortion")
    add_undistort_option(p)
    add_backend_options(p, "worker processes (default: the cores)")
    add_image_options(p)
    add_plugin_option(p)
    add_progress_option(p)
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    check_backend_args(args.backend, args.workers, args.address)
    methods = method_list(args.methods)
    mo.thresholds_in_use(args.thresholds)
    if args.camera_thresholds is not None:
        mo.thresholds_in_use(args.camera_thresholds)
    if args.photos is not None or args.distances is not None:
        return run_photos(args, methods)
    if not args.datasets:
        raise InputError("no input: give DATASET... (rendered datasets), or --photos DIR --distances FILE.csv "
                         "--calibration FILE|DIR (real photos)")
    sets = [open_dataset(d) for d in args.datasets]  # each must be a dataset
    if not any(ds.targets() for ds in sets):
        raise InputError(f"{' '.join(map(str, args.datasets))}: no target images to evaluate; render a spec with "
                         "kind = \"target\" groups")
    if args.calibration is None and not any(ds.checkerboards() for ds in sets):
        raise InputError("no checkerboard images among the datasets; pass --calibration FILE|DIR "
                         "(a calibration.json, or a dataset of checkerboard renders)")
    if args.calibration is not None:
        p = Path(args.calibration)
        if not p.is_dir():
            check_input_file(p, "calibration JSON")

    samples = [(f"{d}/{s.name}", s.truth) for d, ds in zip(args.datasets, sets) for s in ds.targets()]
    for f in (args.thresholds, args.camera_thresholds):
        check_disjoint(f, samples)  # calibration and test seeds: refused before anything is written
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
                                            "camera_thresholds": args.camera_thresholds, "undistort": args.undistort})
    write_json(out / "calibration.json", cal.to_dict())
    header = {"datasets": ", ".join(f"{d} ({ds.spec_name})" for d, ds in zip(args.datasets, sets)),
              "calibration": source, "UTC": utc_stamp()}
    report = evaluate_datasets(args.datasets, cal, out, methods=methods, thresholds=args.thresholds,
                               progress=not args.no_progress, backend=args.backend,
                               workers=args.workers or default_workers(), address=args.address, header=header,
                               camera_thresholds=args.camera_thresholds, undistort=args.undistort)
    console.say(f"evaluate: report {report}")
    return 0


def run_photos(args: argparse.Namespace, methods) -> int:
    """``--photos DIR --distances FILE.csv --calibration FILE|DIR``: every check before anything is written."""
    if args.datasets:
        raise InputError(f"{args.datasets[0]}: give either DATASET... (renders) or --photos DIR (real photos), not both")
    if args.photos is None:
        raise InputError("--distances needs --photos DIR (the folder holding the photos)")
    if args.distances is None:
        raise InputError("--photos needs --distances FILE.csv (one row per photo; docs/formats.md, "
                         "\"Distances CSV for real photos\")")
    if args.exif_focal_length and args.calibration is not None:
        raise InputError("--exif-focal-length and --calibration both set the focal length; give one")
    if not args.photos.is_dir():
        raise InputError(f"--photos {args.photos}: not a directory; pass the folder that holds the photos")
    records = read_distances(args.distances, args.photos)
    if args.reference_photo:
        records = resolve_references(records, args.reference_photo, args.photos, args.distances)
    has_ref = any(r.reference for r in records)
    if args.exif_focal_length and has_ref:
        raise InputError("--exif-focal-length and reference photos both set the focal length; give one")
    if args.calibration is None and not has_ref and not args.exif_focal_length:
        raise InputError("--photos needs --calibration FILE|DIR (a calibration.json of this camera, or a dataset "
                         "of checkerboard renders), --reference-photo IMAGE or --exif-focal-length")
    cal = cals = None
    focal = ""
    if args.calibration is not None:
        cal_path = Path(args.calibration)
        if not cal_path.is_dir():
            check_input_file(cal_path, "calibration JSON")
    out = check_run_dir(args.output or default_runs_dir() / f"{utc_stamp()}-evaluate", "evaluate")
    if args.calibration is not None:
        cal = load_calibration(cal_path, progress=not args.no_progress)
    size = check_photos(records, cal.image_size if cal else None, args.distances, channel=args.channel,
                        progress=not args.no_progress)
    if has_ref:
        refs = ", ".join(r.image for r in records if r.reference)
        if cal is None:
            cal = camera_without_board(float(max(size)), size, f"no board: fx from the reference photo(s) {refs}")
            focal = (f"from the reference photo(s) {refs}, per method (fx = Z·l/S); principal point at the image "
                     "centre, no distortion (no calibration given)")
        else:
            focal = (f"from the reference photo(s) {refs}, per method (fx = Z·l/S); principal point and distortion "
                     f"from {args.calibration}")
    elif args.exif_focal_length:
        found = [exif_fx(r.path, size[0], size[1], f"{args.distances} line {r.line} ({r.image})") for r in records]
        cals = [camera_without_board(fx, size, f"no board: {src}") for fx, src in found]
        cal = cals[0]
        fxs = sorted({round(fx, 2) for fx, _ in found})
        focal = (f"from each photo's EXIF (approximate): {found[0][1]}; fx = "
                 + (f"{fxs[0]:.2f} px" if len(fxs) == 1 else f"{fxs[0]:.2f}-{fxs[-1]:.2f} px over the photos")
                 + "; principal point at the image centre, no distortion")
    extra = unlisted_photos(records, args.photos)
    out = prepare_run_dir(out, "evaluate", {"photos": str(args.photos), "distances": str(args.distances),
                                            "calibration": args.calibration, "methods": methods,
                                            "reference_photos": args.reference_photo,
                                            "exif_focal_length": args.exif_focal_length, "channel": args.channel,
                                            "thresholds": args.thresholds,
                                            "camera_thresholds": args.camera_thresholds, "undistort": args.undistort})
    write_json(out / "calibration.json", cal.to_dict())
    header = {"photos": f"{args.photos} ({len(records)} in {args.distances.name}"
                        + (f"; {len(extra)} more image files there are not in the CSV and were not evaluated"
                           if extra else "") + ")",
              "distances": str(args.distances),
              "calibration": str(args.calibration) if args.calibration else "none (" + focal.split(";")[0] + ")",
              "gray from colour": args.channel, "UTC": utc_stamp()}
    report = evaluate_photos(records, cal, out, args.photos, methods=methods, thresholds=args.thresholds,
                             camera_thresholds=args.camera_thresholds, channel=args.channel,
                             progress=not args.no_progress, backend=args.backend,
                             workers=args.workers or default_workers(), address=args.address, header=header,
                             undistort=args.undistort, cals=cals, focal_source=focal)
    console.say(f"evaluate: report {report}")
    return 0
