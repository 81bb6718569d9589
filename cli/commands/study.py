"""``edgetruth study synthetic|board|twin``: the seed's synthetic study on analytic ground truth, the board
study on real photographs of a board of squares, and the digital twin of a shipped photo set (rendered, then
the same board study on twin and photos, side by side)."""
from __future__ import annotations

import datetime as _dt
from pathlib import Path

from edgetruth import console
from edgetruth.cli import (add_backend_options, add_image_options, add_pattern_option, add_plugin_option,
                           add_progress_option, method_list, methods_help, positive_int)
from edgetruth.errors import InputError
from edgetruth.evaluate.board.study import run_board_study
from edgetruth.evaluate.board.twin.budget import TERMS
from edgetruth.evaluate.board.twin.study import run_twin_study
from edgetruth.evaluate.board.which_pattern.study import DEFAULT_SPEC as PATTERN_SPEC, run_pattern_study
from edgetruth.resources import default_runs_dir


#: options that belong to one kind of study only (dest -> the kind), refused with the other
_SYNTHETIC_ONLY = {"preset": "--preset", "images_per_scenario": "--images-per-scenario", "workers": "-j/--workers",
                   "address": "--address"}
_BOARD_ONLY = {"inputs": "PHOTOS", "model": "--model", "pattern": "--pattern", "square": "--square", "tone": "--tone",
               "marker": "--marker"}
_TWIN_ONLY = {"images": "--images", "spp": "--spp", "variant": "--variant", "twin": "--twin", "budget": "--budget"}
_PATTERN_ONLY = {"spec": "--spec"}


