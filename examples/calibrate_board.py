"""Calibrate from your own board: Zhang's method on chessboard photos, with the checks edgetruth adds.

`edgetruth calibrate PHOTOS... --pattern COLSxROWS --square-m SIZE -o calibration.json` finds the inner
corners of a chessboard (OpenCV's detector and cornerSubPix, or `--corners lines` for corners where an edge
method's grid lines meet), calibrates the camera (K, k1, k2, p1, p2, k3), and says whether the residuals
are noise or a smooth field per view, and how much of them a bent board takes. This runs it on the shipped
OpenCV `left01-14` photos (9x6 inner corners, Apache-2.0, assets/real/); point it at your own photos the
same way. The JSON it writes is what `edgetruth evaluate --calibration` reads.

    python examples/calibrate_board.py               # all 13 photos, cornerSubPix corners
    python examples/calibrate_board.py --photos 6    # what the tests run
    python examples/calibrate_board.py --corners lines:erf4p_fixed11
"""
import argparse
import json
import tempfile
from pathlib import Path

from edgetruth.cli import main as edgetruth
from edgetruth.resources import real_set


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--photos", type=int, default=0, help="use the first N photos (default: all)")
    ap.add_argument("--corners", default="subpix", help="subpix (default) or lines[:METHOD]")
    args = ap.parse_args(argv)

    photos = sorted(real_set("opencv_left").glob("left*.jpg"))
    if args.photos:
        photos = photos[:args.photos]
    out = Path(tempfile.mkdtemp(prefix="edgetruth_cal_")) / "calibration.json"
    code = edgetruth(["calibrate", *map(str, photos), "--pattern", "9x6", "--square-m", "0.025",
                      "--corners", args.corners, "-o", str(out), "--no-progress"])
    if code:
        raise SystemExit(code)
    cal = json.loads(out.read_text())
    print(f"\n{cal['n_views']} views: fx {cal['fx_px']:.2f} px, fy {cal['fy_px']:.2f} px, "
          f"principal point ({cal['cx_px']:.2f}, {cal['cy_px']:.2f}) px, RMS {cal['reprojection_rms_px']:.4f} px")
    print("distortion (k1, k2, p1, p2, k3):", ", ".join(f"{v:+.4f}" for v in cal["dist_coeffs_opencv"]))
    print(f"written: {out}")
    return cal


if __name__ == "__main__":
    main()
