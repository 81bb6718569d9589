"""`edgetruth study twin`: its parts on analytic inputs, a reduced twin run end to end (3 of Zhang's poses, 4 spp,
3 methods: both columns, finite rho and p, the files; ~40 s on 2 cores, marked slow), and bad inputs refused with
one line and exit code 2 before anything is written."""
from __future__ import annotations

import csv

import numpy as np
import pytest

from edgetruth.cli import main
from edgetruth.errors import InputError
from edgetruth.evaluate.board.twin import study as twin


# --- parts ----------------------------------------------------------------------------------------
def _square_truth(corners: np.ndarray) -> dict:
    """A truth block of one square whose outline is the straight polygon ``corners`` (4, 2), polyline 1 px apart."""
    poly, par = [], []
    for k in range(4):
        a, b = corners[k], corners[(k + 1) % 4]
        n = int(np.ceil(np.linalg.norm(b - a)))
        for i in range(n):
            poly.append(a + (b - a) * i / n)
            par.append((k + i / n) / 4)
    return {"squares": {"polylines_distorted_px": [np.asarray(poly).tolist()], "polylines_parameter": [par],
                        "corners_distorted_px": [corners.tolist()]}}


def test_outline_points_and_point_errors():
    from edgetruth.evaluate.board.measure.rows import Row
    from edgetruth.evaluate.board.sides.lines import fit_lines

    c = np.array([[10.0, 10.0], [50.0, 12.0], [48.0, 52.0], [8.0, 50.0]])
    truth = _square_truth(c)
    x, y, lab = twin.outline_points(truth)
    assert set(np.unique(lab)) == {0, 1, 2, 3}
    f = fit_lines(lab, x, y, 1)
    np.testing.assert_allclose(f.corners[0], c, atol=1e-9)  # straight sides: the lines give the corners back
    assert np.nanmax(f.rms_px) < 1e-9
    # points moved 0.2 px outward (away from the centre) along their side's normal: error +0.2 each
    centre = c.mean(0)
    n = f.normal[0][lab]
    n = n * np.sign(((np.c_[x, y] - centre) * n).sum(1))[:, None]
    row = Row("m", [f.corners], points=[{"x": x + 0.2 * n[:, 0], "y": y + 0.2 * n[:, 1], "label": lab}])
    e = twin.point_errors(row, [truth])
    assert e["truth_mean_px"] == pytest.approx(0.2, abs=1e-6) and e["truth_rms_px"] == pytest.approx(0.2, abs=1e-6)
    assert e["truth_points"] == len(x)


def test_spearman_and_ranks():
    r = twin.spearman([1, 2, 3, 4, np.nan], [10, 20, 40, 30, 5])
    assert r["n"] == 4 and r["rho"] == pytest.approx(0.8) and 0 < r["p"] < 1
    assert np.isnan(twin.spearman([1, 2], [1, 2])["rho"])
    np.testing.assert_array_equal(twin.ranks([0.3, 0.1, np.nan, 0.2]), [3, 1, np.nan, 2])


def test_checks():
    with pytest.raises(InputError, match="sets with a twin: zhang1998, opencv_left"):
        twin.check_set("mystery")
    assert twin.check_set("opencv_left") == "opencv_left_twin"
    assert twin.check_images(None, 5) == [0, 1, 2, 3, 4]
    assert twin.check_images([3, 1, 2], 5) == [0, 1, 2]
    for bad, match in (([1, 2], "at least 3"), ([1, 2, 9], "from 1 to 5"), ([1, 1, 2], "twice")):
        with pytest.raises(InputError, match=match):
            twin.check_images(bad, 5)
    with pytest.raises(InputError, match="--spp"):
        twin.twin_spec("zhang1998_twin", 10)
    assert twin.twin_spec("zhang1998_twin", 16).render.spp == 16


# --- the CLI --------------------------------------------------------------------------------------
def _bad(tmp_path, capsys, argv, match):
    out = tmp_path / "out"
    rc = main(["study", "twin", *argv, "-o", str(out), "--no-progress"])
    err = [line for line in capsys.readouterr().err.strip().splitlines() if not line.startswith("warning:")]
    assert rc == 2, err
    assert len(err) == 1 and match in err[0], err
    assert not out.exists()