def register(sub) -> None:
    p = sub.add_parser("study", help="run a study and write its report",
                       description="synthetic: the seed's synthetic study (Tables 3-8, Figures 4-7) on analytic "
                                   "edges with exact ground truth; re-running into the same directory resumes. "
                                   "board: every method on real photos of a board of squares (straightness of the "
                                   "sides, Zhang calibration of the corners, leave-one-image-out, side lengths; "
                                   "docs/board.md), e.g. `edgetruth study board zhang1998 -o DIR` or "
                                   "`edgetruth study board PHOTOS... --model Model.txt -o DIR`, or for a chessboard "
                                   "`edgetruth study board opencv_left -o DIR` or "
                                   "`edgetruth study board PHOTOS... --pattern 9x6 --square 25 -o DIR`, or for a "
                                   "circle grid `edgetruth study board sony_hx5v_circles -o DIR` or "
                                   "`edgetruth study board PHOTOS... --pattern circles:10x8 --square 25 -o DIR`. "
                                   "twin: the digital twin of a shipped photo set, `edgetruth study twin zhang1998 "
                                   "-o DIR` (or opencv_left): renders the set's twin scene (scenes/SET_twin.toml: "
                                   "the camera, "
                                   "board and poses, with optics, noise and output measured on the photos) into "
                                   "DIR/renders (resumable), runs the same board study on the twin's images and "
                                   "on the photos, scores the twin's points against its exact outlines, measures "
                                   "both with the photo model, and writes DIR/report.md with real and twin side "
                                   "by side and the Spearman rank correlations (docs/board.md, 'Digital twin'); "
                                   "~3-5 min on 2 cores; of your own photos: `edgetruth study twin PHOTOS... "
                                   "--pattern 9x6 --twin DIR/twin.toml -o RUN` (`edgetruth twin` writes the twin). "
                                   "pattern: \"which pattern?\": a chessboard, a circle grid and a ChArUco board "
                                   "rendered on the same poses (scenes/which_pattern.toml, resumable), each calibrated "
                                   "with OpenCV's detector and edgetruth's against the exact truth, with paired "
                                   "tests and the circle-centre bias against tilt (docs/patterns.md); ~8 min on 2 "
                                   "cores.")
    p.add_argument("kind", choices=["synthetic", "board", "twin", "pattern"], help="which study")
    p.add_argument("inputs", nargs="*", metavar="PHOTOS",
                   help="board: photo files, folders of photos, or a shipped set's name (zhang1998: its photos, "
                        "model, corners and published calibration; opencv_left: OpenCV's chessboard photos; "
                        "sony_hx5v_circles: BoofCV's photos of a 10x8 circle grid); twin: "
                        "the shipped set's name (zhang1998 or opencv_left), or your photos (as for board) with "
                        "--twin")
    p.add_argument("--model", default=None, metavar="FILE",
                   help="board: the board model, one square per line, x y of its four corners in board units "
                        "(Zhang's Model.txt layout)")
    add_pattern_option(p, "board, and twin of your own photos (a chessboard): the photos show this board, and its dark squares "
                          "between the inner corners are studied (in place of --model); board: a circle grid's "
                          "circles are studied as docs/board.md, 'Circle grids', says",
                       kinds=("chessboard", "circles", "charuco"))
    p.add_argument("--square", default=None, metavar="SIZE",
                   help="board, with --pattern: the side of one square, in the unit side lengths are reported in "
                        "(default 1: lengths in squares); a circle grid (required there): OpenCV's squareSize, the "
                        "distance between neighbouring centres, for an asymmetric grid the row spacing (half the "
                        "distance between neighbours in a row)")
    p.add_argument("--marker", default=None, metavar="SIZE",
                   help="board, with --pattern charuco:COLSxROWS:DICT: the printed side of one marker (its black "
                        "border included), in the unit of --square (in squares without it, e.g. 0.75)")
    p.add_argument("--tone", default=None, metavar="stored|srgb|power:G|auto[:METHOD]",
                   help="board: how the photos' stored values are decoded before locating: 'stored' (default) as "
                        "stored; 'srgb' the sRGB curve; 'power:G' full*(v/full)**G (e.g. power:2.2); 'auto' (a "
                        "chessboard) the power at which a method's own square corners meet the junctions, measured "
                        "on the photos (default method erf4p_fixed11; auto:canny_devernay for another)")
    p.add_argument("--images", default=None, metavar="LIST",
                   help="twin: which of the set's photos (1-based, comma-separated, at least 3; default all), e.g. "
                        "1,2,3")
    p.add_argument("--spp", type=positive_int, default=None,
                   help="twin: samples per pixel of the renders (a power of 4 up to 16384; default the scene's 256)")
    p.add_argument("--variant", default=None, help="twin: Mitsuba variant of the renders (default: the fastest here)")
    p.add_argument("--twin", default=None, metavar="SPEC",
                   help="twin: the twin scene to render, a shipped spec or a TOML path with one image per photo "
                        "(default: the set's, SET_twin); opencv_left_twin_bent curls each board as its photo's "
                        "(docs/board.md, 'A bent twin'); with your own photos, required: e.g. the DIR/twin.toml "
                        "`edgetruth twin` writes")
    p.add_argument("--budget", nargs="?", const="all", default=None, metavar="TERMS",
                   help="twin: the error budget -- the twin rendered again with each term it renders switched off in "
                        "turn (noise, fpn, jpeg, sharpening, clip, bend, lens_shading; or a comma-separated list), "
                        "the same board study on each, and a budget table of straightness (a circle grid: the ellipse "
                        "residual) and calibration RMS against the photos' (docs/board.md, 'Error budget'); ~30 s a "
                        "term for opencv_left")
    p.add_argument("--spec", default=None, metavar="SPEC",
                   help=f"pattern: the boards to compare, a shipped spec or a TOML path (default {PATTERN_SPEC}: "
                        "copy it to change the camera, boards, poses, focus or light)")
    p.add_argument("--preset", choices=["quick", "full"], default=None,
                   help="synthetic: quick (default): 24 images per scenario (~1 min); full: 200 per scenario "
                        "(the seed's scale)")
    p.add_argument("--images-per-scenario", type=positive_int, default=None,
                   help="synthetic: override the preset's image count")
    p.add_argument("--methods", default=None, metavar="LIST", help=methods_help())
    p.add_argument("--thresholds", default=None, metavar="FILE",
                   help="entropy thresholds for the dynamic methods (default: the shipped ones)")
    p.add_argument("-o", "--output", default=None, help="output directory (default ./runs/<UTC stamp>-<kind>); "
                   "synthetic: re-running into the same directory resumes; board: re-running with the same "
                   "settings re-makes it, other settings are refused")
    add_backend_options(p, "synthetic: local worker processes (default 1 = in-process; timings are cleanest with 1)")
    add_image_options(p)
    add_plugin_option(p)
    add_progress_option(p)
    p.set_defaults(handler=run)


