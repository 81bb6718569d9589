"""The power a chessboard photo set's tone curve has, measured at its junctions (``--tone auto``): exact renders
through known curves, OpenCV's photos, and the option end to end."""
import csv
import json
from pathlib import Path

import numpy as np
import pytest

from edgetruth.cli import main
from edgetruth.errors import InputError
from edgetruth.evaluate import method_order as mo
from edgetruth.evaluate.board.detect import chessboard as cb
from edgetruth.evaluate.board.tone import fit as tone_fit
from edgetruth.evaluate.board.inputs import BoardInputs
from edgetruth.evaluate.board.model import BoardModel
from tests.evaluate.board.chessboard_images import stored_views

FULL = 65535.0


def estimate(images, method="erf4p_fixed11"):
    inp = BoardInputs([Path(f"v{i}.png") for i in range(len(images))], cb.chessboard_model((9, 6), 1.0))
    m, kw = mo.resolve(method, mo.study_options(None))
    return tone_fit.estimate_power(inp, images, [FULL] * len(images), method, m, kw)


@pytest.mark.parametrize("power", [1.0, 2.2])
@pytest.mark.parametrize("method", ["erf4p_fixed11", "canny_devernay"])
def test_the_power_of_a_power_law_comes_back(power, method):
    """Views stored as linear ** (1 / power) (blur before the curve, as in a camera): the estimate is the power, one
    power fits every view, and at it the method's own corners meet the junctions.  Measured: 2.2004 / 1.0000
    (ERF4P-fixed11), 2.2025 / 1.0010 (Devernay); per view within 0.012; Cochran's Q p 0.10-0.37."""
    fit = estimate(stored_views(lambda v: v ** (1 / power)), method)
    assert fit.power == pytest.approx(power, abs=0.006)
    assert fit.one_power_fits and fit.q_p > 0.01
    assert np.allclose(fit.per_photo, power, atol=0.02)
    assert abs(fit.offset_fit_px) < 1e-3
    if power > 1:
        assert fit.offset_stored_px < -0.15  # the dark squares imaged small before decoding
        assert fit.ci[0] < power < fit.ci[1] or abs(fit.power - power) < 0.003


def test_a_highlight_shoulder_shows_as_a_power_rising_with_the_exposure():
    """A curve that is not a power law, (1 - exp(-3 x)) / (1 - exp(-3)), at exposures 0.3-1.0: the brighter the view,
    the more of the shoulder its edges cross and the higher its power; Cochran's Q rejects one power and the powers
    follow the white level.  Measured: per view 1.39, 1.91, 2.66, 3.57; Q 7e4; ρ = 1."""
    exposures = (0.3, 0.5, 0.75, 1.0)
    fit = estimate(stored_views(lambda x: (1 - np.exp(-3 * x)) / (1 - np.exp(-3)), exposures))
    assert not fit.one_power_fits and fit.q_p < 1e-6
    assert np.all(np.diff(fit.per_photo) > 0.3) and fit.per_photo[0] > 1.2
    assert fit.rho_white == pytest.approx(1.0)
    assert np.all(np.diff(fit.white_levels) > 0)
    # the levels are the stored ones: white 210 / 255 of the linear range through the curve
    assert fit.white_levels[-1] == pytest.approx(FULL * (1 - np.exp(-3 * 210 / 255)) / (1 - np.exp(-3)), rel=2e-3)


def test_a_clipped_white_shows_as_on_opencvs_photos():
    """Linear views with noise (SD 2 of 255) at exposures 0.8-1.4, clipped at 230 of 255: the two views whose white
    (210 x exposure) passes the clip get a power well above 1 and lose their white noise; the two below it keep
    power ~1.  What OpenCV's bright photos show (docs/board.md, Tone).  Measured: 0.971, 0.972, 1.58, 2.77; white SD
    532, 491, 0, 0 (of 65535)."""
    rng = np.random.default_rng(5)
    clip = 230 / 255 * FULL
    views = [np.clip(np.round(v + rng.normal(0.0, 2 * 257, v.shape)), 0, clip)
             for v in stored_views(lambda x: x, exposures=(0.8, 1.0, 1.2, 1.4))]
    fit = estimate(views)
    assert np.allclose(fit.per_photo[:2], 1.0, atol=0.06)
    assert 1.3 < fit.per_photo[2] < fit.per_photo[3]
    assert not fit.one_power_fits
    sd = [lv.white_sd for lv in fit.levels]
    assert min(sd[:2]) > 400 and max(sd[2:]) == 0 and fit.white_levels[2:] == [clip, clip]


def test_no_power_is_an_input_error_naming_what_to_give(monkeypatch):
    """An offset that no power in the range undoes (here +1 px everywhere, as ink spread would) is not a tone."""
    monkeypatch.setattr(tone_fit, "outward_offsets", lambda row, jn: [np.ones(8) for _ in row.sides])
    with pytest.raises(InputError, match="no power from 0.4 to 3 .* give --tone stored or power:G"):
        estimate(stored_views(lambda v: v)[:3])