@pytest.mark.parametrize("argv, match", [
    (["nosuchset"], "nosuchset: no twin for this set"),
    ([], "give one shipped set"),
    (["zhang1998", "zhang1998"], "give one shipped set"),
    (["zhang1998", "--images", "1,2"], "at least 3"),
    (["opencv_left", "--images", "1,2,14"], "from 1 to 13"),
    (["zhang1998", "--images", "1,x"], "comma-separated photo numbers"),
    (["zhang1998", "--spp", "10"], "--spp"),
    (["zhang1998", "--model", "Model.txt"], "--model"),
    (["zhang1998", "--methods", "nosuchmethod"], "nosuchmethod"),
    (["opencv_left", "--twin", "zhang1998_twin"], "zhang1998_twin: 5 images for 13 photos"),
    (["opencv_left", "--twin", "nosuchspec"], "nosuchspec"),
])
def test_bad_inputs_exit_2_with_one_line(tmp_path, capsys, argv, match):
    _bad(tmp_path, capsys, argv, match)


@pytest.mark.parametrize("flag", [["--spp", "16"], ["--twin", "opencv_left_twin_bent"]])
def test_twin_options_are_refused_by_board(tmp_path, capsys, flag):
    rc = main(["study", "board", "zhang1998", *flag, "-o", str(tmp_path / "b"), "--no-progress"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and flag[0] in err[0]


# --- a reduced twin run ----------------------------------------------------------------------------
@pytest.mark.slow
def test_reduced_twin_run(tmp_path, fast_variant):
    out = tmp_path / "twin"
    argv = ["study", "twin", "zhang1998", "-o", str(out), "--images", "1,2,3", "--spp", "4",
            "--methods", "canny_devernay,pae2013,erf4p_fixed11", "--no-progress"]
    assert main(argv) == 0
    report = (out / "report.md").read_text()
    assert "straightness real" in report and "## Rankings" in report and "Table 3" in report
    with open(out / "twin_vs_real.csv", newline="") as fh:
        rows = {r["row"]: r for r in csv.DictReader(fh)}
    assert list(rows) == ["canny_devernay", "pae2013", "erf4p_fixed11", "pae2013_floating"]
    for r in rows.values():
        for k in ("straightness_real_px", "straightness_twin_px", "calib_rms_real_px", "calib_rms_twin_px",
                  "loo_rms_real_px", "loo_rms_twin_px", "truth_rms_px", "truth_median_abs_px"):
            assert np.isfinite(float(r[k])), k
    assert rows["pae2013_floating"]["in_ranking"] == "False"
    line = next(ln for ln in report.splitlines() if ln.startswith("| straightness: real vs twin"))
    rho, p, n = (c.strip() for c in line.strip("|").split("|")[1:4])
    assert np.isfinite(float(rho)) and np.isfinite(float(p)) and n == "3"
    for sub in ("real", "twin"):
        assert (out / sub / "summary.csv").is_file() and (out / sub / "report.md").is_file()
    assert len(list((out / "renders").glob("*.png"))) == 3 and (out / "photo_model.json").is_file()
    # the same settings again: resumes (nothing to render) and re-makes the report; others are refused
    assert main(argv) == 0
    assert main([*argv[:-1], "--spp", "16", "--no-progress"]) == 2


@pytest.mark.slow
def test_opencv_left_twin_reproduces_the_clipped_photos_shrink(tmp_path, fast_variant):
    """OpenCV's chessboard twin (3 photos: left01 unsaturated, left03 and left05 saturated; 4 spp): the twin's points
    lie on the exact outline where the white is not clipped (|mean| < 0.02 px) and inside the dark squares where it
    is (< -0.05 px), and its squares' own corners shrink where the photos' do (Table 2b).  Table 5: a bend per view
    takes a third of the photos' residual energy (measured 0.37, p ~ 1e-23) and less than half of that on the
    twin's flat board (0.08 here: 3 views at 4 spp; 0.03 over all 13 at 256 spp), and the exact outline's corners
    need no bend deeper than 0.05 mm (0.009)."""
    import json

    out = tmp_path / "twin"
    argv = ["study", "twin", "opencv_left", "-o", str(out), "--images", "1,3,5", "--spp", "4",
            "--methods", "canny_devernay,erf4p_fixed11", "--no-progress"]
    assert main(argv) == 0
    report = (out / "report.md").read_text()
    assert "Table 2b" in report and "OpenCV's corners (cornerSubPix), real / twin" in report
    rows = {c["photo"]: c for c in json.loads((out / "corners_per_photo.json").read_text())}
    assert [rows[p]["white_saturated"] for p in ("left01.jpg", "left03.jpg", "left05.jpg")] == [False, True, True]
    assert abs(rows["left01.jpg"]["twin_truth_mean_px"]) < 0.02
    for p in ("left03.jpg", "left05.jpg"):
        assert rows[p]["twin_truth_mean_px"] < -0.05
        assert rows[p]["own_corner_outward_twin_px"] < -0.1 and rows[p]["own_corner_outward_real_px"] < -0.1
    flat = json.loads((out / "board_flatness.json").read_text())
    assert "Table 5" in report and set(flat) == {"photos", "twin", "twin, exact outline"}
    photos, twin = flat["photos"]["quadratic"], flat["twin"]["quadratic"]
    assert photos["bend_share"] > 0.25 and photos["p_value"] < 1e-10 and flat["photos"]["views"] == 3
    assert twin["bend_share"] < 0.5 * photos["bend_share"]
    assert flat["twin, exact outline"]["quadratic"]["depth_mm_median"] < 0.05


@pytest.mark.slow
def test_bent_opencv_twin_reads_its_bend_back(tmp_path, fast_variant):
    """``--twin opencv_left_twin_bent`` (each board curled as its photo's; left01, 03, 05 at 4 spp): Table 5 finds
    the bend on the twin too (measured 70 % of its residual energy here, 93 % over all 13 at 256 spp; the flat
    twin's 8 % and 3 %), its exact outline reads
    each view's curl at the coefficients the spec renders (within 0.05 mm, rescaled to the check's s), the caption
    says the twin is curled, and the header names the spec."""
    import json

    from edgetruth.render.dataset.spec import load_spec
    from edgetruth.render.scene.bend import BoardBend

    out = tmp_path / "twin"
    argv = ["study", "twin", "opencv_left", "--twin", "opencv_left_twin_bent", "-o", str(out), "--images", "1,3,5",
            "--spp", "4", "--methods", "erf4p_fixed11", "--no-progress"]
    assert main(argv) == 0
    report = (out / "report.md").read_text()
    assert "spec `opencv_left_twin_bent`" in report and "The twin's boards are curled" in report
    flat = json.loads((out / "board_flatness.json").read_text())
    assert flat["twin"]["quadratic"]["bend_share"] > 0.5 and flat["twin"]["quadratic"]["p_value"] < 1e-10
    exact = flat["twin, exact outline"]["quadratic"]
    spec = load_spec("opencv_left_twin_bent")
    s_render = 1e3 * BoardBend.of((0, 0, 0), spec.squares.black_quads_local(0.0)).scale_m
    given = np.array([spec.groups[i].board_bend_mm for i in (0, 2, 4)])
    given = given * (np.array(exact["scale_mm"])[:, None] / s_render) ** 2
    assert np.abs(np.array(exact["coefficients_mm"]) - given).max() < 0.05


@pytest.mark.slow
def test_twin_study_of_your_own_photos(tmp_path, fast_variant, capsys):
    """Your own photos (4 analytic PNG views of a 9x6 board) -> `edgetruth twin` -> `study twin PHOTOS --pattern 9x6
    --twin DIR/twin.toml` (4 spp): the report names the twin, Table 5 is there, and against its exact outline the
    twin's points are unbiased on every photo (|mean| < 0.03 px; measured ≤ 0.007), as on an unclipped, linear
    photo they should be.  A photo in the folder without the board: `edgetruth twin` leaves it out, and the study
    of the whole folder pairs the twin's images with their photos by name, with one line naming the one left."""
    import json

    import cv2

    from tests.evaluate.board.chessboard_images import write_views

    photos = tmp_path / "photos"
    photos.mkdir()
    write_views(photos, ".png")
    cv2.imwrite(str(photos / "blank.png"), np.full((480, 640), 128, np.uint8))
    assert main(["twin", str(photos), "--pattern", "9x6", "--square-m", "0.03", "-o", str(tmp_path / "mine"),
                 "--no-progress"]) == 0
    out = tmp_path / "study"
    argv = ["study", "twin", str(photos), "--pattern", "9x6", "--twin", str(tmp_path / "mine" / "twin.toml"),
            "--spp", "4", "--methods", "erf4p_fixed11,canny_devernay", "-o", str(out), "--no-progress"]
    capsys.readouterr()
    assert main(argv) == 0
    assert "has no image of blank.png; comparing the 4 photos it renders, paired by name" in capsys.readouterr().out
    report = (out / "report.md").read_text()
    assert report.startswith("# Digital twin — mine:") and "Table 5" in report
    assert "derived by `edgetruth twin` (" in report  # its measurements.json, beside the twin
    rows = json.loads((out / "corners_per_photo.json").read_text())
    means = [r["twin_truth_mean_px"] for r in rows]
    with capsys.disabled():
        print(f"twin points vs truth, mean per photo: {np.round(means, 4)}")
    assert len(rows) == 4 and max(abs(v) for v in means) < 0.03


@pytest.mark.slow  # a twin of 5 photos, rendered and studied beside them: ~18 s on 2 cores
def test_twin_study_of_your_own_squares_photos(tmp_path, fast_variant, capsys):
    """Zhang's photos as your own: `edgetruth twin --model` -> `study twin PHOTOS --model DIR/model.txt --twin
    DIR/twin.toml` (4 spp, 2 methods): both board studies run on the model's squares, the report's Table 3 has a
    twin row per photo, and Table 4 points at the measurements `edgetruth twin` wrote."""
    from edgetruth.evaluate.board.reference import shipped_set

    photos = tmp_path / "photos"
    photos.mkdir()
    for p in shipped_set("zhang1998")["photos"]:
        (photos / p.name).write_bytes(p.read_bytes())
    model = shipped_set("zhang1998")["model"]
    assert main(["twin", str(photos), "--model", str(model), "--model-unit-m", "0.0254", "-o",
                 str(tmp_path / "mine"), "--no-progress"]) == 0
    out = tmp_path / "study"
    assert main(["study", "twin", str(photos), "--model", str(tmp_path / "mine" / "model.txt"), "--twin",
                 str(tmp_path / "mine" / "twin.toml"), "--spp", "4", "--methods", "erf4p_fixed11,canny_devernay",
                 "-o", str(out), "--no-progress"]) == 0
    report = (out / "report.md").read_text()
    assert report.startswith("# Digital twin — mine:") and "derived by `edgetruth twin` (" in report
    assert sum(line.startswith("| twin 000") for line in report.splitlines()) == 5


@pytest.mark.parametrize("extra, match", [
    ([], "give one shipped set's name"),
    (["--twin", "zhang1998_twin", "--tone", "srgb"], "--tone: not an option of `study twin PHOTOS...`"),
    (["--twin", "zhang1998_twin"], "zhang1998_twin: 5 images for 4 photos"),
])
def test_your_own_photos_need_their_twin(tmp_path, capsys, extra, match):
    from tests.evaluate.board.chessboard_images import write_views

    photos = tmp_path / "photos"
    photos.mkdir()
    write_views(photos, ".png")
    _bad(tmp_path, capsys, [str(photos), "--pattern", "9x6", *extra], match)


def test_pairs_where_the_board_was_found_on_both(capsys):
    """A photo or twin image where the board study found no board takes its pair out of the comparison, with one
    line saying which (a 4-spp twin can lose a board to its noise); fewer than 3 pairs left is an input error."""
    photos, renders = ["a.jpg", "b.jpg", "c.jpg", "d.jpg"], ["0_a.png", "1_b.png", "2_c.png", "3_d.png"]
    assert twin.paired(photos, photos, renders, renders) == [0, 1, 2, 3] and capsys.readouterr().out == ""
    assert twin.paired(photos, ["a.jpg", "c.jpg", "d.jpg"], renders, ["0_a.png", "2_c.png", "3_d.png"]) == [0, 2, 3]
    assert "not found on b.jpg / 1_b.png" in capsys.readouterr().out
    with pytest.raises(InputError, match="for 2 pair"):
        twin.paired(photos, photos, renders, ["0_a.png", "3_d.png"])
