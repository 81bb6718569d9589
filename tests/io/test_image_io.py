"""Real photographs in: `edgetruth.image_io.read_gray` reads 8/16-bit PNG (palette too), JPEG and TIFF,
turns colour into gray by one stated rule, honours the EXIF orientation, drops an opaque alpha and
refuses any other, and gives one line for a bad file.

References are independent of the code under test: hand-computed luma values, Pillow's own
decoding and EXIF transpose, and the orientation definitions of the EXIF standard (tag 274).
"""
from __future__ import annotations

import struct

import cv2
import numpy as np
import pytest
from PIL import Image, ImageOps

from edgetruth.errors import InputError
from edgetruth.image_io import full_scale, read_gray, read_gray_scaled
from edgetruth.resources import real_set

RNG = np.random.default_rng(20260112)
RGB8 = RNG.integers(0, 256, (12, 16, 3), dtype=np.uint8)  # R, G, B order (Pillow's)

#: EXIF 2.3, tag 0x0112: how the stored rows/columns map to the upright picture
UPRIGHT = {
    1: lambda a: a,
    2: lambda a: a[:, ::-1],                      # mirrored left-right
    3: lambda a: a[::-1, ::-1],                   # turned 180 degrees
    4: lambda a: a[::-1],                         # mirrored top-bottom
    5: lambda a: a.transpose(1, 0, *range(2, a.ndim)),           # transposed (main diagonal)
    6: lambda a: np.rot90(a, -1),                 # stored 90 degrees anticlockwise: turn clockwise
    7: lambda a: a[::-1, ::-1].transpose(1, 0, *range(2, a.ndim)),  # transverse (anti-diagonal)
    8: lambda a: np.rot90(a, 1),                  # stored 90 degrees clockwise: turn anticlockwise
}


def _exif(orientation: int) -> Image.Exif:
    ex = Image.Exif()
    ex[0x0112] = orientation
    return ex


def _one_line_error(call, *expected: str) -> str:
    with pytest.raises(InputError) as info:
        call()
    msg = str(info.value)
    assert "\n" not in msg
    for e in expected:
        assert e in msg, (e, msg)
    return msg


# --- formats ---------------------------------------------------------------------------------------
def test_gray_palette_png_is_returned_as_its_gray_levels(tmp_path):
    """A palette PNG whose entries are all gray: OpenCV expands it to three equal channels, returned
    as the stored gray levels (uint8, unchanged)."""
    g = RNG.integers(0, 256, (10, 13), dtype=np.uint8)
    pal = Image.fromarray(g, "L").convert("P")
    assert pal.mode == "P"
    pal.save(tmp_path / "gray_pal.png")
    got = read_gray(tmp_path / "gray_pal.png")
    assert got.dtype == np.uint8 and np.array_equal(got, g)


def test_zhang_palette_png_is_colour_and_read_by_the_luma_rule():
    """Zhang's CalibIm2.png is an 8-bit palette PNG whose entries are NOT gray (a 3-3-2 colour palette,
    dithered: entries such as (0, 36, 85)), so it is colour: float64 luma of Pillow's RGB decode, 640x480.
    Measured here: 74 distinct luma values (58 after OpenCV's rounding to 8-bit gray)."""
    p = real_set("zhang1998") / "CalibIm2.png"
    im = Image.open(p)
    assert im.mode == "P"
    pal = np.asarray(im.getpalette(), int).reshape(-1, 3)[np.unique(np.asarray(im))]
    assert np.any(pal[:, 0] != pal[:, 1])
    rgb = np.asarray(im.convert("RGB")).astype(np.float64)
    img = read_gray(p)
    assert img.dtype == np.float64 and img.shape == (480, 640)
    np.testing.assert_allclose(img, 0.299 * rgb[..., 0] + 0.587 * rgb[..., 1] + 0.114 * rgb[..., 2], rtol=0, atol=1e-9)
    assert len(np.unique(img)) == 74


def test_colour_palette_png_follows_the_luma_rule(tmp_path):
    pal = Image.fromarray(RGB8).quantize(colors=16)
    pal.save(tmp_path / "pal.png")
    rgb = np.asarray(pal.convert("RGB")).astype(np.float64)
    want = 0.299 * rgb[..., 0] + 0.587 * rgb[..., 1] + 0.114 * rgb[..., 2]
    got = read_gray(tmp_path / "pal.png")
    assert got.dtype == np.float64
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)


