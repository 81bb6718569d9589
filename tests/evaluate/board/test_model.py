"""The board model reader: Zhang's Model.txt, and one clear line for each malformed file."""
import numpy as np
import pytest

from edgetruth.errors import InputError
from edgetruth.evaluate.board.model import check_model, read_model
from edgetruth.resources import real_set


def test_zhang_model_reads_64_squares_of_half_an_inch():
    m = read_model(real_set("zhang1998") / "Model.txt")
    assert m.corners.shape == (64, 4, 2)
    np.testing.assert_allclose(m.side_lengths, 0.5, atol=1e-5)
    # corner 0 of square 0 is (0, -0.5); rows of 8 squares, pitch 0.8889 in
    np.testing.assert_allclose(m.corners[0, 0], [0.0, -0.5])
    np.testing.assert_allclose(m.centres[1] - m.centres[0], [0.888889, 0.0], atol=1e-5)
    np.testing.assert_allclose(m.centres[8] - m.centres[0], [0.0, -0.888889], atol=1e-5)
    obj = m.object_points()
    assert obj.shape == (256, 3) and obj.dtype == np.float32 and np.all(obj[:, 2] == 0)


def test_comments_and_blank_lines_are_allowed(tmp_path):
    lines = [f"{x} 0 {x + 1} 0 {x + 1} 1 {x} 1" for x in (0, 2, 4, 6)]
    p = tmp_path / "m.txt"
    p.write_text("# a board\n\n" + "\n".join(lines) + "  # last\n")
    assert len(read_model(p)) == 4


@pytest.mark.parametrize("text, match", [
    ("", "no squares"),
    ("0 0 1 0 1 1 0\n", "line 1 has 7 values"),
    ("0 0 1 0 1 1 0 one\n", "line 1 holds a value that is not a number"),
    ("\n".join(["0 0 1 0 1 1 0 1"] * 3), "3 square"),
    ("\n".join(f"{x} 0 {x + 1} 0 {x} 1 {x + 1} 1" for x in (0, 2, 4, 6)), "square 1 .* not a convex"),
    ("\n".join(f"{x} 0 {x + 1} 0 {x + 1} 1 {x} 1" for x in (0, 2, 4)) + "\n6 0 6 1 7 1 7 0",
     "square 4 .* other direction"),
    ("\n".join(f"{x} 0 {x + 1} 0 {x + 1} 1 {x} 1" for x in (0, 2, 4, 4.1)), "overlap"),
    ("\n".join(f"{x} 0 {x + 1} 0 {x + 1} 1 {x} nan" for x in (0, 2, 4, 6)), "non-finite"),
])
def test_malformed_models_are_one_line_errors(tmp_path, text, match):
    p = tmp_path / "bad.txt"
    p.write_text(text)
    with pytest.raises(InputError, match=match) as e:
        read_model(p)
    assert "\n" not in str(e.value) and str(p) in str(e.value)


def test_missing_and_binary_model_files(tmp_path):
    with pytest.raises(InputError, match="no such board model file"):
        read_model(tmp_path / "none.txt")
    p = tmp_path / "bin.txt"
    p.write_bytes(b"\xff\xfe\x00\x81" * 10)
    with pytest.raises(InputError, match="cannot be read as text|not a number|values"):
        read_model(p)


def test_check_model_shape():
    with pytest.raises(InputError, match="shape"):
        check_model(np.zeros((4, 3, 2)), "x")
