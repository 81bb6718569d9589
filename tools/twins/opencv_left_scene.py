"""Write ``scenes/opencv_left_twin.toml`` and ``assets/cameras/opencv_left.toml``: OpenCV's left01-14 photos through
``edgetruth twin``'s derivation (``edgetruth.evaluate.board.twin_derive``), named as shipped files (not packaged).

    python tools/twins/opencv_left_scene.py

The derivation is the packaged one; what this adds is the shipped names and the noise a closed loop through the
renders found for these photos (docs/board.md): the white's SD before their JPEG, 4.5 DN at a white of 220 (3 and
6 gave SDs after the JPEG below and above the photos').  ``tests/tools/test_opencv_left_scene.py`` re-derives both
files byte for byte.
"""
from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
CAMERA = ROOT / "assets" / "cameras" / "opencv_left.toml"
SCENE = ROOT / "scenes" / "opencv_left_twin.toml"
SQUARE_M = 0.025  # assumed: the board's printed square (not published; it scales the poses only)
NAME = "opencv_left_twin"
DESCRIPTION = ("digital twin of OpenCV's left01-14 chessboard photos: their camera, board, poses, exposure, clip and "
               "JPEG")
SOURCE = "OpenCV's left01-14 sample photos (assets/real/opencv_left)"


def texts() -> tuple[str, str]:
    """(camera TOML, scene TOML) derived now from the shipped photos."""
    from edgetruth.evaluate.board.inputs import resolve_inputs
    from edgetruth.evaluate.board.twin_derive import TwinAssumptions, measure_chessboard, twin_texts

    inp = resolve_inputs(["opencv_left"])
    m = measure_chessboard(inp.photos, (9, 6))
    why = "a closed loop through the JPEG: 3 and 6 gave SDs after it below and above the photos'"
    return twin_texts(m, NAME, DESCRIPTION, "opencv_left", SQUARE_M, SOURCE,
                      TwinAssumptions(white_noise_dn=4.5, white_noise_why=why))


def main() -> None:
    cam, scene = texts()
    CAMERA.write_text(cam)
    SCENE.write_text(scene)
    print(f"wrote {CAMERA.relative_to(ROOT)} and {SCENE.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
