"""``edgetruth calibrate-thresholds``: choose tau1 <= tau2 <= tau3 on the calibration split."""
from __future__ import annotations

from pathlib import Path

from edgetruth import console
from edgetruth.cli import add_progress_option, positive_int
from edgetruth.errors import InputError
from edgetruth.evaluate import threshold_calibration as tc
from edgetruth.fileio import check_output_file
from edgetruth.render.dataset.reader import open_dataset
from edgetruth.render.synthetic.scenarios import SCENARIOS


def register(sub) -> None:
    p = sub.add_parser("calibrate-thresholds", help="calibrate the dynamic window's entropy thresholds",
                       description="Exhaustive grid search of tau1 <= tau2 <= tau3 minimising the dynamic ERF RMSE "
                                   "on the synthetic calibration split (seeds disjoint from every test set), or, with "
                                   "--dataset, on the per-point truth of rendered target images of your camera (render "
                                   "them from a spec of their own, e.g. the shipped `thresholds`, so that their seeds "
                                   "differ from the test renders'; evaluating the file on an image with the same seeds "
                                   "is refused). Writes the thresholds with their provenance (data, seeds, objective, "
                                   "result, code version).")
    p.add_argument("-o", "--output", default="entropy_thresholds.json",
                   help="JSON to write (default ./entropy_thresholds.json; the shipped defaults are "
                        "assets/entropy_thresholds.json)")
    p.add_argument("--dataset", nargs="+", metavar="DIR", default=None,
                   help="rendered dataset(s) to calibrate on (their target images) instead of the synthetic split")
    p.add_argument("--images-per-scenario", type=positive_int, default=100,
                   help="synthetic calibration images per scenario (without --dataset)")
    p.add_argument("--step", type=float, default=0.01, help="grid step of the thresholds")
    add_progress_option(p)
    p.set_defaults(handler=run)


def run(args) -> int:
    out = check_output_file(args.output, "-o")  # before the calibration, not after it
    if not 0 < args.step <= 0.25:
        raise InputError(f"--step {args.step}: must be in (0, 0.25]")
    if args.dataset:  # the camera's own renders


        dirs = [Path(d) for d in args.dataset]
        n, desc, where = sum(len(open_dataset(d).targets()) for d in dirs), "calibration renders", "the renders"
        command = f"--dataset {' '.join(args.dataset)}"
        work = lambda progress: tc.calibrate_renders(dirs, args.step, progress=progress)  # noqa: E731
    else:  # the synthetic calibration split
        n, desc, where = args.images_per_scenario * len(SCENARIOS), "calibration images", "the calibration split"
        command = f"--images-per-scenario {args.images_per_scenario}"
        work = lambda progress: tc.calibrate(args.images_per_scenario, args.step, progress=progress)  # noqa: E731
    with console.bar(total=n, desc=desc, unit="img", enabled=not args.no_progress) as bar:
        record = work(bar.update)
    record["provenance"]["command"] = f"edgetruth calibrate-thresholds {command} --step {args.step} -o {out.name}"
    tc.write(record, out)
    _say(record, where)
    console.say(f"-> {out}")
    return 0


def _say(record: dict, where: str) -> None:
    for model, r in record["models"].items():
        fixed = min(r["fixed_window_rmse_px"].values())
        shares = ", ".join(f"{w}: {100 * v:.0f} %" for w, v in r["window_shares"].items())
        console.say(f"{model}: tau = {tuple(round(t, 3) for t in r['tau'])}  RMSE {r['rmse_px']:.4f} px "
                    f"(best fixed window {fixed:.4f} px) on {where}; windows {shares}")
