"""Write OpenCV's shipped twins: ``assets/cameras/opencv_left.toml``, ``scenes/opencv_left_twin.toml`` and
``scenes/opencv_left_twin_bent.toml`` -- OpenCV's left01-14 photos through ``edgetruth twin``'s derivation
(``edgetruth.evaluate.board.twin.derive``; the bent twin with ``--bend``), under the shipped names (not packaged).

    python tools/twins/opencv_left_scene.py

The derivation is the packaged one; what this adds is the shipped names and the noise a closed loop through the
renders found for these photos (docs/board.md): the white's shot-noise SD before their JPEG, 4.1 DN at a white of
220, and 29 e- of read noise, with which the twin's dark and white SDs after the JPEG (the photo model's, Table 3
of `edgetruth study twin opencv_left`) are the photos' to 1 % (medians over the 7 unsaturated photos; renders
without Monte-Carlo noise, ``board_mode = "frame"``; with each photo's dark offset, added after the loop, 0.99 and
0.97).  The bent twin renders path-traced (a curled board), with the
Monte-Carlo noise in its darks: it keeps the loop closed on path-traced renders, 4.5 DN and 15 e- (3 and 6 DN gave
SDs after the JPEG below and above the photos').  ``tests/tools/test_opencv_left_scene.py`` re-derives the
three files byte for byte.
"""
from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
CAMERA = ROOT / "assets" / "cameras" / "opencv_left.toml"
SCENE = ROOT / "scenes" / "opencv_left_twin.toml"
BENT = ROOT / "scenes" / "opencv_left_twin_bent.toml"
SQUARE_M = 0.025  # assumed: the board's printed square (not published; it scales the poses only)
WHAT = "their camera, board, poses, exposure, clip and JPEG"
SOURCE = "OpenCV's left01-14 sample photos (assets/real/opencv_left)"


def texts() -> tuple[str, str, str]:
    """(camera TOML, flat twin TOML, bent twin TOML) derived now from the shipped photos."""
    from edgetruth.evaluate.board.inputs import resolve_inputs
    from edgetruth.evaluate.board.twin.derive import TwinAssumptions, twin_texts
    from edgetruth.evaluate.board.twin.measure import measure_chessboard

    m = measure_chessboard(resolve_inputs(["opencv_left"]).photos, (9, 6))
    why = ("a closed loop through the renders and their JPEG, with the read noise: the twin's dark and white SDs "
           "after it within 3 % of the photos' (medians over the unsaturated photos)")
    a = TwinAssumptions(white_noise_dn=4.1, white_noise_why=why, dark_noise_e=29.0)
    cam, flat = twin_texts(m, "opencv_left_twin", f"digital twin of OpenCV's left01-14 chessboard photos: {WHAT}",
                           "opencv_left", SQUARE_M, SOURCE, a)
    why = ("a closed loop through path-traced renders and their JPEG (the Monte-Carlo noise of a curled board's "
           "darks included): 3 and 6 gave SDs after it below and above the photos'")
    a = TwinAssumptions(white_noise_dn=4.5, white_noise_why=why, dark_noise_e=15.0)
    _, bent = twin_texts(m, "opencv_left_twin_bent", "digital twin of OpenCV's left01-14 chessboard photos, each "
                         f"board curled as its photo's: {WHAT}", "opencv_left", SQUARE_M, SOURCE, a, bend=True)
    return cam, flat, bent


def main() -> None:
    for path, text in zip((CAMERA, SCENE, BENT), texts()):
        path.write_text(text)
        print(f"wrote {path.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
