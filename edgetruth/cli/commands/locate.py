"""``edgetruth locate IMAGE --method M -o points.csv``: subpixel edge points of one image."""
from __future__ import annotations

import argparse


def register(sub) -> None:
    from edgetruth.cli import add_image_options, add_plugin_option

    p = sub.add_parser("locate", help="subpixel edge points of an image -> CSV",
                       description="Canny candidates refined by METHOD; one CSV row per point "
                                   "(x, y in OpenCV pixel coordinates: pixel centres at integers; columns in "
                                   "docs/formats.md).")
    p.add_argument("image", help="image file (PNG/TIFF/JPEG 8/16-bit, EXR, .npy), gray or colour (see --channel); "
                                 "its EXIF orientation is honoured")
    p.add_argument("--method", "-m", default="dynamic_erf_4p", help="method id (see `edgetruth methods`)")
    p.add_argument("-o", "--output", required=True, help="CSV file to write (written atomically)")
    p.add_argument("--sigma", type=float, default=1.0, help="Gaussian smoothing for candidates/normals, px")
    p.add_argument("--low", type=float, default=None, help="Canny low threshold, gray levels/px")
    p.add_argument("--high", type=float, default=None, help="Canny high threshold, gray levels/px")
    p.add_argument("--thresholds", default=None,
                   help="entropy-thresholds JSON (from `edgetruth calibrate-thresholds`) for dynamic_erf_*")
    add_image_options(p)
    add_plugin_option(p)
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from edgetruth import console, locate
    from edgetruth.errors import InputError
    from edgetruth.fileio import check_input_file, check_output_file
    from edgetruth.image_io import read_gray
    from edgetruth.locate import thresholds as thr

    locate.get_method(args.method)
    check_input_file(args.image, "image")
    out = check_output_file(args.output, "-o", inputs=[args.image])
    options = {}
    if args.thresholds is not None:
        if not args.method.startswith("dynamic_erf_"):
            raise InputError(f"--thresholds applies to dynamic_erf_2p/4p only, not {args.method}")
        options["tau"] = thr.load(args.method[-2:], args.thresholds)
    img = read_gray(args.image, channel=args.channel)
    try:
        pts = locate.locate(img, args.method, sigma_px=args.sigma, low=args.low, high=args.high, **options)
    except InputError as exc:
        raise InputError(f"{args.image}: {exc}") from exc
    try:
        pts.to_csv(out)
    except OSError as exc:
        raise InputError(f"-o {out}: cannot write ({exc.strerror}); choose a writable location") from exc
    console.say(f"{len(pts)} points ({int(pts.converged.sum())} converged) -> {out}")
    return 0
