"""``edgetruth twin PHOTOS... --pattern 9x6 --square-m 0.025 -o DIR``: a digital twin of your own chessboard photos;
``edgetruth twin PHOTOS... --model Model.txt --model-unit-m 0.0254 -o DIR``: of photos of a board of separate squares;
``edgetruth twin PHOTOS... --pattern circles:10x8 --square-m 0.025 -o DIR``: of a circle grid's.

Measures on the photos what a twin needs (``edgetruth.evaluate.board.twin.measure`` for a chessboard,
``measure_squares`` for a model's squares, ``measure_circles`` for a circle grid: camera, poses, board, levels, clip, blur, tone, JPEG quality) and writes
``DIR/twin.toml`` (one group per photo), ``DIR/camera.toml``, ``DIR/measurements.json`` and, for a model, its file
(``DIR/model.txt``, so the directory renders on its own); ``edgetruth render DIR/twin.toml -o RENDERS`` renders it
with exact truth.
"""
from __future__ import annotations

import argparse
import math
import shlex
from pathlib import Path

from edgetruth import console
from edgetruth.cli import (add_image_options, add_pattern_option, add_progress_option, add_square_m_option,
                           parse_square_m)
from edgetruth.errors import InputError
from edgetruth.evaluate.board.model import read_model
from edgetruth.evaluate.board.twin.derive import TwinAssumptions, safe_name, twin_texts
from edgetruth.evaluate.board.twin.measure import measure_chessboard
from edgetruth.evaluate.board.twin.measure_circles import measure_circles
from edgetruth.evaluate.board.twin.measure_squares import measure_squares
from edgetruth.evaluate.calibration import find_photos, parse_pattern
from edgetruth.evaluate.pattern import parse_board_pattern
from edgetruth.fileio import atomic_write_bytes, atomic_write_text, check_output_dir, make_output_dir, write_json
from edgetruth.render.dataset.spec import load_spec
from edgetruth.render.schema import NAME_RE
from edgetruth.resources import real_set, shipped_real_set_names


FILES = ("twin.toml", "camera.toml", "measurements.json", "model.txt")
#: a board of separate squares' tone when not given: sRGB's (close to a power of 2.2)
DEFAULT_TONE_POWER = 2.2