def test_separate_squares_have_no_junctions_to_measure_at():
    squares = np.array([[[0, 0], [1, 0], [1, 1], [0, 1]]], float)
    inp = BoardInputs([Path("a.png")] * 3, BoardModel(squares, "test"))
    with pytest.raises(InputError, match="chessboard's junctions"):
        tone_fit.estimate_power(inp, [np.zeros((4, 4))] * 3, [255.0] * 3, "erf4p_fixed11", "erf4p_fixed11", {})


# --------------------------------------------------------------------------------- OpenCV's photos, end to end
def _rows(path):
    with open(path, newline="") as fh:
        return {r["row"]: r for r in csv.DictReader(fh)}


@pytest.fixture(scope="module")
def opencv_auto(tmp_path_factory):
    out = tmp_path_factory.mktemp("tone") / "run"
    rc = main(["study", "board", "opencv_left", "--tone", "auto", "-o", str(out),
               "--methods", "canny_devernay,erf4p_fixed11", "--no-progress"])
    return rc, out


def test_opencvs_photos_power_rises_with_their_white_level(opencv_auto):
    """A finding, measured (docs/board.md, Tone): decoded with one power (1.31, CI 1.10-1.57) the dark squares no
    longer image small on average, but no one power fits the photos (Cochran's Q 3470): per photo 0.86-2.24, in the
    order of their white level (Spearman ρ 0.98): the brighter photos' whites, 246-250, are clipped flat (their
    centres' noise SD 0.00-0.34 against 1.8-2.2 DN).  The junction corners, and so the calibration, do not move
    (0.150 px)."""
    rc, out = opencv_auto
    assert rc == 0
    fit = json.loads((out / "tone.json").read_text())["fit"]
    assert 1.2 < fit["power"] < 1.45 and fit["ci95"][0] < fit["power"] < fit["ci95"][1]
    assert fit["offset_stored_px"] < -0.15 and abs(fit["offset_fit_px"]) < 0.002
    assert not fit["one_power_fits"] and fit["cochran_q_p"] < 1e-6
    assert fit["spearman_rho_power_white"] > 0.8 and fit["spearman_p_power_white"] < 1e-3
    per = fit["per_photo"]
    assert len(per) == 13 and min(per.values()) < 1.1 and max(per.values()) > 1.8
    rows = _rows(out / "summary.csv")
    assert abs(float(rows["erf4p_fixed11"]["own_corner_outward_px"])) < 0.002
    assert abs(float(rows["canny_devernay"]["own_corner_outward_px"])) < 0.03
    for m in ("canny_devernay", "erf4p_fixed11"):
        assert float(rows[m]["calib_rms_px"]) == pytest.approx(0.151, abs=0.004)
        assert float(rows[m]["calib_rms_px"]) < float(rows["opencv_corners"]["calib_rms_px"])
    text = (out / "report.md").read_text()
    assert "- Tone (`--tone auto:erf4p_fixed11`): power 1.3" in text
    assert "One power does not describe every photo (Cochran's Q" in text
    assert "## Tone per photo (`--tone auto`)" in text
    # the bright photos' white squares are clipped flat: their centres' noise is gone
    white, sd = fit["white_level"], fit["white_sd"]
    assert max(sd[k] for k in sd if white[k] >= 246) < 0.5 < 1.5 < min(sd[k] for k in sd if white[k] < 240)


def test_a_given_tone_is_recorded_and_another_is_refused_in_the_same_directory(tmp_path, capsys):
    out = tmp_path / "run"
    base = ["study", "board", "opencv_left", "-o", str(out), "--methods", "canny_devernay", "--no-progress"]
    assert main([*base, "--tone", "power:1.3"]) == 0
    tone = json.loads((out / "tone.json").read_text())
    assert tone["spec"] == "power:1.3" and tone["fit"] is None
    assert "- Tone (`--tone power:1.3`): the stored values v decoded as 255·(v/255)^1.3." in (
        out / "report.md").read_text()
    capsys.readouterr()
    assert main([*base, "--tone", "srgb"]) == 2
    assert "tone" in capsys.readouterr().err
    assert (out / "tone.json").exists() and (out / "report.md").exists()  # nothing written is lost


@pytest.mark.parametrize("argv, says", [
    (["board", "zhang1998", "--tone", "auto"], "--tone auto: measures the tone at a chessboard's junctions"),
    (["board", "opencv_left", "--tone", "gamma"], "--tone gamma: unknown tone"),
    (["board", "opencv_left", "--tone", "power:9"], "--tone power:9: the power must be"),
    (["board", "opencv_left", "--tone", "auto:patch_esf_fit"], "needs a camera model"),
    (["board", "opencv_left", "--tone", "auto:nope"], "--tone auto:nope: unknown method"),
    (["synthetic", "--tone", "srgb"], "--tone: not an option of `study synthetic`"),
])
def test_bad_tones_are_one_line_and_exit_2(tmp_path, capsys, argv, says):
    rc = main(["study", *argv, "-o", str(tmp_path / "out"), "--no-progress"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and says in err[0], err
    assert not (tmp_path / "out").exists()
