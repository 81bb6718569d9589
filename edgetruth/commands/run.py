"""``edgetruth run``: the whole study in one command (what ``make run`` calls).

render (specs) -> calibrate (Zhang, OpenCV) -> undistort -> find targets -> every method
-> ranging statistics -> ``report.md``; plus the synthetic study's quick preset, linked
from the report.  Output: ``runs/<UTC stamp>/`` (or ``-o DIR``).

* ``--study quick`` (default): the ``quick`` spec (5 target images + 15 boards, half
  resolution): a smoke test of the whole chain, minutes on 2 cores.
* ``--study full``: ``calibration`` + ``standard`` + ``snr`` + ``targets`` at full
  resolution (hours on a CPU); ``--limit N`` keeps N target images per group (spread
  over the distance range) and ``--calib-limit N`` N boards, for a tiny end-to-end check.
"""
from __future__ import annotations

import argparse
import importlib.util
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

from edgetruth.errors import InputError
from edgetruth.paths import RUNS_DIR

STUDIES = {
    "quick": {"calibration": "quick", "targets": ["quick"]},
    "full": {"calibration": "calibration", "targets": ["standard", "snr", "targets"]},
}


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "run", help="render, calibrate, locate (all methods), evaluate and report, in one go",
        description=__doc__.split("\n\n")[1], formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--study", choices=sorted(STUDIES), default="quick", help="which specs to run (default quick)")
    p.add_argument("-o", "--output", metavar="DIR", type=Path, default=None,
                   help="run directory (default runs/<UTC stamp>); an existing one resumes its renders")
    p.add_argument("--limit", metavar="N", type=int, default=None,
                   help="at most N target images per group (evenly spread over distance)")
    p.add_argument("--calib-limit", metavar="N", type=int, default=None,
                   help="at most N calibration boards (>= 4)")
    p.add_argument("--methods", default=None, help="comma-separated method ids (default: all)")
    p.add_argument("--variant", default=None, help="Mitsuba variant (default: best that works here)")
    p.add_argument("--skip-synthetic", action="store_true", help="do not run the synthetic study's quick preset")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.set_defaults(handler=run)


def select_jobs(spec, limit: int | None, kind: str) -> list[int] | None:
    """Indices of the jobs of ``kind`` to render: all, or ``limit`` per group spread over the group."""
    jobs = [j for j in spec.jobs if j["kind"] == kind]
    if limit is None:
        return [j["index"] for j in jobs]
    out = []
    for g in dict.fromkeys(j["group"] for j in jobs):
        gj = sorted((j for j in jobs if j["group"] == g), key=lambda j: j["distance_cm"])
        if limit >= len(gj):
            out += [j["index"] for j in gj]
        else:
            pick = sorted({int(round(k)) for k in
                           ([0.0] if limit == 1 else [i * (len(gj) - 1) / (limit - 1) for i in range(limit)])})
            out += [gj[k]["index"] for k in pick]
    return sorted(out)


def _stamp() -> str:
    return datetime.now(timezone.utc).strftime("%Y%m%dT%H%M%SZ")


