"""What a twin needs, measured on chessboard photos (``twin.measure``): the JPEG quality read from the file, a photo
without the board left out and named, photos of another bit depth and 16-bit values with a tone curve refused."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from edgetruth.errors import InputError
from edgetruth.evaluate.board.detect import chessboard as cb
from edgetruth.evaluate.board.twin import measure as tm
from tests.evaluate.board.chessboard_images import ROTATIONS, render
from tests.evaluate.board.chessboard_images import write_views as views


@pytest.mark.parametrize("quality", [10, 50, 75, 95])
def test_jpeg_quality_is_read_from_the_file(tmp_path, quality):
    """OpenCV's encoder (libjpeg) stores the IJG table at the quality asked for: read back exactly; a PNG has
    none."""
    img = np.random.default_rng(0).integers(0, 255, (32, 32)).astype(np.uint8)
    cv2.imwrite(str(tmp_path / "a.jpg"), img, [cv2.IMWRITE_JPEG_QUALITY, quality])
    cv2.imwrite(str(tmp_path / "a.png"), img)
    assert tm.jpeg_quality(tmp_path / "a.jpg") == (quality, True)
    assert tm.jpeg_quality(tmp_path / "a.png") is None


def test_ijg_tables():
    """Quality 50 is the Annex K table itself; 100 is all ones; the scaling is libjpeg's (quality 75: half)."""
    assert np.array_equal(tm.ijg_table(50), tm.IJG_LUMA)
    assert np.all(tm.ijg_table(100) == 1)
    assert np.array_equal(tm.ijg_table(75), np.clip((tm.IJG_LUMA * 50 + 50) // 100, 1, 255))
    assert sorted(tm.ZIGZAG) == list(range(64))


def test_a_photo_without_the_board_is_left_out_and_named(tmp_path):
    """A photo where the board is not found is left out, named with why (as calibrate leaves it out); the others are
    measured in the order given, each with its own bend.  Fewer than 3 boards: one InputError naming the photos."""
    paths, _ = views(tmp_path, ".png")
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((480, 640), 128, np.uint8))
    m = tm.measure_chessboard([paths[0], blank, *paths[1:]], (9, 6))
    assert m["left_out"] == [{"photo": "blank.png", "why": "the 9x6 board was not found on it"}]
    assert [p["photo"] for p in m["photos"]] == [p.name for p in paths]
    assert all(len(p["bend_squares"]["coefficients"]) == 3 for p in m["photos"])
    whole = tm.measure_chessboard(paths, (9, 6))
    assert whole["left_out"] == [] and np.allclose(whole["K"], m["K"], rtol=1e-12)
    assert [p["bend_squares"] for p in whole["photos"]] == [p["bend_squares"] for p in m["photos"]]
    with pytest.raises(InputError, match=r"found in only 2 of 3 photos \(need >= 3; not found: blank.png\)"):
        tm.measure_chessboard([*paths[:2], blank], (9, 6))


def test_photos_of_two_bit_depths_are_refused(tmp_path):
    """An 8-bit set with one 16-bit photo: one InputError naming that photo (one camera's output, one depth)."""
    paths, _ = views(tmp_path, ".png")
    img = cv2.imread(str(paths[0]), cv2.IMREAD_GRAYSCALE).astype(np.uint16) * 16
    cv2.imwrite(str(tmp_path / "deep.png"), img)
    with pytest.raises(InputError, match="deep.png: 16-bit among 8-bit photos"):
        tm.measure_chessboard([*paths, tmp_path / "deep.png"], (9, 6))


def test_colour_photos_are_read_as_their_luma(tmp_path):
    """Colour JPEGs (a phone's): the same 4 views stored as colour (a warm cast: R x 1.05, B x 0.9) at quality 75 are
    measured on their luma (float) as 8-bit photos (full scale 255), the camera as from the gray views (fx 600 to
    0.1 %: measured the same to 0.05 px) and their quality read from the file; before, an 8-bit colour photo was
    refused as 'float64 values'."""
    gray, _ = views(tmp_path, ".jpg")
    paths = []
    for p in gray:
        g = cv2.imread(str(p), cv2.IMREAD_GRAYSCALE).astype(float)
        bgr = np.clip(np.round(np.dstack([0.9 * g, g, 1.05 * g])), 0, 255).astype(np.uint8)
        paths.append(tmp_path / f"c_{p.name}")
        cv2.imwrite(str(paths[-1]), bgr, [cv2.IMWRITE_JPEG_QUALITY, 75])
    m = tm.measure_chessboard(paths, (9, 6))
    assert m["full_scale"] == 255.0 and abs(m["K"][0][0] - 600.0) < 0.6
    assert all(p["jpeg_quality"] == {"quality": 75, "exact": True} for p in m["photos"])
    assert m["value_step"] == 1 and m["max_value"] <= 255


def raw_views(power: float, black_dn: float = 0.0, seed: int = 1) -> list[np.ndarray]:
    """``ROTATIONS``' views of a 12-bit linear sensor (15,000 e- at white, 10 e- read noise, K 0.25 DN/e-) at four
    exposures, stored as 16-bit: as they are plus ``black_dn`` (``power`` 1), or through the curve
    65535 (x / 4095)^(1/power) from that black (a 16-bit export with a tone curve)."""
    rng = np.random.default_rng(seed)
    out = []
    for r, k in zip(ROTATIONS, (1.0, 0.6, 0.8, 0.4)):
        img, _ = render((9, 6), r, sigma_px=0.7)
        dn = 0.25 * (rng.poisson(k * img / 255.0 * 15000.0) + rng.normal(0.0, 10.0, img.shape))
        v = dn + black_dn if power == 1.0 else black_dn + (65535.0 - black_dn) * np.clip(dn / 4095.0, 0, 1) ** (
            1.0 / power)
        out.append(np.clip(np.round(v), 0, 65535).astype(np.uint16))
    return out


@pytest.mark.parametrize("power, black_dn", [(1.0, 200.0), (1.0, 0.0), (1.8, 0.0), (2.2, 0.0)])
def test_raw_tone_reads_a_linear_sensor_as_1_and_refuses_a_tone_curve(tmp_path, power, black_dn):
    """16-bit values read at the junctions: a linear sensor's a power of 1 whatever its black level (to 0.01:
    measured 0.999 at black 0 and 200), rendered linear; ProPhoto's 1.8 and sRGB's 2.2 their own (to 0.01:
    measured 1.801, 2.204), refused with one InputError naming the photos, the power and the fix."""
    model = cb.chessboard_model((9, 6), 1.0)
    images = raw_views(power, black_dn)
    paths = [tmp_path / f"v{i}.png" for i in range(len(images))]
    rows = [{"photo": p.name, "white_saturated": False} for p in paths]
    assert abs(tm.measure_tone(paths, images, rows, model, full_scale=65535.0)["power"] - power) < 0.01
    if power == 1.0:
        tone = tm.raw_tone(paths, images, rows, model)
        assert tone["output_gamma"] == 1.0 and "read a power of 0.99" in tone["note"]
    else:
        with pytest.raises(InputError, match=rf"v0.png \.\.\. \(4 16-bit photos\): their edges read a tone power of "
                                             rf"{power:.1f}.*dcraw -4 -T"):
            tm.raw_tone(paths, images, rows, model)


def test_16_bit_photos_with_a_tone_curve_are_refused_before_a_twin(tmp_path):
    """The whole measurement on 16-bit PNGs through ProPhoto's curve (1.8): refused, one line (their noise alone
    would have passed: a photon-transfer slope of 2 DN/e- and a print contrast of 2.5 for 5.6)."""
    paths = []
    for i, img in enumerate(raw_views(1.8)):
        paths.append(tmp_path / f"v{i}.png")
        cv2.imwrite(str(paths[-1]), img)
    with pytest.raises(InputError, match="tone power of 1.80"):
        tm.measure_chessboard(paths, (9, 6))
