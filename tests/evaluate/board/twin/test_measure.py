"""What a twin needs, measured on chessboard photos (``twin.measure``): the JPEG quality read from the file, a photo
without the board or of another bit depth named."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from edgetruth.errors import InputError
from edgetruth.evaluate.board.twin import measure as tm
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


def test_a_photo_without_the_board_is_named(tmp_path):
    """A photo where the board is not found: one InputError naming it (a twin renders one image per photo)."""
    paths, _ = views(tmp_path, ".png")
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((480, 640), 128, np.uint8))
    with pytest.raises(InputError, match="blank.png: the 9x6 board was not found"):
        tm.measure_chessboard([*paths, blank], (9, 6))


def test_photos_of_two_bit_depths_are_refused(tmp_path):
    """An 8-bit set with one 16-bit photo: one InputError naming that photo (one camera's output, one depth)."""
    paths, _ = views(tmp_path, ".png")
    img = cv2.imread(str(paths[0]), cv2.IMREAD_GRAYSCALE).astype(np.uint16) * 16
    cv2.imwrite(str(tmp_path / "deep.png"), img)
    with pytest.raises(InputError, match="deep.png: uint16 values among 8-bit photos"):
        tm.measure_chessboard([*paths, tmp_path / "deep.png"], (9, 6))
