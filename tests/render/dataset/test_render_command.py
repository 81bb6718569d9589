"""``edgetruth render`` on the command line."""
from __future__ import annotations

import json

import pytest

from edgetruth.cli import main
from edgetruth.errors import InputError

from edgetruth.render.testing import write_tiny_spec as _spec


def test_unknown_spec_exits_2(capsys):
    assert main(["render", "no-such-spec", "-o", "/tmp/x"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not found" in err


def test_render_and_resume(tmp_path, capsys):
    spec = _spec(tmp_path)
    out = tmp_path / "out"
    assert main(["render", str(spec), "-o", str(out), "--only", "0", "--no-progress"]) == 0
    first = capsys.readouterr().out
    assert "using Mitsuba variant" in first and "1/3" in first
    assert main(["render", str(spec), "-o", str(out), "--only", "0", "--no-progress"]) == 0
    assert "nothing to do" in capsys.readouterr().out
    assert set(json.loads((out / "manifest.json").read_text())["images"]) == {"0000_T2"}
    assert main(["render", str(spec), "-o", str(out), "--only", "x"]) == 2


def test_a_pose_no_draw_can_meet_is_refused_before_anything_is_written(tmp_path, capsys):
    """The tiny camera (64 px, fx 83 px) sees its 0.24 m checkerboard whole, centred, from ~0.40 m on: a group that
    starts at 0.20 m is refused at once, naming the group and the distance it needs (it stopped at its first such
    image before, after writing the others).  The check draws the nearest image's pose as its render would, and
    the distance it names is where the board fits centred and untilted (the draw's last resort): 1 cm nearer it
    does not."""
    spec = _spec(tmp_path)
    text = spec.read_text()
    spec.write_text(text.replace("distance_range_cm = [70, 90]", "distance_range_cm = [20, 90]"))
    out = tmp_path / "out"
    assert main(["render", str(spec), "-o", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "tiny group 'cal': the board does not fit in the image at 0." in err[0], err
    assert not out.exists()
    need = int(err[0].split("start its distance_range_cm at ")[1].split()[0])
    assert 30 <= need <= 60
    from edgetruth.render.dataset.image import check_views, in_view
    from edgetruth.render.dataset.spec import load_spec
    from edgetruth.render.scene.pose import Pose

    spec.write_text(text.replace("distance_range_cm = [70, 90]", f"distance_range_cm = [{need}, {need + 1}]"))
    s = load_spec(spec)
    check_views(s)
    board, cam = s.checkerboard.plate_corners_local(), s.jobs[2].camera
    assert in_view(cam, Pose(need / 100, 0, 0, 0, 0, 0), board)
    assert not in_view(cam, Pose((need - 1) / 100, 0, 0, 0, 0, 0), board)


@pytest.mark.parametrize("text, expect", [
    ("0,3,5-7", [0, 3, 5, 6, 7]), (" 2 - 3 ", [2, 3]),
    ("", "'' is not an index or a range"), ("1-", "'1-' is not an index or a range"),
    ("2-1", "'2-1' runs backwards"), ("x", "'x' is not an index"), ("3,,4", "'' is not an index"),
    ("0-20000000", "spans more than 10 million"),
])
def test_only_takes_indices_and_ranges_and_names_the_bad_part(text, expect):
    from edgetruth.cli.commands.render import parse_indices

    if isinstance(expect, list):
        assert parse_indices(text) == expect
    else:
        with pytest.raises(InputError, match=expect):
            parse_indices(text)
    assert parse_indices(None) is None


def test_only_beyond_the_spec_names_its_range(tmp_path, capsys):
    spec = _spec(tmp_path)
    assert main(["render", str(spec), "-o", str(tmp_path / "o"), "--only", "1-9", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "spec 'tiny' has images 0-2, and 7 of the indices asked for lie beyond them (the first: 3)" in err
