"""``edgetruth twin PHOTOS... --pattern 9x6 --square-m 0.025 -o DIR``: a digital twin of your own chessboard photos.

Measures on the photos what a twin needs (``edgetruth.evaluate.board.twin.measure``: camera, poses, board, levels,
clip, blur, tone, JPEG quality) and writes ``DIR/twin.toml`` (one group per photo), ``DIR/camera.toml`` and
``DIR/measurements.json``; ``edgetruth render DIR/twin.toml -o RENDERS`` renders it with exact truth.
"""
from __future__ import annotations

import argparse

FILES = ("twin.toml", "camera.toml", "measurements.json")


def register(sub) -> None:
    from edgetruth.cli import add_image_options, add_pattern_option, add_progress_option, add_square_m_option

    p = sub.add_parser("twin", help="derive a digital twin (a render spec) of your own chessboard photos",
                       description="Measure on chessboard photos what a digital twin of them needs -- the camera "
                                   "(Zhang's calibration on line corners), each photo's pose, the board's outer "
                                   "ring, levels and clip, blur, tone and JPEG quality -- and write a render spec "
                                   "with one image per photo (DIR/twin.toml), its camera (DIR/camera.toml) and the "
                                   "measurements (DIR/measurements.json).  `edgetruth render DIR/twin.toml -o R` "
                                   "renders it with exact truth (docs/board.md, 'Your own twin').")
    p.add_argument("photos", nargs="*", metavar="PHOTOS",
                   help="image files, folders, glob patterns (quoted), or a shipped photo set's name (opencv_left); "
                        "8-bit, every photo showing the whole board")
    add_pattern_option(p, "the board the photos show", required=True)
    add_square_m_option(p, "it sets the twin's board size and its distances")
    p.add_argument("-o", "--output", required=True, metavar="DIR",
                   help="directory for twin.toml, camera.toml and measurements.json (refused if it holds a "
                        "twin.toml already)")
    p.add_argument("--name", default=None, help="the spec's name (default: the directory's name)")
    p.add_argument("--pitch-um", type=float, default=6.0, metavar="UM",
                   help="assumed pixel pitch (default 6); with fx it sets the focal length, hence the defocus")
    p.add_argument("--f-number", type=float, default=4.0, metavar="N", help="assumed f-number (default 4)")
    p.add_argument("--white-noise-dn", type=float, default=None, metavar="DN",
                   help="the white's shot-noise SD (8-bit DN, at a white of 220) before the output coding (15 e- "
                        "of read noise add to it); default: from the photos (JPEG photos with a linear tone: shot "
                        "and read noise through their JPEG; docs/board.md); 8-bit photos only")
    p.add_argument("--read-noise-e", type=float, default=None, metavar="E",
                   help="the sensor's read noise (e-); default: JPEG photos with a linear tone: from their darks; "
                        "16-bit photos: from their noise at a given --black-dn; else 15 (assumed)")
    p.add_argument("--black-dn", type=float, default=None, metavar="DN",
                   help="16-bit (raw) photos: the camera's black level (DN); default: from the photos' noise with "
                        "the read noise (photon transfer; docs/board.md)")
    p.add_argument("--bend", action="store_true",
                   help="curl each photo's board as the calibration's bend check measures it (a quadratic height "
                        "per photo, board_bend_mm; docs/board.md, 'A bent twin'): prints curl, and a flat twin "
                        "leaves that in the photos' residuals only")
    add_image_options(p)
    add_progress_option(p)
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    import math
    import shlex

    from edgetruth import console
    from edgetruth.cli import parse_square_m
    from edgetruth.errors import InputError
    from edgetruth.evaluate.board.twin.derive import TwinAssumptions, safe_name, twin_texts
    from edgetruth.evaluate.board.twin.measure import measure_chessboard
    from edgetruth.evaluate.calibration import find_photos, parse_pattern
    from edgetruth.fileio import atomic_write_text, check_output_dir, make_output_dir, write_json

    pattern = parse_pattern(args.pattern)
    square_m = parse_square_m(args.square_m)
    for flag, v, lo, hi in (("--pitch-um", args.pitch_um, 0.5, 50.0), ("--f-number", args.f_number, 0.5, 64.0),
                            ("--white-noise-dn", args.white_noise_dn, 0.01, 50.0),
                            ("--read-noise-e", args.read_noise_e, 0.0, 1e4),
                            ("--black-dn", args.black_dn, 0.0, 65535.0)):
        if v is not None and not (math.isfinite(v) and lo <= v <= hi):
            raise InputError(f"{flag} {v:g}: give a number from {lo:g} to {hi:g}")
    out = check_output_dir(args.output)
    if (out / "twin.toml").exists():
        raise InputError(f"-o {out}: it holds a twin.toml already; choose a new directory or remove that one")
    photos = find_photos(args.photos)
    if len(photos) < 3:
        raise InputError(f"{len(photos)} photo(s): Zhang's calibration needs 3 or more views of the board")
    from edgetruth.render.schema import NAME_RE

    if args.name is not None and not (NAME_RE.match(args.name) and ".." not in args.name):
        raise InputError(f"--name {args.name!r}: use 1-100 letters, digits, '_', '-', '.', starting with a letter or "
                         "digit (it names files and directories)")
    name = args.name or safe_name(out.resolve().name or "twin")
    m = measure_chessboard([p for _, p in photos], pattern, channel=args.channel,
                           progress=lambda it: console.track(it, desc="twin", unit="photo",
                                                             enabled=not args.no_progress))
    assumptions = TwinAssumptions(pitch_um=args.pitch_um, f_number=args.f_number, white_noise_dn=args.white_noise_dn,
                                  dark_noise_e=args.read_noise_e, black_dn=args.black_dn)
    for o in m["left_out"]:
        console.warn(f"twin: {o['photo']}: {o['why']}; left out (the twin has one image per photo it measured)")
    gone = {o["photo"] for o in m["left_out"]}
    kept = [(name, path) for name, path in photos if path.name not in gone]
    source = f"{len(kept)} photos ({kept[0][0]} ... {kept[-1][0]})"
    cam, scene = twin_texts(m, name, f"digital twin of {source}", "camera.toml", square_m, source, assumptions,
                            bend=args.bend)
    make_output_dir(out)
    write_json(out / "measurements.json", m)
    atomic_write_text(out / "camera.toml", cam)
    atomic_write_text(out / "twin.toml", scene)  # last: its presence says the directory is complete
    from edgetruth.render.dataset.spec import load_spec

    spec = load_spec(out / "twin.toml")
    tone = m["tone"]
    console.say(f"twin: {spec.n_images} photos; camera fx {m['K'][0][0]:.2f} fy {m['K'][1][1]:.2f} px, RMS "
                f"{m['rms_px']:.4f} px; {spec.sensor.output}"
                + (f" quality {spec.sensor.jpeg_quality}" if spec.sensor.output == "jpeg" else "")
                + (f" {spec.sensor.bits}-bit, K {spec.sensor.k0_dn_per_e:.4f} DN/e-, black "
                   f"{spec.sensor.dark_offset_dn:.1f} DN" if spec.sensor.output == "raw" else
                   f", output_gamma {tone['output_gamma']:g}")
                + f"; {sum(p['white_saturated'] for p in m['photos'])} "
                f"clipped" + ("; each board curled as its photo's" if args.bend else "") + f" -> {out / 'twin.toml'}")
    console.say(f"twin: render it with `edgetruth render {shlex.quote(str(out / 'twin.toml'))} -o RENDERS`")
    # the photos as given: the study pairs the twin's images with the photos its groups name
    study = ["edgetruth", "study", "twin", *args.photos, "--pattern", args.pattern, "--twin", str(out / "twin.toml"),
             *(["--channel", args.channel] if args.channel != "luma" else []), "-o", "RUN"]
    console.say(f"twin: or render it beside the photos and compare: `{shlex.join(study)}`")
    return 0