def register(sub) -> None:
    p = sub.add_parser("twin", help="derive a digital twin (a render spec) of your own board photos",
                       description="Measure on photos of a chessboard (--pattern) or of a board of separate squares "
                                   "(--model) what a digital twin of them needs -- the camera (Zhang's calibration "
                                   "on line corners), each photo's pose, the board (a chessboard's outer ring), "
                                   "levels and clip, blur and sharpening, tone and JPEG quality -- and write a render "
                                   "spec with one image per photo (DIR/twin.toml), its camera (DIR/camera.toml) and "
                                   "the measurements (DIR/measurements.json).  `edgetruth render DIR/twin.toml -o R` "
                                   "renders it with exact truth (docs/board.md, 'Your own twin').")
    p.add_argument("photos", nargs="*", metavar="PHOTOS",
                   help="image files, folders, glob patterns (quoted), or a shipped photo set's name (opencv_left, "
                        "zhang1998); 8- or 16-bit, gray or colour (read as luma, or --channel), every photo showing "
                        "the whole board")
    add_pattern_option(p, "the chessboard or circle grid the photos show (or --model)", kinds=("chessboard", "circles"))
    add_square_m_option(p, "with --pattern: it sets the twin's board size and its distances; a circle grid: OpenCV's "
                           "squareSize, the distance between neighbouring centres (an asymmetric grid's row spacing)",
                        required=False)
    p.add_argument("--model", default=None, metavar="FILE",
                   help="the board of separate squares the photos show (or --pattern): one square per line, x y of "
                        "its four corners in model units (Zhang's Model.txt layout); copied to DIR/model.txt")
    p.add_argument("--model-unit-m", default=None, metavar="METRES",
                   help="with --model: the length of its unit in metres (0.0254 for inches); it sets the twin's "
                        "board size and its distances")
    p.add_argument("--tone-power", type=float, default=None, metavar="G",
                   help=f"with --model or a circle grid, 8-bit photos: their tone, stored = full * linear^(1/G) (default "
                        f"{DEFAULT_TONE_POWER:g}, close to sRGB; 1: linear); separate squares and circles have no "
                        "junctions to measure it at (a chessboard's is measured)")
    p.add_argument("-o", "--output", required=True, metavar="DIR",
                   help="directory for twin.toml, camera.toml, measurements.json (and with --model its "
                        "model.txt); refused if it holds a twin.toml already")
    p.add_argument("--name", default=None, help="the spec's name (default: the directory's name)")
    p.add_argument("--pitch-um", type=float, default=6.0, metavar="UM",
                   help="assumed pixel pitch (default 6); with fx it sets the focal length, hence the defocus")
    p.add_argument("--f-number", type=float, default=4.0, metavar="N", help="assumed f-number (default 4)")
    p.add_argument("--white-noise-dn", type=float, default=None, metavar="DN",
                   help="the white's shot-noise SD (8-bit DN, at a white of 220) before the output coding (15 e- "
                        "of read noise add to it); default: from the photos (JPEG photos with a linear tone: shot "
                        "and read noise through their JPEG; through a tone curve: their darks and whites split "
                        "into noise before and after it; docs/board.md); 8-bit photos only")
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
    pattern, model, unit_m = _board(args)
    for flag, v, lo, hi in (("--pitch-um", args.pitch_um, 0.5, 50.0), ("--f-number", args.f_number, 0.5, 64.0),
                            ("--tone-power", args.tone_power, 0.2, 5.0),
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

    if args.name is not None and not (NAME_RE.match(args.name) and ".." not in args.name):
        raise InputError(f"--name {args.name!r}: use 1-100 letters, digits, '_', '-', '.', starting with a letter or "
                         "digit (it names files and directories)")
    name = args.name or safe_name(out.resolve().name or "twin")
    track = lambda it: console.track(it, desc="twin", unit="photo", enabled=not args.no_progress)  # noqa: E731
    tone_power = DEFAULT_TONE_POWER if args.tone_power is None else args.tone_power
    circles = pattern is not None and not isinstance(pattern, tuple)  # a circle grid's BoardPattern
    if circles:
        m = measure_circles([p for _, p in photos], pattern, tone_power, channel=args.channel, progress=track)
    elif model is None:
        m = measure_chessboard([p for _, p in photos], pattern, channel=args.channel, progress=track)
    else:
        m = measure_squares([p for _, p in photos], model, tone_power, channel=args.channel, progress=track)
    assumptions = TwinAssumptions(pitch_um=args.pitch_um, f_number=args.f_number, white_noise_dn=args.white_noise_dn,
                                  dark_noise_e=args.read_noise_e, black_dn=args.black_dn)
    for o in m["left_out"]:
        console.warn(f"twin: {o['photo']}: {o['why']}; left out (the twin has one image per photo it measured)")
    gone = {o["photo"] for o in m["left_out"]}
    kept = [(name, path) for name, path in photos if path.name not in gone]
    source = f"{len(kept)} photos ({kept[0][0]} ... {kept[-1][0]})"
    cam, scene = twin_texts(m, name, f"digital twin of {source}", "camera.toml", unit_m, source, assumptions,
                            bend=args.bend, model_ref=None if model is None else "model.txt")
    make_output_dir(out)
    write_json(out / "measurements.json", m)
    if model is not None:
        atomic_write_bytes(out / "model.txt", Path(args.model).read_bytes())
    atomic_write_text(out / "camera.toml", cam)
    atomic_write_text(out / "twin.toml", scene)  # last: its presence says the directory is complete

    spec = load_spec(out / "twin.toml")
    tone = m["tone"]
    console.say(f"twin: {spec.n_images} photos; camera fx {m['K'][0][0]:.2f} fy {m['K'][1][1]:.2f} px, RMS "
                f"{m['rms_px']:.4f} px; {spec.sensor.output}"
                + (f" quality {spec.sensor.jpeg_quality}" if spec.sensor.output == "jpeg" else "")
                + (f" {spec.sensor.bits}-bit, K {spec.sensor.k0_dn_per_e:.4f} DN/e-, black "
                   f"{spec.sensor.dark_offset_dn:.1f} DN" if spec.sensor.output == "raw" else
                   f", output_gamma {tone['output_gamma']:g}")
                + ("" if model is None and not circles else " (assumed, --tone-power)")
                + f"; {sum(p['white_saturated'] for p in m['photos'])} "
                f"clipped" + ("; each board curled as its photo's" if args.bend else "") + f" -> {out / 'twin.toml'}")
    console.say(f"twin: render it with `edgetruth render {shlex.quote(str(out / 'twin.toml'))} -o RENDERS`")
    # the photos as given (the study pairs the twin's images with the photos its groups name); a shipped set's name
    # as its folder: `study twin NAME` is the set's own study, with its own twin

    given = [str(real_set(r)) if not Path(r).exists() and "/" not in r and r in shipped_real_set_names() else r
             for r in args.photos]
    board = ["--pattern", args.pattern] if model is None else ["--model", str(out / "model.txt")]
    if circles:
        board += ["--square", f"{unit_m:g}"]
    study = ["edgetruth", "study", "twin", *given, *board, "--twin", str(out / "twin.toml"),
             *(["--channel", args.channel] if args.channel != "luma" else []), "-o", "RUN"]
    console.say(f"twin: or render it beside the photos and compare: `{shlex.join(study)}`")
    return 0


def _board(args):
    """(pattern, model, unit_m): a chessboard's (``--pattern``, ``--square-m``) or a model's (``--model``,
    ``--model-unit-m``); one ``InputError`` line for a mix or a missing half."""
    if (args.pattern is None) == (args.model is None):
        raise InputError("twin: give the board the photos show, either --pattern COLSxROWS --square-m METRES (a "
                         "chessboard) or --model FILE --model-unit-m METRES (separate squares), not both")
    if args.pattern is not None:
        board = parse_board_pattern(args.pattern, kinds=("chessboard", "circles"))
        if board.kind == "circles":
            if args.model_unit_m is not None:
                raise InputError("--model-unit-m: for --model (a board of separate squares); a circle grid's spacing "
                                 "is --square-m; drop it")
            if args.bend:
                raise InputError("--bend: for chessboards only (a circle grid has no bend check); drop it")
            if args.square_m is None:
                raise InputError(f"--pattern {board.text} needs --square-m METRES: OpenCV's squareSize, the distance "
                                 "between neighbouring centres (an asymmetric grid's row spacing), e.g. 0.025")
            return board, None, parse_square_m(args.square_m)
        for flag, v in (("--model-unit-m", args.model_unit_m), ("--tone-power", args.tone_power)):
            if v is not None:
                raise InputError(f"{flag}: for --model (a board of separate squares); a chessboard's "
                                 + ("size is --square-m" if flag == "--model-unit-m" else "tone is measured at its "
                                    "junctions") + "; drop it")
        if args.square_m is None:
            raise InputError("--pattern needs --square-m METRES: the side of one printed square (e.g. 0.025)")
        return parse_pattern(args.pattern), None, parse_square_m(args.square_m)
    if args.square_m is not None:
        raise InputError("--square-m: for --pattern; a model's size is --model-unit-m METRES (its unit's length); "
                         "drop it")
    if args.bend:
        raise InputError("--bend: for chessboards only (a board of separate squares has no bend check); drop it")
    if args.model_unit_m is None:
        raise InputError("--model needs --model-unit-m METRES: the length of the model file's unit (0.0254 for "
                         "inches, 1 for metres)")
    try:
        unit = float(args.model_unit_m)
    except ValueError:
        unit = float("nan")
    if not (0 < unit < 1e3):
        raise InputError(f"--model-unit-m {args.model_unit_m!r}: give the model unit's length in metres, a positive "
                         "number (0.0254 for inches)")
    return None, read_model(args.model), unit
