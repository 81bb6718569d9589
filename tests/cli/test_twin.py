"""`edgetruth twin`: a twin spec of your own chessboard photos, written whole or not at all."""
from __future__ import annotations

import json
import re
import shlex

import pytest

from edgetruth.cli import main
from tests.evaluate.board.chessboard_images import write_views


@pytest.mark.slow
def test_twin_of_four_views(tmp_path, capsys):
    """4 PNG views -> DIR/twin.toml (one group per view, PNG out, the camera by relative path), DIR/camera.toml
    (fx 600 to 0.1 %) and DIR/measurements.json; the spec loads from any directory; the printed lines say how to
    render it."""
    from edgetruth.render.dataset.spec import load_spec

    (tmp_path / "photos").mkdir()
    write_views(tmp_path / "photos", ".png")
    out = tmp_path / "my twin"
    rc = main(["twin", str(tmp_path / "photos"), "--pattern", "9x6", "--square-m", "0.03", "-o", str(out),
               "--no-progress"])
    assert rc == 0 and sorted(p.name for p in out.iterdir()) == ["camera.toml", "measurements.json", "twin.toml"]
    spec = load_spec(out / "twin.toml")
    assert spec.name == "my_twin" and spec.n_images == 4 and spec.sensor.output == "srgb8"
    assert spec.camera.fx_px == pytest.approx(600.0, rel=1e-3)
    m = json.loads((out / "measurements.json").read_text())
    assert m["pattern"] == [9, 6] and len(m["photos"]) == 4 and m["image_size"] == [640, 480]
    assert m["full_scale"] == 255.0 and m["max_value"] <= 255 and "flat_noise" not in m["photos"][0]
    text = capsys.readouterr().out
    assert "twin: 4 photos" in text and "edgetruth render" in text
    # the study that compares twin and photos, as a command to paste: the photos and pattern as given
    study = shlex.split(re.search(r"compare: `(.*)`", text).group(1))
    assert study == ["edgetruth", "study", "twin", str(tmp_path / "photos"), "--pattern", "9x6", "--twin",
                     str(out / "twin.toml"), "-o", "RUN"]
    # a read noise given is the twin's, and its header says so
    assert main(["twin", str(tmp_path / "photos"), "--pattern", "9x6", "--square-m", "0.03", "-o",
                 str(tmp_path / "r"), "--read-noise-e", "7.5", "--no-progress"]) == 0
    assert load_spec(tmp_path / "r" / "twin.toml").sensor.dark_noise_e == 7.5
    assert "7.5 e- read noise," in " ".join((tmp_path / "r" / "twin.toml").read_text().replace("#", "").split())


