"""``edgetruth bench``: the performance figures (refinement throughput, rendering speed)."""
from __future__ import annotations


def register(sub) -> None:
    p = sub.add_parser("bench", help="print performance figures (medians, ratios from one run)")
    p.add_argument("--only", choices=["locate", "render"], default=None)
    p.add_argument("--repeats", type=int, default=7)
    p.set_defaults(handler=run)


def run(args) -> int:
    from edgetruth.errors import InputError

    if args.repeats < 1:
        raise InputError(f"--repeats {args.repeats}: must be >= 1 (the figures are medians over repeats)")
    if args.only in (None, "locate"):
        from locate.bench import run_bench

        print("\n".join(run_bench(repeats=args.repeats)), flush=True)
    if args.only in (None, "render"):
        from render.bench import run_bench as render_bench

        print("\n".join(render_bench()), flush=True)
    return 0