def _budget_terms(text: str | None) -> list[str] | None:
    """--budget's terms: None (no budget), [] (every term the twin renders) or the names given."""
    if text is None:
        return None
    if text == "all":
        return []
    names = [t.strip() for t in text.split(",") if t.strip()]
    bad = [t for t in names if t not in TERMS]
    if bad or not names:
        raise InputError(f"--budget {text}: unknown term(s) {', '.join(bad) or '(none)'}; use all or a comma-separated "
                         f"list of {', '.join(TERMS)}")
    return names


def _refuse(args, only: dict, kind: str) -> None:
    for dest, flag in only.items():
        v = getattr(args, dest, None)
        if v not in (None, []):
            raise InputError(f"{flag}: not an option of `study {kind}`; drop it")


def run(args) -> int:
    out = Path(args.output) if args.output else default_runs_dir() / (
        _dt.datetime.now(_dt.timezone.utc).strftime("%Y%m%d-%H%M%S") + f"-{args.kind}")
    if args.kind == "twin":
        # one name that is not a path: a shipped set; else your own photos, with their twin scene (--twin)
        shipped = len(args.inputs) == 1 and not Path(args.inputs[0]).exists()
        board_only = {k: v for k, v in _BOARD_ONLY.items() if k != "inputs" and (shipped or k == "tone")}
        _refuse(args, _SYNTHETIC_ONLY | board_only | _PATTERN_ONLY, "twin" + (" SET" if shipped else " PHOTOS..."))
        if args.backend != "local":
            raise InputError("--backend: not an option of `study twin` (it renders in-process); drop it")
        if not args.inputs:
            raise InputError("study twin: give one shipped set's name, e.g. `edgetruth study twin zhang1998 -o DIR`, "
                             "or your photos with --twin FILE")
        report = run_twin_study(args.inputs[0] if shipped else list(args.inputs), out,
                                methods=method_list(args.methods), images=_images(args.images), spp=args.spp,
                                thresholds=args.thresholds, channel=args.channel, variant=args.variant,
                                progress=not args.no_progress, twin=args.twin, model_path=args.model,
                                pattern=args.pattern, square=args.square, budget=_budget_terms(args.budget))
        console.say(f"report: {report}")
        return 0
    if args.kind == "pattern":
        _refuse(args, {k: v for k, v in _SYNTHETIC_ONLY.items() if k != "workers"} | _BOARD_ONLY | _TWIN_ONLY,
                "pattern")
        if args.backend != "local" or args.methods:
            raise InputError("--backend/--methods: not options of `study pattern` (it renders with local workers "
                             "and measures with erf4p_fixed11); drop them")
        report = run_pattern_study(out, args.spec or PATTERN_SPEC, progress=not args.no_progress,
                                   workers=args.workers,
                                   command="edgetruth study pattern" + (f" --spec {args.spec}" if args.spec else "")
                                           + f" -o {out}")
        console.say(f"report: {report}")
        return 0
    if args.kind == "board":
        _refuse(args, _SYNTHETIC_ONLY | _TWIN_ONLY | _PATTERN_ONLY, "board")
        if args.backend != "local":
            raise InputError("--backend: not an option of `study board` (it runs in-process); drop it")
        report = run_board_study(args.inputs, out, model=args.model, pattern=args.pattern, square=args.square,
                                 tone=args.tone, marker=args.marker,
                                 methods=method_list(args.methods),
                                 channel=args.channel, thresholds=args.thresholds, progress=not args.no_progress)
        console.say(f"report: {report}")
        return 0
    from edgetruth.evaluate.synthetic.study import run_synthetic_study  # lazy: study loads numba

    _refuse(args, _BOARD_ONLY | _TWIN_ONLY | _PATTERN_ONLY, "synthetic")
    report = run_synthetic_study(out, args.preset or "quick", method_list(args.methods), progress=not args.no_progress,
                                 images_per_scenario=args.images_per_scenario, backend=args.backend,
                                 workers=args.workers or 1, address=args.address, thresholds=args.thresholds)
    console.say(f"report: {report}")
    return 0


def _images(text: str | None) -> list[int] | None:
    """``--images 1,2,3`` -> [1, 2, 3]; None for all."""
    if text is None:
        return None
    try:
        out = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise InputError(f"--images {text!r}: give comma-separated photo numbers, e.g. 1,2,3") from None
    if not out:
        raise InputError(f"--images {text!r}: give comma-separated photo numbers, e.g. 1,2,3")
    return out
