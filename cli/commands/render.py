"""``edgetruth render SPEC -o DIR``: render a spec (a shipped name or a TOML path) into a dataset."""
from __future__ import annotations

import argparse
from pathlib import Path

from edgetruth import console
from edgetruth.backends import check_backend_args
from edgetruth.cli import add_backend_options, add_progress_option
from edgetruth.errors import InputError
from edgetruth.fileio import check_output_dir
from edgetruth.render.dataset.driver import render_spec
from edgetruth.render.dataset.spec import load_spec
from edgetruth.resources import default_runs_dir, shipped_spec_names


def register(subparsers) -> None:
    shipped = ", ".join(shipped_spec_names()) or "none (broken install)"

    p = subparsers.add_parser(
        "render", help="render a spec into images + ground truth (resumable)",
        description="Render every image of SPEC (a shipped spec name or a TOML path; keys in docs/spec.md) into "
                    "DIR: NAME.exr (radiance), NAME.png (16-bit sensor image), NAME.json (ground truth) and "
                    "manifest.json (formats in docs/formats.md).  Images already complete (hashes verified) "
                    "are skipped, so an interrupted run resumes.")
    p.add_argument("spec", metavar="SPEC", help=f"a shipped spec ({shipped}) or a TOML path")
    p.add_argument("-o", "--output", metavar="DIR", type=Path, default=None,
                   help="output directory (default: ./runs/render/SPEC)")
    p.add_argument("--variant", default=None,
                   help="Mitsuba variant to use (default: best working of cuda_ad_rgb, llvm_ad_rgb, scalar_rgb)")
    p.add_argument("--only", metavar="I,J-K", default=None, help="render only these image indices")
    p.add_argument("--files", choices=("auto", "driver", "workers"), default="auto",
                   help="who writes the image files: the workers when they share this disk (auto: a local pool or "
                        "a local Ray instance), else this driver, which then receives the bytes (driver); workers: "
                        "always the workers (every node mounts DIR at the same path)")
    add_progress_option(p)
    add_backend_options(p, "local worker processes (default: the number of cores; 1 renders in this process); "
                           "with --backend ray and no --address: CPUs of the local Ray instance")
    p.set_defaults(handler=run)


def parse_indices(text: str | None) -> list[int] | None:
    if text is None:
        return None
    out: list[int] = []
    for part in text.split(","):
        a, dash, b = (t.strip() for t in part.partition("-"))
        try:
            lo, hi = (int(a), int(b)) if dash else (int(a), int(a))
        except ValueError:
            raise InputError(f"--only {text!r}: {part.strip()!r} is not an index or a range; expected indices like "
                             "0,3,5-9 (a range names both ends)") from None
        if lo < 0 or hi < lo:
            raise InputError(f"--only {text!r}: {part.strip()!r} runs backwards or below 0; write ranges low-high, "
                             "e.g. 5-9")
        if hi - lo > 10_000_000:
            raise InputError(f"--only {text!r}: {part.strip()!r} spans more than 10 million images; split it")
        out += list(range(lo, hi + 1))
    return out


def run(args: argparse.Namespace) -> int:
    check_backend_args(args.backend, args.workers, args.address)
    only = parse_indices(args.only)
    spec = load_spec(args.spec)
    out = check_output_dir(args.output or default_runs_dir() / "render" / spec.name)
    timings: dict = {}
    render_spec(spec, out, variant=args.variant, progress=not args.no_progress, only=only, timings=timings,
                backend=args.backend, workers=args.workers, address=args.address, files=args.files,
                announce=console.say)
    done = timings["n_complete"]
    n = timings.get("n_rendered", 0)
    extra = f", {n} rendered in {timings.get('wall_s', 0):.1f} s" if n else ", nothing to do"
    console.say(f"render: {done}/{spec.n_images} images of {spec.name!r} complete in {out}{extra}")
    return 0
