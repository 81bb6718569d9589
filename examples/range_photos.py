"""Range your own photos: targets at measured distances, Z = fx·S/l and the pose, against your reference.

`edgetruth evaluate --photos DIR --distances FILE.csv --calibration FILE` ranges photos of squares,
rectangles or circles whose distances you measured. Photos of your own go in DIR with one CSV row each
(docs/formats.md, "Distances CSV"). This script stands in for the camera: it renders a few photos of a
13 cm black square at 60-150 cm, writes their CSV from the renders' truth, and writes the camera's
calibration, as `edgetruth calibrate` would from your board photos (see calibrate_board.py). Then it runs
the command and prints, per photo, the reference distance and each method's ranging error.

    python examples/range_photos.py              # 6 photos at 320x256
    python examples/range_photos.py --scale 4 --photos 2   # what the tests run
"""
import argparse
import csv
import json
import shutil
import tempfile
from pathlib import Path

from edgetruth.cli import main as edgetruth
from edgetruth.render import open_dataset
from edgetruth.render.dataset.driver import render_spec

SPEC = """
[spec]
name = "my_photos"
camera = "quick"
camera_scale = {scale}
spp = 16
edge_spp = 64
sampler = "multijitter"

[[group]]
name = "square"
target = "T1"             # the 13 cm black matte square on a white board
distance_range_cm = [60, 150]
count = {count}
tilt_max_deg = 3
irradiance_w_m2 = {irradiance}
"""


def main(argv=None) -> list[dict]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scale", type=int, default=2, help="bin the quick camera's pixels (default 2: 320x256)")
    ap.add_argument("--photos", type=int, default=6, help="how many photos (default 6)")
    args = ap.parse_args(argv)

    work = Path(tempfile.mkdtemp(prefix="edgetruth_photos_"))
    spec = work / "my_photos.toml"
    spec.write_text(SPEC.format(scale=args.scale, count=args.photos, irradiance=0.075 / args.scale ** 2))
    render_spec(spec, work / "renders", progress=False)

    # what you would have: a folder of photos, the distances you measured, and a calibration
    photos = work / "photos"
    photos.mkdir()
    rows = []
    for s in open_dataset(work / "renders"):
        shutil.copy(s.dataset.path / f"{s.name}.png", photos)  # the 16-bit sensor image, as a camera saves it
        rows.append({"image": f"{s.name}.png", "distance_cm": f"{s.truth['true_distance_m'] * 100:.2f}",
                     "size_m": 0.13, "shape": "square", "group": "G1"})
        cam = s.truth["camera"]
    with open(work / "distances.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    (work / "calibration.json").write_text(json.dumps({
        "K": cam["K"], "dist_coeffs_opencv": cam["dist_coeffs_opencv"],
        "image_size": [cam["width_px"], cam["height_px"]]}))

    code = edgetruth(["evaluate", "--photos", str(photos), "--distances", str(work / "distances.csv"),
                      "--calibration", str(work / "calibration.json"), "--no-progress",
                      "--methods", "canny_pixel,erf4p_fixed11,patch_psf_fit", "-o", str(work / "report")])
    if code:
        raise SystemExit(code)
    with open(work / "report" / "ranging_rows.csv") as f:
        out = list(csv.DictReader(f))
    print(f"\nreport: {work / 'report' / 'report.md'}")
    print(f"{'photo':<16}{'method':<16}{'reference cm':>13}{'size model cm':>15}{'pose cm':>9}")
    for r in out:
        print(f"{r['image']:<16}{r['method']:<16}{float(r['true_distance_m']) * 100:>13.1f}"
              f"{float(r['error_cm']):>+15.3f}{float(r['error_pose_cm'] or 'nan'):>+9.3f}")
    return out


if __name__ == "__main__":
    main()
