"""``edgetruth calibrate-thresholds``: choose tau1 <= tau2 <= tau3 on the calibration split."""
from __future__ import annotations


def register(sub) -> None:
    from edgetruth.cli import add_progress_option, positive_int

    p = sub.add_parser("calibrate-thresholds", help="calibrate the dynamic window's entropy thresholds",
                       description="Exhaustive grid search of tau1 <= tau2 <= tau3 minimising the dynamic ERF RMSE "
                                   "on the synthetic calibration split (seeds disjoint from every test set). "
                                   "Writes the thresholds with their provenance (data, objective, result, code version).")
    p.add_argument("-o", "--output", default="entropy_thresholds.json",
                   help="JSON to write (default ./entropy_thresholds.json; the shipped defaults are "
                        "assets/entropy_thresholds.json)")
    p.add_argument("--images-per-scenario", type=positive_int, default=100, help="calibration images per scenario")
    p.add_argument("--step", type=float, default=0.01, help="grid step of the thresholds")
    add_progress_option(p)
    p.set_defaults(handler=run)


def run(args) -> int:
    from edgetruth import console
    from edgetruth.errors import InputError
    from edgetruth.evaluate import threshold_calibration as tc
    from edgetruth.fileio import check_output_file
    from edgetruth.render.synthetic import SCENARIOS

    out = check_output_file(args.output, "-o")  # before the calibration, not after it
    if not 0 < args.step <= 0.25:
        raise InputError(f"--step {args.step}: must be in (0, 0.25]")
    with console.bar(total=args.images_per_scenario * len(SCENARIOS), desc="calibration images", unit="img",
                     enabled=not args.no_progress) as bar:
        record = tc.calibrate(args.images_per_scenario, args.step, progress=bar.update)
    record["provenance"]["command"] = (f"edgetruth calibrate-thresholds --images-per-scenario "
                                       f"{args.images_per_scenario} --step {args.step} -o {out.name}")
    tc.write(record, out)
    for model, r in record["models"].items():
        fixed = min(r["fixed_window_rmse_px"].values())
        console.say(f"{model}: tau = {tuple(round(t, 3) for t in r['tau'])}  RMSE {r['rmse_px']:.4f} px "
                    f"(best fixed window {fixed:.4f} px) on the calibration split")
    console.say(f"-> {out}")
    return 0
