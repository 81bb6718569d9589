"""Issue 21's smaller things: an empty -o, articles in messages, a camera named without .toml, every
shipped spec in `render --help` and docs/spec.md."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

from edgetruth.cli import build_parser, main
from edgetruth.errors import InputError

from tests.support.files import tree_hash

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("argv", [
    ["locate", "img.png", "-o", ""],
    ["render", "quick", "-o", ""],
    ["render", "quick", "--output", ""],
    ["run", "-o", ""],
    ["calibrate-thresholds", "-o", ""],
    ["study", "synthetic", "-o", ""],
    ["evaluate", "data", "-o", ""],
])
def test_an_empty_output_is_named_as_such(argv, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "keep.txt").write_text("x")
    before = tree_hash(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "'': an empty path; give a file or folder name" in err, err
    assert tree_hash(tmp_path) == before


def test_input_messages_use_the_right_article(tmp_path):
    from edgetruth.fileio import check_input_file

    with pytest.raises(InputError, match="is a directory, not an image; pass a file"):
        check_input_file(tmp_path, "image")
    with pytest.raises(InputError, match="not a photo"):
        check_input_file(tmp_path, "photo")
    fifo = tmp_path / "p.exr"
    os.mkfifo(fifo)
    with pytest.raises(InputError, match="pass an EXR file on disk"):
        check_input_file(fifo, "EXR file")
    with pytest.raises(InputError, match="pass an image file on disk"):
        check_input_file(fifo, "image")


def test_no_message_says_a_image():
    for folder in ("edgetruth", "render", "locate", "evaluate"):
        for f in (ROOT / folder).rglob("*.py"):
            assert "a image" not in f.read_text(), f


def _spec_with_camera(tmp_path, camera: str) -> Path:
    from edgetruth.render.testing import write_tiny_spec

    spec = write_tiny_spec(tmp_path)
    text = spec.read_text()
    cam_line = next(line for line in text.splitlines() if line.startswith("camera"))
    spec.write_text(text.replace(cam_line, f'camera = "{camera}"'))
    return spec


def test_a_camera_file_without_toml_says_what_is_wrong(tmp_path):
    from edgetruth.render.dataset.spec import load_spec

    (tmp_path / "cam.txt").write_text((tmp_path / "x").name)
    spec = _spec_with_camera(tmp_path, "cam.txt")
    with pytest.raises(InputError) as info:
        load_spec(spec)
    msg = str(info.value)
    assert "not found" not in msg and "is a file" in msg and "cam.toml" in msg and "default" in msg, msg


def test_a_camera_folder_says_it_is_a_folder(tmp_path):
    from edgetruth.render.dataset.spec import load_spec

    (tmp_path / "cams").mkdir()
    with pytest.raises(InputError) as info:
        load_spec(_spec_with_camera(tmp_path, "cams"))
    msg = str(info.value)
    assert "not found" not in msg and "is a folder" in msg, msg


def test_an_unknown_camera_name_is_still_not_found(tmp_path):
    from edgetruth.render.dataset.spec import load_spec

    with pytest.raises(InputError, match="not found; shipped cameras"):
        load_spec(_spec_with_camera(tmp_path, "nosuchcam"))


def test_render_help_and_spec_doc_list_every_shipped_spec(capsys):
    from edgetruth.resources import shipped_spec_names

    names = shipped_spec_names()
    assert len(names) >= 5
    with pytest.raises(SystemExit):
        main(["render", "--help"])
    help_text = " ".join(capsys.readouterr().out.split())
    doc = (ROOT / "docs" / "spec.md").read_text()
    for n in names:
        assert n in help_text and f"`{n}`" in doc, n


def test_every_render_option_still_has_help():
    sub = next(a for a in build_parser()._actions if a.__class__.__name__ == "_SubParsersAction")
    assert all(a.help for a in sub.choices["render"]._actions)


def test_a_closed_pipe_ends_quietly(tmp_path):
    """`edgetruth methods | head -1`: when the reader goes away the command ends with the shell's SIGPIPE code
    (141) and no traceback."""
    import subprocess
    import sys

    read, write = os.pipe()
    os.close(read)  # the reader is gone before the first line
    try:
        proc = subprocess.run([sys.executable, "-c", "import sys; from edgetruth.cli import main; "
                               "sys.exit(main(['methods']))"], stdout=write, stderr=subprocess.PIPE, cwd=tmp_path,
                              env={**os.environ, "PYTHONPATH": str(ROOT)}, timeout=120)
    finally:
        os.close(write)
    err = proc.stderr.decode()
    assert proc.returncode == 141 and "Traceback" not in err, err
