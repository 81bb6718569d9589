"""The board study end to end on rendered photos of a known camera (exact side lines, no distortion):
photos + --model through the CLI, the camera recovered."""
import csv

import cv2
import numpy as np
import pytest

from edgetruth.cli import main
from tests.evaluate.board.board_images import apply_h, camera_homography, grid_model, render_board

K = np.array([[600.0, 0, 239.5], [0, 600.0, 179.5], [0, 0, 1]])
#: rotations (rvec) of the board (6 x 6 squares of side 1, pitch 1.6: 9 units wide), its centre 22 units
#: in front of the camera: the whole board in view, tilted 20-30 degrees
ROTATIONS = [(0.35, -0.25, 0.05), (-0.3, 0.3, 0.1), (0.25, 0.4, -0.15), (-0.4, -0.3, 0.3)]


def pose(rvec, distance=22.0):
    R, _ = cv2.Rodrigues(np.array(rvec, float))
    return rvec, np.array([0.0, 0.0, distance]) - R @ np.array([4.5, 4.5, 0.0])


POSES = [pose(r) for r in ROTATIONS]


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    root = tmp_path_factory.mktemp("synboard")
    model = grid_model(6, 6, side=1.0, pitch=1.6)
    (root / "Model.txt").write_text("\n".join(" ".join(f"{v:.6f}" for v in sq.ravel()) for sq in model) + "\n")
    photos = []
    for i, (r, t) in enumerate(POSES):
        quads = apply_h(camera_homography(K, r, t), model)
        assert quads.min() > 10 and quads[..., 0].max() < 470 and quads[..., 1].max() < 350  # all in view
        img = render_board((360, 480), quads, sigma_px=0.6)
        p = root / f"view{i}.png"
        cv2.imwrite(str(p), np.round(img * 256).astype(np.uint16))
        photos.append(str(p))
    out = root / "study"
    rc = main(["study", "board", *photos, "--model", str(root / "Model.txt"), "-o", str(out),
               "--methods", "canny_devernay,erf4p_fixed11", "--no-progress"])
    with open(out / "summary.csv", newline="") as fh:
        return rc, out, {r["row"]: r for r in csv.DictReader(fh)}


def test_a_square_cut_by_the_border_is_reported_missing():
    """The board shifted up so that square 0 (the highest) is cut by the image's top border: it is left out,
    the others keep their numbers."""
    from edgetruth.evaluate.board.detect.correspond import match_squares
    from edgetruth.evaluate.board.model import check_model
    from edgetruth.evaluate.board.detect.quads import find_quads

    model = check_model(grid_model(6, 6, side=1.0, pitch=1.6), "6x6")
    r, t = POSES[3]
    truth = apply_h(camera_homography(K, r, t), model.corners)
    truth[..., 1] -= truth[0, :, 1].min() + 8.0  # square 0's top 8 px above the image
    assert truth[0, :, 1].max() > 15 and truth[1:, :, 1].min() > 3
    c = match_squares(model, find_quads(render_board((360, 480), truth, sigma_px=0.6)))
    assert c.missing == [0]
    assert np.linalg.norm(c.corners[1:] - truth[1:], axis=2).max() < 2.5


def test_runs_without_a_reference(run):
    rc, out, rows = run
    assert rc == 0 and list(rows) == ["canny_devernay", "erf4p_fixed11"]
    text = (out / "report.md").read_text()
    assert "Table 3" not in text
    assert all(f"| view{i}.png | 36 | 36 | — |" in text for i in range(4))


@pytest.mark.parametrize("method", ["canny_devernay", "erf4p_fixed11"])
def test_the_camera_comes_back(run, method):
    """Exact edges, no noise: the calibration is near exact, and the principal point lands on the OpenCV
    convention's image centre (W/2 - 0.5, H/2 - 0.5).  Measured: RMS 0.019 px (Devernay), 0.0017 px
    (ERF4P-fixed11); fx 600.046 / 599.998; cx 239.494 / 239.499; cy 179.510 / 179.496."""
    _, _, rows = run
    r = rows[method]
    assert float(r["calib_rms_px"]) < 0.03 and float(r["loo_rms_px"]) < 0.05
    assert float(r["fx"]) == pytest.approx(600, rel=1e-3) and float(r["fy"]) == pytest.approx(600, rel=1e-3)
    assert float(r["cx"]) == pytest.approx(239.5, abs=0.1) and float(r["cy"]) == pytest.approx(179.5, abs=0.1)
    assert abs(float(r["k1"])) < 0.02
    assert float(r["straightness_px"]) < 0.03
    assert abs(float(r["length_bias_model"])) < 0.003 and float(r["length_rmse_px"]) < 0.05
