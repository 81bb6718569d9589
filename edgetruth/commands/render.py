"""``edgetruth render SPEC -o DIR``: render a spec (``scenes/<name>.toml`` or a path) into a dataset."""
from __future__ import annotations

import argparse
from pathlib import Path

from edgetruth.paths import RUNS_DIR


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "render", help="render a spec into images + ground truth (resumable)",
        description="Render every image of SPEC (a name in scenes/ or a TOML path) into DIR: "
                    "NAME.exr (radiance), NAME.png (16-bit sensor image), NAME.json (ground truth) and "
                    "manifest.json.  Images already complete (hashes verified) are skipped.")
    p.add_argument("spec", metavar="SPEC", help="spec name (standard, snr, targets, calibration, quick) or TOML path")
    p.add_argument("-o", "--output", metavar="DIR", type=Path, default=None,
                   help="output directory (default: runs/render/SPEC)")
    p.add_argument("--variant", default=None,
                   help="Mitsuba variant to use (default: best working of cuda_ad_rgb, llvm_ad_rgb, scalar_rgb)")
    p.add_argument("--only", metavar="I,J-K", default=None, help="render only these image indices")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--backend", choices=("local", "ray"), default="local",
                   help="where images render: local process pool (default) or a Ray cluster "
                        "(pip install 'edgetruth[cluster]'; see docs/cluster.md)")
    p.add_argument("--workers", "-j", type=_positive_int, default=None, metavar="N",
                   help="local worker processes (default: the number of cores; 1 renders in this process); "
                        "with --backend ray and no --address: CPUs of the local Ray instance")
    p.add_argument("--address", default=None, metavar="ADDR",
                   help="Ray cluster to join (e.g. ray://head:10001 or auto; default: $RAY_ADDRESS, "
                        "else a local Ray instance)")
    p.set_defaults(handler=run)


def _positive_int(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if n < 1:
        raise argparse.ArgumentTypeError(f"{n} must be at least 1")
    return n


def _parse_indices(text: str | None) -> list[int] | None:
    from edgetruth.errors import InputError

    if not text:
        return None
    out: list[int] = []
    try:
        for part in text.split(","):
            a, _, b = part.partition("-")
            lo, hi = (int(a), int(b)) if b else (int(a), int(a))
            if lo < 0 or hi < lo:
                raise ValueError
            out += list(range(lo, hi + 1))
    except ValueError:
        raise InputError(f"--only {text!r}: expected indices like 0,3,5-9") from None
    return out


def run(args: argparse.Namespace) -> int:
    from render.dataset import render_spec
    from render.spec_checks import load_checked_spec

    from edgetruth.backends import check_backend_args

    check_backend_args(args.backend, args.workers, args.address)
    only = _parse_indices(args.only)
    spec = load_checked_spec(args.spec)
    out = args.output or RUNS_DIR / "render" / spec.name
    timings: dict = {}
    manifest = render_spec(spec, out, variant=args.variant, progress=not args.no_progress,
                           only=only, timings=timings, backend=args.backend, workers=args.workers,
                           address=args.address)
    done = sum(1 for e in manifest["images"].values() if e.get("complete"))
    n = timings.get("n_rendered", 0)
    extra = f", {n} rendered in {timings.get('wall_s', 0):.1f} s" if n else ", nothing to do"
    print(f"render: {done}/{len(spec.jobs)} images of {spec.name!r} complete in {out}{extra}")
    return 0