def test_16bit_gray_png_keeps_every_level(tmp_path):
    a = RNG.integers(0, 65536, (9, 11), dtype=np.uint16)
    a[0, :3] = [0, 1, 65535]
    cv2.imwrite(str(tmp_path / "g16.png"), a)
    got = read_gray(tmp_path / "g16.png")
    assert got.dtype == np.uint16 and np.array_equal(got, a)


def test_16bit_colour_tiff_luma_matches_a_hand_computation(tmp_path):
    """Stored R, G, B -> 0.299 R + 0.587 G + 0.114 B in float64, not rounded (16-bit precision kept)."""
    rgb = np.zeros((3, 4, 3), np.uint16)
    rgb[0, 0] = (1000, 2000, 3000)   # 299 + 1174 + 342 = 1815
    rgb[0, 1] = (65535, 0, 0)        # 0.299 * 65535 = 19594.965
    rgb[0, 2] = (0, 0, 1)            # 0.114
    rgb[0, 3] = (0, 1, 0)            # 0.587: one 16-bit level of green survives
    rgb[1, 0] = (65535, 65535, 65535)  # 65535 (the weights sum to 1)
    rgb[1, 1] = (12345, 54321, 777)  # 3691.155 + 31886.427 + 88.578 = 35666.16
    cv2.imwrite(str(tmp_path / "c16.tif"), rgb[..., ::-1])  # OpenCV writes BGR arrays as RGB files
    got = read_gray(tmp_path / "c16.tif")
    assert got.dtype == np.float64 and got.shape == (3, 4)
    np.testing.assert_allclose(got[0], [1815.0, 19594.965, 0.114, 0.587], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(got[1, :2], [65535.0, 35666.16], rtol=1e-12)
    assert got[2, 3] == 0.0


@pytest.mark.parametrize("suffix", [".png", ".tif", ".bmp"])
def test_channel_selection_takes_r_g_b_as_stored(tmp_path, suffix):
    """--channel r/g/b: the file's red/green/blue channel (not OpenCV's B, G, R positions), dtype kept."""
    rgb = np.empty((6, 7, 3), np.uint8)
    rgb[..., 0], rgb[..., 1], rgb[..., 2] = 10, 20, 30
    rgb[2, 3] = (200, 100, 50)
    Image.fromarray(rgb).save(tmp_path / f"c{suffix}")
    for ch, k in (("r", 0), ("g", 1), ("b", 2)):
        got = read_gray(tmp_path / f"c{suffix}", channel=ch)
        assert got.dtype == np.uint8 and np.array_equal(got, rgb[..., k]), ch
    np.testing.assert_allclose(read_gray(tmp_path / f"c{suffix}")[2, 3], 0.299 * 200 + 0.587 * 100 + 0.114 * 50)


def test_16bit_channel_selection_keeps_uint16(tmp_path):
    bgr = RNG.integers(0, 65536, (5, 6, 3), dtype=np.uint16)
    cv2.imwrite(str(tmp_path / "c16.png"), bgr)
    for ch, k in (("r", 2), ("g", 1), ("b", 0)):
        got = read_gray(tmp_path / "c16.png", channel=ch)
        assert got.dtype == np.uint16 and np.array_equal(got, bgr[..., k])


@pytest.mark.parametrize("channel", ["luma", "r", "g", "b"])
def test_gray_and_equal_channel_images_are_returned_unchanged(tmp_path, channel):
    g = RNG.integers(0, 256, (8, 9), dtype=np.uint8)
    cv2.imwrite(str(tmp_path / "gray.png"), g)
    Image.fromarray(np.dstack([g, g, g])).save(tmp_path / "rgb_equal.png")
    for name in ("gray.png", "rgb_equal.png"):
        got = read_gray(tmp_path / name, channel=channel)
        assert got.dtype == np.uint8 and np.array_equal(got, g), name


def test_gray_jpeg_of_real_set_keeps_its_size_and_values():
    p = real_set("opencv_left") / "left01.jpg"
    img = read_gray(p)
    assert img.dtype == np.uint8 and img.shape == (480, 640)
    assert np.array_equal(img, np.asarray(Image.open(p).convert("L")))


def test_an_unknown_channel_is_one_line():
    _one_line_error(lambda: read_gray(real_set("opencv_left") / "left01.jpg", channel="red"), "'red'", "luma")


# --- EXIF orientation ------------------------------------------------------------------------------
def test_jpeg_with_orientation_6_is_turned_clockwise(tmp_path):
    """The same pixels stored twice, tagged upright (1) and 'turn 90 degrees clockwise' (6)."""
    for o in (1, 6):
        Image.fromarray(RGB8).save(tmp_path / f"o{o}.jpg", exif=_exif(o), quality=100, subsampling=0)
    upright, turned = read_gray(tmp_path / "o1.jpg", "g"), read_gray(tmp_path / "o6.jpg", "g")
    assert upright.shape == (12, 16) and turned.shape == (16, 12)
    assert np.array_equal(turned, np.rot90(upright, -1))
    assert np.array_equal(turned[0, :], upright[::-1, 0])  # the top row is the old left column, bottom up
    # Pillow's own EXIF transpose of the same file agrees
    assert np.array_equal(turned, np.asarray(ImageOps.exif_transpose(Image.open(tmp_path / "o6.jpg")))[..., 1])


@pytest.mark.parametrize("orientation", range(1, 9))
def test_png_every_orientation_matches_the_exif_definition(tmp_path, orientation):
    f = tmp_path / f"o{orientation}.png"
    Image.fromarray(RGB8).save(f, exif=_exif(orientation))
    got = read_gray(f, "r")
    assert np.array_equal(got, UPRIGHT[orientation](RGB8)[..., 0])


@pytest.mark.parametrize("orientation", [3, 6, 8])
def test_tiff_orientation_is_applied_once(tmp_path, orientation):
    """OpenCV 5.0's TIFF decoder itself applies tags 2-4 and fails on 5-8; the result must still be upright."""
    f = tmp_path / f"o{orientation}.tif"
    Image.fromarray(RGB8).save(f, exif=_exif(orientation))
    assert np.array_equal(read_gray(f, "b"), UPRIGHT[orientation](RGB8)[..., 2])


def test_big_endian_exif_block_in_a_jpeg(tmp_path):
    """Many cameras write EXIF in Motorola byte order ('MM'): one IFD with orientation 8."""
    tiff = b"MM\x00\x2a" + struct.pack(">I", 8) + struct.pack(">H", 1) \
        + struct.pack(">HHIHH", 0x0112, 3, 1, 8, 0) + struct.pack(">I", 0)
    Image.fromarray(RGB8).save(tmp_path / "mm.jpg", exif=b"Exif\x00\x00" + tiff, quality=100, subsampling=0)
    Image.fromarray(RGB8).save(tmp_path / "plain.jpg", quality=100, subsampling=0)
    assert np.array_equal(read_gray(tmp_path / "mm.jpg", "g"), np.rot90(read_gray(tmp_path / "plain.jpg", "g"), 1))


# --- alpha -----------------------------------------------------------------------------------------
def test_opaque_alpha_is_dropped(tmp_path):
    g = RNG.integers(0, 256, (6, 8), dtype=np.uint8)
    Image.fromarray(np.dstack([g, np.full_like(g, 255)]), "LA").save(tmp_path / "la.png")
    got = read_gray(tmp_path / "la.png")
    assert got.dtype == np.uint8 and np.array_equal(got, g)
    Image.fromarray(np.dstack([RGB8, np.full((12, 16), 255, np.uint8)]), "RGBA").save(tmp_path / "rgba.png")
    rgb = RGB8.astype(np.float64)
    np.testing.assert_allclose(read_gray(tmp_path / "rgba.png"),
                               0.299 * rgb[..., 0] + 0.587 * rgb[..., 1] + 0.114 * rgb[..., 2], atol=1e-9)
    bgra16 = RNG.integers(0, 65536, (4, 5, 4), dtype=np.uint16)
    bgra16[..., 3] = 65535
    cv2.imwrite(str(tmp_path / "rgba16.png"), bgra16)
    assert np.array_equal(read_gray(tmp_path / "rgba16.png", "r"), bgra16[..., 2])


def test_non_opaque_alpha_is_refused_in_one_line(tmp_path):
    g = RNG.integers(0, 256, (6, 8), dtype=np.uint8)
    a = np.full_like(g, 255)
    a[2, 2] = 254
    Image.fromarray(np.dstack([g, a]), "LA").save(tmp_path / "la.png")
    _one_line_error(lambda: read_gray(tmp_path / "la.png"), "la.png", "1 of 48 pixels", "opaque")
    Image.fromarray(np.dstack([RGB8, np.zeros((12, 16), np.uint8)]), "RGBA").save(tmp_path / "clear.png")
    _one_line_error(lambda: read_gray(tmp_path / "clear.png", "g"), "clear.png", "192 of 192", "opaque")


# --- bad files -------------------------------------------------------------------------------------
def test_bad_files_are_one_line_errors(tmp_path):
    good = (real_set("opencv_left") / "left01.jpg").read_bytes()
    (tmp_path / "trunc.jpg").write_bytes(good[: len(good) // 2])  # libjpeg would fill the rest mid-gray
    (tmp_path / "no_eoi.jpg").write_bytes(good[:-2])
    (tmp_path / "text.jpg").write_text("not an image")
    (tmp_path / "empty.png").write_bytes(b"")
    cv2.imwrite(str(tmp_path / "c16.tif"), RNG.integers(0, 65536, (40, 50, 3), dtype=np.uint16))
    tif = (tmp_path / "c16.tif").read_bytes()
    (tmp_path / "trunc.tif").write_bytes(tif[: len(tif) // 2])
    (tmp_path / "folder.png").mkdir()
    for name in ("trunc.jpg", "no_eoi.jpg", "text.jpg", "empty.png", "trunc.tif"):
        _one_line_error(lambda: read_gray(tmp_path / name), name, "cannot be decoded")
    _one_line_error(lambda: read_gray(tmp_path / "folder.png"), "is a directory")
    _one_line_error(lambda: read_gray(tmp_path / "missing.jpg"), "no such image")


def test_data_after_the_jpeg_end_marker_is_allowed(tmp_path):
    """A phone's motion photo appends a video after the JPEG's end marker: the picture is complete."""
    p = real_set("opencv_left") / "left01.jpg"
    (tmp_path / "motion.jpg").write_bytes(p.read_bytes() + b"\x00\x00\x00\x18ftypmp42" + bytes(200))
    assert np.array_equal(read_gray(tmp_path / "motion.jpg"), read_gray(p))


# --- the locate command reads colour by the rule (it used to refuse colour) ------------------------
def test_locate_cli_reads_a_colour_photo_by_its_channel_option(tmp_path):
    """`edgetruth locate colour.png` = the same points as on the luma array; `--channel g` = as on the green
    channel saved as a gray PNG."""
    from edgetruth.cli import main

    y, x = np.mgrid[0:48, 0:64]
    step = (x + 0.3 * y > 30).astype(np.float64)
    rgb = np.dstack([40 + 150 * step, 20 + 200 * step, 90 + 60 * (1 - step)]).astype(np.uint8)
    Image.fromarray(rgb).save(tmp_path / "colour.png")
    rgbf = rgb.astype(np.float64)
    np.save(tmp_path / "luma.npy", 0.299 * rgbf[..., 0] + 0.587 * rgbf[..., 1] + 0.114 * rgbf[..., 2])
    cv2.imwrite(str(tmp_path / "green.png"), rgb[..., 1])
    runs = {"luma": ["colour.png"], "luma_ref": ["luma.npy"], "g": ["colour.png", "--channel", "g"],
            "g_ref": ["green.png"]}
    csv = {}
    for key, args in runs.items():
        out = tmp_path / f"{key}.csv"
        assert main(["-q", "locate", str(tmp_path / args[0]), *args[1:], "-m", "glm1984", "-o", str(out)]) == 0
        csv[key] = out.read_text()
    assert csv["luma"].count("\n") > 40
    assert csv["luma"] == csv["luma_ref"] and csv["g"] == csv["g_ref"] and csv["luma"] != csv["g"]


def test_the_full_scale_is_the_stored_types_not_the_gray_rules(tmp_path):
    """A colour 8-bit photo read as float luma still has full scale 255; 16-bit 65535; float arrays 1."""
    rng = np.random.default_rng(0)
    cases = [("c8.png", rng.integers(0, 256, (6, 7, 3)).astype(np.uint8), 255.0, np.float64),
             ("g16.png", rng.integers(0, 65536, (6, 7)).astype(np.uint16), 65535.0, np.uint16),
             ("c16.tif", rng.integers(0, 65536, (6, 7, 3)).astype(np.uint16), 65535.0, np.float64)]
    for name, arr, scale, dtype in cases:
        cv2.imwrite(str(tmp_path / name), arr)
        img, got = read_gray_scaled(tmp_path / name)
        assert got == scale and img.dtype == dtype and np.array_equal(img, read_gray(tmp_path / name))
    np.save(tmp_path / "f.npy", rng.random((5, 5)))
    assert read_gray_scaled(tmp_path / "f.npy")[1] == 1.0
    assert (full_scale(np.uint8), full_scale(np.uint16), full_scale(np.float32)) == (255.0, 65535.0, 1.0)