def test_twin_refuses_bad_input_before_writing(tmp_path, capsys):
    """Each bad input: exit 2, one line naming it; an existing twin.toml is left as it was."""
    (tmp_path / "photos").mkdir()
    paths, _ = write_views(tmp_path / "photos", ".png")
    out = tmp_path / "t"
    out.mkdir()
    (out / "twin.toml").write_text("# mine\n")
    base = ["twin", "--pattern", "9x6", "--square-m", "0.03", "--no-progress"]
    cases = [
        ([str(tmp_path / "photos"), "-o", str(out)], "holds a twin.toml already"),
        ([str(p) for p in paths[:2]] + ["-o", str(tmp_path / "u")], "needs 3 or more views"),
        ([str(tmp_path / "photos"), "-o", str(tmp_path / "u"), "--name", "a b"], "--name 'a b'"),
        ([str(tmp_path / "photos"), "-o", str(tmp_path / "u"), "--pitch-um", "0"], "--pitch-um 0"),
        ([str(tmp_path / "photos"), "-o", str(tmp_path / "u"), "--square-m", "-1"], "--square-m"),
        ([str(tmp_path / "photos"), "-o", str(tmp_path / "u"), "--read-noise-e", "-2"], "--read-noise-e -2"),
        ([str(tmp_path / "photos"), "-o", str(tmp_path / "u"), "--black-dn", "64"], "--black-dn: for 16-bit"),
    ]
    for extra, words in cases:
        capsys.readouterr()
        assert main([*base, *extra]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and words in err[0], (extra, err)
    assert (out / "twin.toml").read_text() == "# mine\n" and not (tmp_path / "u").exists()


def test_a_photo_without_the_board_is_left_out_with_a_warning(tmp_path, capsys):
    """A folder with one photo that shows no board: the twin of the other four, one warning line naming it, and the
    study command printed with the folder as given (the study pairs the twin's images with the photos by name)."""
    import cv2
    import numpy as np

    from edgetruth.render.dataset.spec import load_spec

    (tmp_path / "photos").mkdir()
    paths, _ = write_views(tmp_path / "photos", ".png")
    cv2.imwrite(str(tmp_path / "photos" / "blank.png"), np.full((480, 640), 128, np.uint8))
    out = tmp_path / "t"
    assert main(["twin", str(tmp_path / "photos"), "--pattern", "9x6", "--square-m", "0.03", "-o", str(out),
                 "--no-progress"]) == 0
    cap = capsys.readouterr()
    assert cap.err.strip().splitlines() == ["warning: twin: blank.png: the 9x6 board was not found on it; left out "
                                            "(the twin has one image per photo it measured)"]
    assert load_spec(out / "twin.toml").n_images == 4
    study = shlex.split(re.search(r"compare: `(.*)`", cap.out).group(1))
    assert study[3:6] == [str(tmp_path / "photos"), "--pattern", "9x6"]


def test_twin_bend_curls_each_board(tmp_path):
    """`--bend`: every group carries its photo's quadratic curl (flat analytic views: noise, each term within
    0.05 mm; measured ≤ 0.02), the header says so, and the renderer's scale the curls were converted to is the one
    the spec's board has (``render.scene.bend.BoardBend``)."""
    import numpy as np

    from edgetruth.evaluate.board.twin.derive import bend_mm
    from edgetruth.render.dataset.spec import load_spec
    from edgetruth.render.scene.bend import BoardBend

    (tmp_path / "photos").mkdir()
    write_views(tmp_path / "photos", ".png")
    out = tmp_path / "bent"
    assert main(["twin", str(tmp_path / "photos"), "--pattern", "9x6", "--square-m", "0.03", "-o", str(out),
                 "--bend", "--no-progress"]) == 0
    spec = load_spec(out / "twin.toml")
    curls = np.array([g.board_bend_mm for g in spec.groups])
    assert curls.shape == (4, 3) and np.abs(curls).max() < 0.05
    assert "- bend: each photo's board curled" in (out / "twin.toml").read_text()
    m = json.loads((out / "measurements.json").read_text())
    s_render = BoardBend.of((0, 0, 0), spec.squares.black_quads_local(0.0)).scale_m * 1e3
    # this board's ring is whole (1 square each way): s = (8 + 2) x 30 mm / 2 = 150 mm, as the renderer has it
    assert s_render == pytest.approx(150.0, abs=1e-9)
    assert np.allclose(bend_mm(m, [1.0, 1.0], 0.03), curls, atol=1e-5)
    print(f"flat views' curls: max |term| {np.abs(curls).max():.4f} mm")


def _zhang_folder(tmp_path):
    """A folder of Zhang's 5 photos alone, and his model file."""
    from edgetruth.evaluate.board.reference import shipped_set

    s = shipped_set("zhang1998")
    photos = tmp_path / "zhang"
    photos.mkdir()
    for p in s["photos"]:
        (photos / p.name).write_bytes(p.read_bytes())
    return photos, s["model"]


@pytest.mark.slow
def test_twin_of_a_board_of_separate_squares(tmp_path, capsys):
    """Zhang's 5 photos with `--model Model.txt --model-unit-m 0.0254`: DIR holds the model (its bytes), the spec
    renders from it (5 groups, poses in inches), the tone is the assumed power (2.2, or --tone-power's) and says so,
    and the study command to paste names the twin's model."""
    from edgetruth.render.dataset.spec import load_spec

    photos, model = _zhang_folder(tmp_path)
    out = tmp_path / "zt"
    assert main(["twin", str(photos), "--model", str(model), "--model-unit-m", "0.0254", "-o", str(out),
                 "--no-progress"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["camera.toml", "measurements.json", "model.txt", "twin.toml"]
    assert (out / "model.txt").read_bytes() == model.read_bytes()
    spec = load_spec(out / "twin.toml")
    assert spec.n_images == 5 and spec.sensor.output == "srgb8" and spec.sensor.output_gamma == 2.2
    assert spec.squares.model_unit_m == 0.0254 and spec.squares.n_squares == 64
    text = " ".join((out / "twin.toml").read_text().replace("#", "").split())
    assert "not measurable on separate squares (no junctions); a power of 2.2 assumed (--tone-power)" in text
    m = json.loads((out / "measurements.json").read_text())
    assert m["board"]["kind"] == "model" and m["board"]["squares"] == 64 and "t_model" in m["photos"][0]
    cap = capsys.readouterr().out
    assert "output_gamma 2.2 (assumed, --tone-power)" in cap
    study = shlex.split(re.search(r"compare: `(.*)`", cap).group(1))
    assert study == ["edgetruth", "study", "twin", str(photos), "--model", str(out / "model.txt"), "--twin",
                     str(out / "twin.toml"), "-o", "RUN"]
    assert main(["twin", str(photos), "--model", str(model), "--model-unit-m", "0.0254", "--tone-power", "1", "-o",
                 str(tmp_path / "lin"), "--no-progress"]) == 0
    assert load_spec(tmp_path / "lin" / "twin.toml").sensor.output_gamma == 1.0
    # the shipped set by its name: the study command names its folder (`study twin zhang1998` is the set's own study)
    capsys.readouterr()
    assert main(["twin", "zhang1998", "--model", str(model), "--model-unit-m", "0.0254", "-o", str(tmp_path / "byname"),
                 "--no-progress"]) == 0
    study = shlex.split(re.search(r"compare: `(.*)`", capsys.readouterr().out).group(1))
    assert study[3] == str(model.parent) and study[4] == "--model"


def test_twin_board_options_are_checked(tmp_path, capsys):
    """A chessboard's options with a model's, or either's half: exit 2, one line naming the option and the fix;
    nothing written."""
    photos, model = _zhang_folder(tmp_path)
    o = ["-o", str(tmp_path / "u"), "--no-progress"]
    cases = [
        (["--pattern", "9x6", "--square-m", "0.03", "--model", str(model)], "either --pattern"),
        ([], "either --pattern"),
        (["--pattern", "9x6"], "--pattern needs --square-m"),
        (["--pattern", "9x6", "--square-m", "0.03", "--tone-power", "2"], "--tone-power: for --model"),
        (["--pattern", "9x6", "--square-m", "0.03", "--model-unit-m", "1"], "--model-unit-m: for --model"),
        (["--model", str(model)], "--model needs --model-unit-m"),
        (["--model", str(model), "--model-unit-m", "0"], "--model-unit-m '0'"),
        (["--model", str(model), "--model-unit-m", "1", "--square-m", "0.03"], "--square-m: for --pattern"),
        (["--model", str(model), "--model-unit-m", "1", "--bend"], "--bend: for chessboards only"),
        (["--model", str(model), "--model-unit-m", "1", "--tone-power", "9"], "--tone-power 9"),
        (["--model", str(tmp_path / "none.txt"), "--model-unit-m", "1"], "none.txt"),
    ]
    for extra, words in cases:
        capsys.readouterr()
        assert main(["twin", str(photos), *extra, *o]) == 2, extra
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and words in err[0], (extra, err)
    assert not (tmp_path / "u").exists()


def test_twin_and_study_twin_of_a_circle_grid(tmp_path, capsys, fast_variant):
    """`edgetruth twin sony_hx5v_circles --pattern circles:10x8 --square-m 0.025`: one group per photo the grid is
    found on (4 of 6, the others named), a circles_grid twin; the `study twin` it prints, run at 16 spp with three
    methods, writes a report with the twin ÷ real figures and rankings, and on the twin every method's corrected
    centres lie within 0.05 px RMS of the truth (measured 0.01-0.02 px at 256 spp; CannyPixel 0.085) and OpenCV's
    blob centroids farther (0.15 px: their perspective and threshold bias); with `--budget jpeg` the error budget's
    table, the ellipse residual in straightness' place."""
    out = tmp_path / "tw"
    assert main(["twin", "sony_hx5v_circles", "--pattern", "circles:10x8", "--square-m", "0.025", "-o", str(out),
                 "--no-progress"]) == 0
    text = capsys.readouterr()
    assert "image00000.jpg" in text.err and "image00004.jpg" in text.err
    scene = (out / "twin.toml").read_text()
    assert scene.count('kind = "circles_grid"') == 4 and "[spec.circles_grid]" in scene
    study = shlex.split(re.search(r"compare: `(.*)`", text.out).group(1))
    assert study[4:9] == ["--pattern", "circles:10x8", "--square", "0.025", "--twin"]
    run = tmp_path / "run"
    assert main(["study", "twin", *study[3:-2], "-o", str(run), "--spp", "16", "--images", "1,2,3", "--methods",
                 "erf4p_fixed11,canny_devernay,canny_pixel", "--variant", fast_variant, "--budget", "jpeg",
                 "--no-progress"]) == 0
    report = (run / "report.md").read_text()
    assert "twin ÷ real" in report and "ellipse residual: real vs twin" in report
    lines = {ln["row"]: ln for ln in json.loads((run / "twin_vs_real.json").read_text())["rows"]}
    assert lines["erf4p_fixed11"]["centre_rms_px"] < 0.05 and lines["canny_devernay"]["centre_rms_px"] < 0.05
    assert lines["opencv_blobs"]["centre_rms_px"] > lines["erf4p_fixed11"]["centre_rms_px"]
    assert (run / "real" / "report.md").is_file() and (run / "twin" / "report.md").is_file()
    # the error budget of the circle twin: the ellipse residual in straightness' place, the JPEG term off
    budget = json.loads((run / "budget.json").read_text())
    assert [r["term"] for r in budget["rows"]] == ["", "all", "seeds", "jpeg", "unexplained"]
    assert "ellipse residual (px) | ÷ real" in report
    assert (run / "budget" / "jpeg" / "twin.toml").is_file()