def run(args: argparse.Namespace) -> int:
    import locate
    from evaluate.calibration import calibrate_dataset
    from evaluate.ranging import run_ranging
    from evaluate.ranging_report import write_report
    from render.dataset import render_spec
    from render.spec import load_spec

    if args.limit is not None and args.limit < 1:
        raise InputError(f"--limit {args.limit}: must be >= 1")
    if args.calib_limit is not None and args.calib_limit < 4:
        raise InputError(f"--calib-limit {args.calib_limit}: Zhang's method needs >= 4 boards here")
    methods = None
    if args.methods:
        methods = [m.strip() for m in args.methods.split(",") if m.strip()]
        for m in methods:
            locate.get_method(m)
    study = STUDIES[args.study]
    out = args.output or RUNS_DIR / _stamp()
    out.mkdir(parents=True, exist_ok=True)
    progress = not args.no_progress
    t0 = time.perf_counter()
    timing: dict = {}
    print(f"run: study {args.study!r} -> {out}", flush=True)

    # 1. render
    render_dir = out / "render"
    t = time.perf_counter()
    variants = []
    cal_spec = load_spec(study["calibration"])
    cal_only = select_jobs(cal_spec, None, "checkerboard")
    if args.calib_limit is not None:
        cal_only = cal_only[:args.calib_limit]
    target_sets = []
    for name in study["targets"]:
        spec = load_spec(name)
        only = select_jobs(spec, args.limit, "target")
        if name == cal_spec.name:
            only = sorted(set(only) | set(cal_only))
        target_sets.append((spec, only))
    if cal_spec.name not in study["targets"]:
        target_sets.insert(0, (cal_spec, cal_only))
    for spec, only in target_sets:
        m = render_spec(spec, render_dir / spec.name, variant=args.variant, progress=progress, only=only,
                        announce=lambda s: (variants.append(s), print(s, flush=True)))
        del m
    timing["render_s"] = time.perf_counter() - t

    # 2. calibrate
    t = time.perf_counter()
    from render.dataset import list_images
    cal_dir = render_dir / cal_spec.name
    cal_names = [n for n in list_images(cal_dir) if int(n.split("_")[0]) in set(cal_only)]
    cal = calibrate_dataset(cal_dir, names=cal_names, progress=progress)
    import json
    (out / "calibration.json").write_text(json.dumps(cal.to_dict(), indent=1))
    e = cal.errors()
    print(f"calibrate: {cal.n_views} boards, RMS {cal.rms_px:.3f} px, fx {cal.fx:.2f} px "
          f"({e.get('fx_rel_pct', float('nan')):+.3f} % vs truth), principal point error "
          f"({e.get('cx_px', float('nan')):+.2f}, {e.get('cy_px', float('nan')):+.2f}) px", flush=True)
    timing["calibrate_s"] = time.perf_counter() - t

    # 3-4. locate + evaluate
    t = time.perf_counter()
    datasets = [render_dir / s.name for s, _ in target_sets if s.name in study["targets"]]
    names = {}
    for s, only in target_sets:
        if s.name in study["targets"]:
            keep = set(only)
            names[str(render_dir / s.name)] = [n for n in list_images(render_dir / s.name)
                                               if int(n.split("_")[0]) in keep]
    result = run_ranging(datasets, cal, out, methods=methods, progress=progress, names=names)
    timing["ranging_s"] = time.perf_counter() - t

    # 5. synthetic study (the lead's module), linked from the report
    synthetic_link, synthetic_failed = None, False
    if not args.skip_synthetic:
        t = time.perf_counter()
        if importlib.util.find_spec("evaluate.synthetic_study") is None:
            print("run: synthetic study skipped: evaluate/synthetic_study.py is not in this checkout yet", flush=True)
            synthetic_link = None
        else:
            try:
                from evaluate.synthetic_study import run_synthetic_study
                rep = Path(run_synthetic_study(out / "synthetic", preset="quick"))
                synthetic_link = str(rep.resolve().relative_to(out.resolve())) if rep.is_absolute() else str(rep)
            except InputError:
                raise
            except Exception as exc:  # keep the ranging results; say what failed
                synthetic_failed = True
                print(f"run: synthetic study failed: {type(exc).__name__}: {exc}", file=sys.stderr, flush=True)
        timing["synthetic_s"] = time.perf_counter() - t

    # 6. report
    n_targets = len({r["image"] for r in result["rows"]})
    header = {"study": args.study, "UTC": _stamp(), "specs": ", ".join(s.name for s, _ in target_sets),
              "target images": n_targets, "methods": len(result["methods"]),
              "Mitsuba": "; ".join(variants) or "renders reused (already complete)",
              "timings (s)": ", ".join(f"{k} {v:.1f}" for k, v in timing.items()),
              "interpolation for undistortion": "bilinear (see evaluate/undistort.py)"}
    if not args.skip_synthetic and synthetic_link is None:
        header["synthetic study"] = ("FAILED (see the console)" if synthetic_failed
                                     else "not run: evaluate/synthetic_study.py is absent")
    path = write_report(out, result["rows"], result["methods"], cal, result["examples"], header, synthetic_link)
    print(f"run: report {path} ({time.perf_counter() - t0:.1f} s in all)", flush=True)
    return 1 if synthetic_failed else 0
