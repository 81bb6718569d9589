"""``edgetruth calibrate PHOTOS... --pattern 9x6 --square-m 0.025 -o calibration.json``: Zhang's
calibration of a real camera from photos of a chessboard.

The JSON it writes is the ``calibration.json`` of ``edgetruth run`` (``Calibration.to_dict``), so
``edgetruth evaluate --calibration FILE`` reads it, plus what the command was told and what became
of each photo (docs/formats.md, *Camera calibration JSON*).  Photos where the board is not found
are listed and left out; fewer than 3 boards is an error and nothing is written.
"""
from __future__ import annotations

import argparse

from edgetruth import console, locate
from edgetruth.cli import (add_image_options, add_pattern_option, add_progress_option, add_square_m_option,
                           parse_square_m)
from edgetruth.errors import InputError
from edgetruth.evaluate import board_bend, method_order as mo, residual_field
from edgetruth.evaluate.board import charuco
from edgetruth.evaluate.board.detect.chessboard import chessboard_model
from edgetruth.evaluate.board.measure.grid_corners import DEFAULT_METHOD, grid_points, line_corners
from edgetruth.evaluate.calibration import (DEFAULT_DIST_MODEL, DIST_MODELS, calibrate_photos, find_photos,
                                            parse_pattern, use_bent_board)
from edgetruth.evaluate.pattern import parse_board_pattern
from edgetruth.fileio import check_output_file, write_json
from edgetruth.locate.registry import camera_free


def register(sub) -> None:
    p = sub.add_parser("calibrate", help="calibrate a camera from photos of a chessboard (Zhang) -> JSON",
                       description="Zhang's calibration (cv2.findChessboardCorners, cornerSubPix, calibrateCamera) "
                                   "from real photos of a printed chessboard; writes K, the distortion "
                                   "coefficients and the reprojection RMS, per photo whether the board was found "
                                   "and its RMS.  The JSON is what `edgetruth evaluate --calibration FILE` reads.")
    p.add_argument("photos", nargs="*", metavar="PHOTOS",  # none: our own one-line error, not argparse's usage
                   help="image files, folders (every image inside, sorted), glob patterns (quoted), or the name "
                        "of a shipped photo set (opencv_left)")
    add_pattern_option(p, "the board the photos show", required=True, kinds=("chessboard", "charuco"))
    add_square_m_option(p, "it scales the board poses only, not K or the distortion")
    p.add_argument("--marker-m", default=None, metavar="METRES",
                   help="a ChArUco board (--pattern charuco:...): the printed side of one marker, its black border "
                        "included (OpenCV's markerLength; required there: OpenCV's detector places the corners "
                        "from the markers)")
    p.add_argument("--model", choices=tuple(DIST_MODELS), default=DEFAULT_DIST_MODEL,
                   help="distortion terms to estimate (the others are held at 0): "
                        + "; ".join(f"{k}: {v[1]}" for k, v in DIST_MODELS.items())
                        + f" (default {DEFAULT_DIST_MODEL})")
    p.add_argument("--subpix-window", default="auto", metavar="auto|N",
                   help="cornerSubPix half-window in px (OpenCV's winSize; the window is 2N+1 px wide): 'auto' "
                        "(default) = 0.4 of the smallest imaged square side, per photo, a corner that a window of "
                        "0.6 of it moves by more than 0.25 px taking that one (the larger reached another edge, such "
                        "as a cut outer ring); 5 = the window of OpenCV's sample and regression test, as it is "
                        "(docs/formats.md has both measured on its left01-14 photos)")
    p.add_argument("--corners", default="subpix", metavar="subpix|lines[:METHOD]",
                   help="how each inner corner is measured: 'subpix' (default) = OpenCV's cornerSubPix; 'lines' = "
                        "where the two grid lines through it meet, each fitted to an edge method's points on both "
                        "its halves (free of dark squares imaging smaller or larger than light ones; docs/board.md, "
                        "Chessboards), with erf4p_fixed11 or the METHOD given (options as in --methods, e.g. "
                        "lines:canny_devernay); a grid corner whose one square between the inner corners is light is "
                        "measured on the grid segments either side of it, the outer ones in the board's outer ring")
    p.add_argument("--line-frame", choices=("undistorted", "photo"), default=None,
                   help="with --corners lines, where the grid lines are fitted: 'undistorted' (default) = in the "
                        "undistorted image, where they are straight (the calibration's own lens, refitted until "
                        "the corners settle, 2-4 refits); 'photo' = straight through the photo's grid lines, which "
                        "a distorting lens bends, so the corners move towards the centre (on OpenCV's left01-14 "
                        "twin: 0.06 px, fx +0.17 %%; docs/formats.md)")
    # the option's name before --line-frame (stop 35); kept so that scripts that pass it still run
    p.add_argument("--undistort-lines", dest="line_frame", action="store_const", const="undistorted",
                   help=argparse.SUPPRESS)
    p.add_argument("--board", choices=("flat", "bent", "common"), default="flat",
                   help="flat (default): Zhang's flat board; bent: the calibration refitted with the board's height "
                        "in each photo a quadratic of its board coordinates (a print that curls; docs/board.md), "
                        "its K and distortion written in place of the flat ones; common: one quadratic height "
                        "shared by every photo (a rigid board that is warped).  Either way the JSON's board_bend "
                        "gives every fit and how much of the residual each bend takes")
    p.add_argument("-o", "--output", required=True, help="JSON file to write (written atomically)")
    add_image_options(p)
    add_progress_option(p)
    p.set_defaults(handler=run)


