"""The shipped real photo sets: each resolves by name, and carries its provenance and licence."""
import pytest

from edgetruth.evaluate.board.detect.chessboard import find_squares, settle_parity
from edgetruth.evaluate.board.inputs import load_photos, resolve_inputs
from edgetruth.resources import real_set, shipped_real_set_names


def test_every_shipped_set_has_a_section_in_the_provenance_file():
    readme = (real_set("zhang1998").parent / "README.md").read_text()
    for name in shipped_real_set_names():
        assert f"## {name}/" in readme, f"assets/real/README.md has no section for {name}/"


def test_sony_hx5v_is_boofcvs_chessboard_of_4x6_inner_corners_with_its_licence():
    inp = resolve_inputs(["sony_hx5v"])
    assert [p.name for p in inp.photos] == [f"frame{i:02d}.jpg" for i in range(1, 14)]
    assert inp.model.pattern == (4, 6)
    folder = real_set("sony_hx5v")
    assert "Attribution 4.0 International" in (folder / "LICENSE-BoofCV-Data").read_text()
    assert "CC by 4.0" in (folder / "README-BoofCV-Data.TXT").read_text()
    assert "chess 2 false true 5 7 30" in (folder / "info.txt").read_text()


@pytest.mark.parametrize("photo", [0, 12])
def test_sony_hx5v_board_is_found_with_all_its_dark_squares(photo):
    inp = resolve_inputs(["sony_hx5v"])
    img = load_photos([inp.photos[photo]])[0]
    model = settle_parity([img], inp.model)
    view = find_squares(img, model)
    assert view is not None and len(model) == 8
    assert view.squares.found.all()  # every dark square, none cut by the border


def test_sony_hx5v_circles_is_boofcvs_10x8_circle_grid_and_plain_opencv_calibrates_it():
    """Plain OpenCV on the shipped circle-grid set (assets/real/README.md): the grid found in 4 of 6 photos and
    its calibration as stated there (3 digits)."""
    import cv2
    import numpy as np

    folder = real_set("sony_hx5v_circles")
    assert "Attribution 4.0 International" in (folder / "LICENSE-BoofCV-Data").read_text()
    assert "CC by 4.0" in (folder / "README-BoofCV-Data.TXT").read_text()
    assert "CIRCLE_GRID" in (folder / "calibration_target.yaml").read_text()
    grid = np.zeros((80, 3), np.float32)
    grid[:, :2] = np.mgrid[0:10, 0:8].T.reshape(-1, 2) * 0.025
    found, obj, img = [], [], []
    for k in range(6):
        gray = cv2.imread(str(folder / f"image{k:05d}.jpg"), cv2.IMREAD_GRAYSCALE)
        ok, centres = cv2.findCirclesGrid(gray, (10, 8), flags=cv2.CALIB_CB_SYMMETRIC_GRID)
        if ok:
            found.append(k)
            obj.append(grid)
            img.append(centres)
    assert found == [1, 2, 3, 5]
    rms, k_mat, dist, _, _ = cv2.calibrateCamera(obj, img, (640, 480), None, None)
    assert rms == pytest.approx(0.450, abs=5e-4)
    np.testing.assert_allclose([k_mat[0, 0], k_mat[1, 1], k_mat[0, 2], k_mat[1, 2]],
                               [454.10, 451.93, 322.47, 242.45], atol=0.01)


def test_study_board_on_sony_hx5v_circles_has_plain_opencv_as_its_reference_row(tmp_path):
    """`edgetruth study board sony_hx5v_circles`: OpenCV's blob centroids calibrate as plain OpenCV does (the test
    above): RMS 0.450 px (to 5e-4), fx 454.10, fy 451.93, cx 322.47, cy 242.45 (to 0.01 px); image00000 and
    image00004 are skipped with why."""
    import csv
    import json

    import numpy as np

    from edgetruth.cli import main

    out = tmp_path / "run"
    assert main(["study", "board", "sony_hx5v_circles", "-o", str(out), "--methods", "erf4p_fixed11",
                 "--no-progress"]) == 0
    with open(out / "summary.csv", newline="") as fh:
        ref = {r["row"]: r for r in csv.DictReader(fh)}["opencv_blobs"]
    assert float(ref["calib_rms_px"]) == pytest.approx(0.450, abs=5e-4)
    np.testing.assert_allclose([float(ref[k]) for k in ("fx", "fy", "cx", "cy")], [454.10, 451.93, 322.47, 242.45],
                               atol=0.01)
    with open(out / "per_photo.csv", newline="") as fh:
        photos = list(csv.DictReader(fh))
    assert [p["photo"] for p in photos if p["used"] == "no"] == ["image00000.jpg", "image00004.jpg"]
    assert all("findCirclesGrid did not find" in p["why_skipped"] for p in photos if p["used"] == "no")
    cal = json.loads((out / "calibration" / "opencv_blobs.json").read_text())
    assert cal["photos"] == ["image00001.jpg", "image00002.jpg", "image00003.jpg", "image00005.jpg"]


def test_sony_hx5v_circles_resolves_to_its_circle_grid():
    """The shipped set's board.toml: OpenCV's 10x8 symmetric grid, centres 25 mm apart, circles 15 mm."""
    inp = resolve_inputs(["sony_hx5v_circles"])
    assert inp.model is None and inp.circles.pattern.text == "circles:10x8"
    assert (inp.circles.spacing, inp.circles.units, inp.circles.diameter) == (25.0, "mm", 15.0)
    assert len(inp.photos) == 6


