"""``edgetruth calibrate-thresholds``: choose tau1 <= tau2 <= tau3 on the calibration split."""
from __future__ import annotations

from pathlib import Path

from edgetruth.errors import InputError


def register(sub) -> None:
    p = sub.add_parser("calibrate-thresholds", help="calibrate the dynamic window's entropy thresholds",
                       description="Exhaustive grid search of tau1 <= tau2 <= tau3 minimising the dynamic ERF RMSE "
                                   "on the synthetic calibration split (seeds disjoint from every test set). "
                                   "Writes the thresholds with their provenance (data, objective, result, code version).")
    p.add_argument("-o", "--output", default="entropy_thresholds.json",
                   help="JSON to write (the shipped defaults are assets/entropy_thresholds.json)")
    p.add_argument("--images-per-scenario", type=int, default=100)
    p.add_argument("--step", type=float, default=0.01, help="grid step of the thresholds")
    p.set_defaults(handler=run)


def run(args) -> int:
    from tqdm import tqdm

    from evaluate import threshold_calibration as tc
    from render.synthetic import SCENARIOS

    out = Path(args.output)
    if out.is_dir():
        raise InputError(f"-o {out}: is a directory; give a file name")
    if not out.parent.exists():
        raise InputError(f"-o {out}: directory {out.parent} does not exist; create it first")
    if args.images_per_scenario < 1:
        raise InputError(f"--images-per-scenario {args.images_per_scenario}: must be >= 1")
    if not 0 < args.step <= 0.25:
        raise InputError(f"--step {args.step}: must be in (0, 0.25]")
    with tqdm(total=args.images_per_scenario * len(SCENARIOS), desc="calibration images", unit="img") as bar:
        record = tc.calibrate(args.images_per_scenario, args.step, progress=bar.update)
    record["provenance"]["command"] = (f"edgetruth calibrate-thresholds --images-per-scenario "
                                       f"{args.images_per_scenario} --step {args.step} -o {out}")
    tc.write(record, out)
    for model, r in record["models"].items():
        fixed = min(r["fixed_window_rmse_px"].values())
        print(f"{model}: tau = {tuple(round(t, 3) for t in r['tau'])}  RMSE {r['rmse_px']:.4f} px "
              f"(best fixed window {fixed:.4f} px) on the calibration split")
    print(f"-> {out}")
    return 0