def _window(text: str) -> int | None:
    if str(text).strip().lower() == "auto":
        return None
    try:
        n = int(text)
    except ValueError:
        n = 0
    if not 1 <= n <= 100:
        raise InputError(f"--subpix-window {text!r}: give 'auto' or a half-window of 1..100 px (5 is OpenCV's)")
    return n


def _corner_finder(text: str, pattern: tuple[int, int], window: int | None, line_frame: str | None = None):
    """``--corners``: (corner_finder, label, undistort_lines) for ``calibrate_photos``; (None, None, False) for
    cornerSubPix.  Line corners are fitted in the undistorted image unless ``line_frame`` is 'photo'; for that the
    finder returns each photo's grid (``grid_corners.grid_points``), which ``calibrate_photos`` refits."""
    kind, _, spec = str(text).partition(":")
    if kind == "subpix" and not spec:
        if line_frame is not None:
            raise InputError(f"--line-frame {line_frame}: only with --corners lines (cornerSubPix fits no lines); "
                             "add --corners lines or drop it")
        return None, None, False
    if kind != "lines":
        raise InputError(f"--corners {text!r}: give 'subpix' or 'lines' (or lines:METHOD, e.g. lines:canny_devernay)")
    if window is not None:
        raise InputError("--subpix-window: only with --corners subpix (the line corners use no cornerSubPix window); "
                         "drop one")

    spec = spec or DEFAULT_METHOD
    method, options = mo.resolve(spec, mo.study_options())
    locate.get_method(method)
    if not camera_free([method]):
        raise InputError(f"--corners {text!r}: {method} needs a camera model, which a calibration does not have yet; "
                         "choose another method (`edgetruth methods`)")
    try:
        chessboard_model(pattern, 1.0)
    except InputError:
        raise InputError(f"--corners lines: a {pattern[0]}x{pattern[1]} board has too few squares between its inner "
                         "corners (need 4x4 inner corners or more); use --corners subpix") from None

    undistort_lines = line_frame != "photo"

    def finder(image, pattern_size):
        if undistort_lines:
            return grid_points(image, pattern_size, method, **options)
        return line_corners(image, pattern_size, method, **options)

    label = f"corners where the grid lines of {spec}'s points meet (edgetruth.evaluate.board.measure.grid_corners)"
    return finder, label, undistort_lines


