"""``edgetruth bench``: the performance figures (refinement throughput, rendering speed)."""
from __future__ import annotations


def register(sub) -> None:
    from edgetruth.cli import positive_int

    p = sub.add_parser("bench", help="print performance figures (medians, ratios from one run)",
                       description="Start-up costs (edgetruth --version, import edgetruth.locate, edgetruth locate "
                                   "on 100 images in one call), refinement throughput per method on a 1280x1024 "
                                   "mosaic, and rendering speed per Mitsuba variant (what `make bench` runs).")
    p.add_argument("--only", choices=["startup", "locate", "render"], default=None, help="run one part only")
    p.add_argument("--repeats", type=positive_int, default=7, help="timed repeats per figure (medians)")
    p.set_defaults(handler=run)


def run(args) -> int:
    if args.only in (None, "startup"):
        from edgetruth.cli.startup_bench import run_bench as startup_bench

        print("\n".join(startup_bench(repeats=args.repeats)), flush=True)
    if args.only in (None, "locate"):
        from edgetruth.evaluate.refine_bench import run_bench

        print("\n".join(run_bench(repeats=args.repeats)), flush=True)
    if args.only in (None, "render"):
        from edgetruth.render.bench import run_bench as render_bench

        print("\n".join(render_bench()), flush=True)
    return 0