def _pycalib_plain_opencv(photos):
    """Plain OpenCV on pycalib's ChArUco photos: CharucoDetector.detectBoard on each photo (gray), every corner it
    finds, matchImagePoints, calibrateCamera with flags 0 (OpenCV's 5-term lens)."""
    import cv2

    board = cv2.aruco.CharucoBoard((18, 9), 1.0, 0.8, cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_250))
    detector = cv2.aruco.CharucoDetector(board)
    counts, obj, img = [], [], []
    for p in photos:
        cc, ids, _, _ = detector.detectBoard(cv2.imread(str(p), cv2.IMREAD_GRAYSCALE))
        counts.append(0 if ids is None else len(ids))
        o, i = board.matchImagePoints(cc, ids)
        obj.append(o)
        img.append(i)
    return counts, cv2.calibrateCamera(obj, img, (1280, 720), None, None, flags=0)


def test_pycalib_gopro_charuco_is_pycalibs_18x9_board_with_its_licence():
    inp = resolve_inputs(["pycalib_gopro_charuco"])
    assert [p.name for p in inp.photos] == [f"{i:08d}.jpg" for i in range(1, 10)]
    board = inp.model.charuco.board
    assert (board.cols, board.rows, board.dictionary) == (18, 9, "DICT_4X4_250")
    assert board.marker_m / board.square_m == pytest.approx(0.8) and inp.model.units == "squares"
    assert inp.model.pattern == (17, 8) and len(inp.model) == 56
    assert "Apache License" in (real_set("pycalib_gopro_charuco") / "LICENSE-pycalib").read_text()


def test_pycalib_gopro_charuco_plain_opencv_calibration_as_stated():
    """Plain OpenCV on the shipped ChArUco set (assets/real/README.md): 136 of 136 corners in 8 photos, 132 in
    00000007.jpg; RMS 0.322 px, fx 587.3, fy 586.9, cx 640.3, cy 355.4 px (3 significant digits and better)."""
    import numpy as np

    counts, (rms, k_mat, dist, _, _) = _pycalib_plain_opencv(resolve_inputs(["pycalib_gopro_charuco"]).photos)
    assert counts == [136] * 6 + [132, 136, 136]
    assert rms == pytest.approx(0.3220, abs=5e-4)
    np.testing.assert_allclose([k_mat[0, 0], k_mat[1, 1], k_mat[0, 2], k_mat[1, 2]],
                               [587.33, 586.93, 640.29, 355.43], atol=0.05)
    np.testing.assert_allclose(dist.ravel()[:2], [-0.2718, 0.1042], atol=5e-4)


def test_pycalib_gopro_charuco_study_reference_row_is_opencvs_corners_as_the_study_calibrates_them(tmp_path):
    """`edgetruth study board pycalib_gopro_charuco`: its reference row is OpenCV's ChArUco corners, but calibrated as
    every row of the chessboard study is (docs/board.md): the 8 photos where every corner is found (00000007.jpg,
    132 of 136, is left out), each corner once per dark square it bounds, k1 k2 only: measured RMS 0.572 px, fx
    581.39, fy 581.43, cx 633.30, cy 355.77.  Plain OpenCV's own calibration of the set (the test above) is the
    reference every row's intrinsics are compared with: `calibration/reference.json` and the report's calibration
    table."""
    import csv
    import json

    import numpy as np

    from edgetruth.cli import main

    out = tmp_path / "run"
    assert main(["study", "board", "pycalib_gopro_charuco", "-o", str(out), "--methods", "erf4p_fixed11",
                 "--no-progress"]) == 0
    with open(out / "summary.csv", newline="") as fh:
        ref = {r["row"]: r for r in csv.DictReader(fh)}["opencv_corners"]
    # the reference the rows are compared with is plain OpenCV's own calibration (the test above), to 3 digits
    plain = json.loads((out / "calibration" / "reference.json").read_text())
    assert plain["source"].startswith("plain OpenCV") and plain["rms_px"] == pytest.approx(0.3220, abs=5e-4)
    np.testing.assert_allclose([plain[k] for k in ("fx", "fy", "cx", "cy")], [587.33, 586.93, 640.29, 355.43],
                               atol=0.05)
    assert "| plain OpenCV (CharucoDetector" in (out / "report.md").read_text()
    assert int(ref["corners_used"]) == 8 * 224
    assert float(ref["calib_rms_px"]) == pytest.approx(0.572, abs=5e-4)
    np.testing.assert_allclose([float(ref[k]) for k in ("fx", "fy", "cx", "cy")], [581.39, 581.43, 633.30, 355.77],
                               atol=0.01)


def test_a_charuco_board_toml_without_marker_is_one_line(monkeypatch):
    """A shipped set's board.toml naming a ChArUco pattern must give its marker side (one InputError line)."""
    from edgetruth.errors import InputError
    from edgetruth.evaluate.board import inputs

    folder = real_set("pycalib_gopro_charuco")
    monkeypatch.setattr(inputs, "shipped_set", lambda name: {
        "name": name, "photos": sorted(folder.glob("*.jpg")), "source": f"{name}/board.toml",
        "chessboard": {"pattern": "charuco:18x9:DICT_4X4_250", "square": 1.0, "units": "squares"}})
    with pytest.raises(InputError, match="needs marker = SIDE"):
        inputs.resolve_inputs(["pycalib_gopro_charuco"])
