"""--pattern: one parser for chessboards, circle grids and ChArUco boards (evaluate/pattern.py)."""
import pytest

from edgetruth.errors import InputError
from edgetruth.evaluate.pattern import BoardPattern, aruco_dictionaries, parse_board_pattern
from edgetruth.evaluate.calibration import parse_pattern


@pytest.mark.parametrize("text, want", [
    ("9x6", BoardPattern("chessboard", 9, 6)),
    (" 9X6 ", BoardPattern("chessboard", 9, 6)),
    ("circles:7x6", BoardPattern("circles", 7, 6)),
    ("circles:7x6:symmetric", BoardPattern("circles", 7, 6)),
    ("circles:4x11:asymmetric", BoardPattern("circles", 4, 11, asymmetric=True)),
    ("Circles:4×11:Asymmetric", BoardPattern("circles", 4, 11, asymmetric=True)),
    ("charuco:5x7:DICT_4X4_50", BoardPattern("charuco", 5, 7, dictionary="DICT_4X4_50")),
    ("charuco:5x7:dict_6x6_250", BoardPattern("charuco", 5, 7, dictionary="DICT_6X6_250")),
])
def test_parses_every_form(text, want):
    got = parse_board_pattern(text)
    assert got == want
    assert parse_board_pattern(got.text) == got  # the text round-trips
    assert got.size == (want.cols, want.rows)


@pytest.mark.parametrize("text, says", [
    ("9", "COLSxROWS"), ("1x6", "2..1000"), ("circles:4x", "COLSxROWS"), ("circles:4x11:skew", "asymmetric"),
    ("charuco:5x7", "dictionary"), ("charuco:5x7:DICT_NOPE", "DICT_4X4_50"), ("dots:4x11", "unknown board kind"),
    ("9x6:asymmetric", "circles:COLSxROWS"),
])
def test_bad_patterns_name_the_value_and_the_forms(text, says):
    with pytest.raises(InputError) as e:
        parse_board_pattern(text)
    assert repr(text) in str(e.value) and says in str(e.value)


def test_a_command_that_takes_only_some_kinds_refuses_the_others():
    with pytest.raises(InputError, match="takes a chessboard or circles pattern, not a charuco one"):
        parse_board_pattern("charuco:5x7:DICT_4X4_50", kinds=("chessboard", "circles"))
    with pytest.raises(InputError, match="takes a chessboard pattern"):
        parse_pattern("circles:4x11:asymmetric")
    assert parse_pattern("9x6") == (9, 6)


def test_dictionaries_are_cv2_arucos_own():
    import cv2

    names = aruco_dictionaries()
    assert "DICT_4X4_50" in names and "DICT_ARUCO_ORIGINAL" in names
    assert all(isinstance(getattr(cv2.aruco, n), int) for n in names)


def test_to_dict_says_what_the_json_records():
    assert parse_board_pattern("circles:4x11:asymmetric").to_dict() == {
        "kind": "circles", "pattern_size": [4, 11], "asymmetric": True}
    assert parse_board_pattern("9x6").to_dict() == {"kind": "chessboard", "pattern_size": [9, 6]}
