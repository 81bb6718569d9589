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
