"""Finding the model's squares on Zhang's photos, in the order of his dataN.txt."""
import numpy as np
import pytest

from edgetruth.evaluate.board.detect.correspond import match_squares
from edgetruth.evaluate.board.model import read_model
from edgetruth.evaluate.board.detect.quads import find_quads
from edgetruth.evaluate.board.reference import read_corners
from edgetruth.image_io import read_gray
from edgetruth.resources import real_set

ROOT = real_set("zhang1998")
MODEL = read_model(ROOT / "Model.txt")


def _photo(i):
    return read_gray(ROOT / f"CalibIm{i}.png"), read_corners(ROOT / f"data{i}.txt", 64)


@pytest.mark.parametrize("i", [1, 2, 3, 4, 5])
def test_all_64_squares_in_zhangs_order(i):
    img, ref = _photo(i)
    c = match_squares(MODEL, find_quads(img))
    assert c is not None and c.found.all() and c.missing == []
    assert not c.mirrored
    # the order: each found square's centre is nearest to the same square of Zhang's, well within a pitch (~55 px)
    d = np.linalg.norm(c.corners.mean(axis=1)[:, None] - ref.mean(axis=1)[None], axis=2)
    assert np.array_equal(np.argmin(d, axis=1), np.arange(64))
    assert d[np.arange(64), np.arange(64)].max() < 1.0
    # the detected quads are polygon vertices, a first pass: measured mean 0.69-0.81 px, max 2.2 px
    err = np.linalg.norm(c.corners - ref, axis=2)
    assert err.mean() < 1.0 and err.max() < 3.0


def test_half_turned_photo_is_numbered_by_the_rule():
    """Rotated by 180 degrees, the board is numbered again from the photo's bottom left (rule: no mirror, model
    +x closest to image +x): square s is Zhang's square 63 - s, its corner k his corner k + 2."""
    img, ref = _photo(1)
    h, w = img.shape
    c = match_squares(MODEL, find_quads(img[::-1, ::-1]))
    assert c.found.all() and not c.mirrored and abs(c.rotation_deg) < 45
    turned = np.stack([w - 1 - ref[..., 0], h - 1 - ref[..., 1]], axis=-1)[::-1]
    turned = np.roll(turned, -2, axis=1)
    assert np.linalg.norm(c.corners - turned, axis=2).mean() < 1.0


def test_mirrored_photo_keeps_the_model_unmirrored():
    img, ref = _photo(2)
    c = match_squares(MODEL, find_quads(img[:, ::-1]))
    assert c.found.all() and not c.mirrored and abs(c.rotation_deg) < 45


def test_a_photo_without_squares():
    assert match_squares(MODEL, find_quads(np.full((120, 160), 128, np.uint8))) is None
