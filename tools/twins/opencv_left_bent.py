"""Write ``scenes/opencv_left_twin_bent.toml``: OpenCV's twin with each photo's own measured bend (not packaged).

    edgetruth calibrate opencv_left --pattern 9x6 --square-m 0.025 --corners lines -o /tmp/opencv_left_cal.json
    python tools/twins/opencv_left_bent.py /tmp/opencv_left_cal.json

The twin (``scenes/opencv_left_twin.toml``) renders a flat board; the photos' board is curled
(``edgetruth calibrate``'s bend check, docs/board.md).  This copies the twin and gives each photo's group the
quadratic bend the check fitted to that photo (``board_bend_mm``), converted from the check's scale (half the
corners' larger extent, 100 mm here) to the renderer's (half the larger side of the printed squares' box:
coefficient × (s_render / s_check)², ``render.scene.bend``).  The board's centre is the same in both: the squares'
box and the 54 corners are symmetric about it, and a shift would change only the linear terms, which are the pose.
"""
from __future__ import annotations

import json
import re
import sys
from pathlib import Path

from edgetruth.render.dataset.spec import load_spec
from edgetruth.render.scene.bend import BoardBend

ROOT = Path(__file__).resolve().parents[2]
TWIN = ROOT / "scenes" / "opencv_left_twin.toml"
OUT = ROOT / "scenes" / "opencv_left_twin_bent.toml"


def bent_twin_text(calibration: dict, twin_text: str, s_render_mm: float) -> str:
    """The twin's TOML with each found photo's quadratic bend (from ``edgetruth calibrate``'s JSON) in its group."""
    q = calibration["board_bend"]["quadratic"]
    names = [Path(p["photo"]).stem for p in calibration["photos"] if p["found"]]
    if len(names) != len(q["coefficients_mm"]):
        raise SystemExit("every found photo must take part in the bend check (>= 13 corners each)")
    text = twin_text.replace('name = "opencv_left_twin"', 'name = "opencv_left_twin_bent"', 1)
    text = text.replace('description = "digital twin of OpenCV\'s left01-14 chessboard photos:',
                        'description = "digital twin of OpenCV\'s left01-14 chessboard photos, each board curled as '
                        'its photo\'s:', 1)
    for name, c, s_check in zip(names, q["coefficients_mm"], q["scale_mm"]):
        c_render = [round(v * (s_render_mm / s_check) ** 2, 5) for v in c]
        text, n = re.subn(rf'(?m)^(name = "{name}"\nkind = "squares"\n)', rf"\1board_bend_mm = {c_render}\n", text)
        if n != 1:
            raise SystemExit(f"{name}: no squares group of that name in {TWIN.name}")
    head = ("# OpenCV's twin with each photo's own bend: written by tools/twins/opencv_left_bent.py from edgetruth\n"
            "# calibrate's bend check on the photos (line corners, 5-term model; x^2, xy, y^2 a photo), the\n"
            f"# coefficients rescaled from the check's s = {q['scale_mm'][0]:.1f} mm to the renderer's "
            f"s = {s_render_mm:.3f} mm.  docs/board.md, \"A bent twin\".\n")
    return head + text


def main(path: str) -> None:
    spec = load_spec(TWIN)
    s_render_mm = 1e3 * BoardBend.of((0.0, 0.0, 0.0), spec.squares.black_quads_local(0.0)).scale_m
    OUT.write_text(bent_twin_text(json.loads(Path(path).read_text()), TWIN.read_text(), s_render_mm))
    print(f"wrote {OUT.relative_to(ROOT)}")


if __name__ == "__main__":
    main(sys.argv[1])