def _charuco(args, board_pattern, square_m: float, window):
    """A ChArUco board's corner finder (``edgetruth.evaluate.board.charuco``) -> (finder, label, undistort_lines,
    the inner corners' pattern size)."""
    if args.marker_m is None:
        raise InputError(f"--pattern {board_pattern.text}: give --marker-m, the printed side of one marker in metres "
                         "(its black border included), as OpenCV's CharucoBoard takes it")
    try:
        marker_m = float(args.marker_m)
    except ValueError:
        marker_m = float("nan")
    if window is not None:
        raise InputError("--subpix-window: a ChArUco board's corners use OpenCV's detector's own cornerSubPix window; "
                         "drop it")
    board = charuco.board_of(board_pattern, square_m, marker_m)
    finder, label, undistort = charuco.corner_finder(board, args.corners, args.line_frame)
    return finder, label, undistort, (board.cols - 1, board.rows - 1)


def run(args: argparse.Namespace) -> int:
    board_pattern = parse_board_pattern(args.pattern, kinds=("chessboard", "charuco"))
    square_m = parse_square_m(args.square_m)
    window = _window(args.subpix_window)
    if board_pattern.kind == "charuco":
        finder, corner_label, undistort_lines, pattern = _charuco(args, board_pattern, square_m, window)
    else:
        if args.marker_m is not None:
            raise InputError(f"--marker-m: only with a ChArUco --pattern (charuco:COLSxROWS:DICT), not "
                             f"{args.pattern!r}; drop it")
        pattern = parse_pattern(args.pattern)
        finder, corner_label, undistort_lines = _corner_finder(args.corners, pattern, window, args.line_frame)
    photos = find_photos(args.photos)
    out = check_output_file(args.output, "-o", inputs=[path for _, path in photos])
    cal, results = calibrate_photos(
        photos, pattern, square_m, model=args.model, window_px=window, channel=args.channel,
        corner_finder=finder, corner_label=corner_label, undistort_lines=undistort_lines,
        progress=lambda it: console.track(it, desc="calibrate", unit="photo", enabled=not args.no_progress))
    if args.board != "flat":
        cal = use_bent_board(cal, results, "quadratic" if args.board == "bent" else "common")
    doc = cal.to_dict()
    if board_pattern.kind == "charuco":
        doc["charuco"] = {"pattern": board_pattern.text, "squares": list(board_pattern.size),
                          "marker_m": float(args.marker_m), "dictionary": board_pattern.dictionary,
                          "object_points": "inner corner k = r (cols - 1) + c at (c, r) * square_m (OpenCV's own "
                                           "board frame less one square: the same K and distortion)"}
    doc.update({"pattern_size": list(pattern), "square_m": square_m, "model": args.model, "board": args.board,
                "subpix_window": "auto" if window is None else window, "corners": args.corners,
                "undistort_lines": undistort_lines,
                "channel": args.channel,
                "photos": [r.to_dict() for r in results]})
    try:
        write_json(out, doc)
    except OSError as exc:
        raise InputError(f"-o {out}: cannot write ({exc.strerror}); choose a writable location") from exc
    missing = [r.photo for r in results if not r.found]
    console.say(f"calibrate: board found in {cal.n_views} of {len(results)} photos"
                + (f" (not found: {', '.join(missing)})" if missing else "")
                + f"; RMS {cal.rms_px:.4f} px, fx {cal.fx:.2f} fy {cal.fy:.2f} cx {cal.cx:.2f} cy {cal.cy:.2f} px"
                + f" -> {out}")

    console.say("calibrate: " + residual_field.reading(cal.residual_structure))
    console.say("calibrate: " + board_bend.reading(cal.board_bend, full_lens=args.model == DEFAULT_DIST_MODEL))
    return 0
