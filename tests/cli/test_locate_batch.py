"""``edgetruth locate`` on many images in one call: folders, globs and several files; one CSV per image
(-o DIR) or one CSV with an image column (-o FILE.csv); the same points as one image at a time, and a
bad image or a bad output leaves everything as it was."""
from __future__ import annotations

import csv
import io
import os

import cv2
import numpy as np
import pytest

from edgetruth.cli import main
from edgetruth.cli.commands.locate import csv_cells, csv_text

from tests.support.files import tree_hash


def _frame(seed: int, shape=(48, 64)) -> np.ndarray:
    rng = np.random.default_rng(seed)
    img = np.full(shape, 180.0)
    r = rng.uniform(9, 14)
    cv2.circle(img, (int(16 * rng.uniform(26, 38)), int(16 * rng.uniform(20, 28))), int(16 * r), 40.0, -1,
               cv2.LINE_AA, 4)
    img = cv2.GaussianBlur(img, (0, 0), 1.0) + rng.normal(0, 1.0, shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


@pytest.fixture
def shots(tmp_path):
    d = tmp_path / "shots"
    d.mkdir()
    for i in range(3):
        cv2.imwrite(str(d / f"a{i}.png"), _frame(i))
    np.save(d / "b.npy", _frame(7).astype(np.float64))
    (d / "notes.txt").write_text("not an image: a folder's other files are skipped")
    return d


def _single(path, out, *extra) -> bytes:
    assert main(["-q", "locate", str(path), "-o", str(out), *extra]) == 0
    return out.read_bytes()


def test_folder_writes_one_csv_per_image_identical_to_single_calls(shots, tmp_path):
    out = tmp_path / "out"
    assert main(["-q", "locate", str(shots), "-m", "glm1984", "-o", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["a0.csv", "a1.csv", "a2.csv", "b.csv"]
    for name in ("a0.png", "a1.png", "a2.png", "b.npy"):
        one = _single(shots / name, tmp_path / "one.csv", "-m", "glm1984")
        assert (out / f"{name.split('.')[0]}.csv").read_bytes() == one, name


def test_combined_csv_has_an_image_column_and_the_same_rows(shots, tmp_path):
    out = tmp_path / "all.csv"
    pattern = str(shots / "a*.png")
    assert main(["-q", "locate", pattern, str(shots / "b.npy"), "-o", str(out)]) == 0
    rows = list(csv.reader(io.StringIO(out.read_text())))
    assert rows[0][0] == "image"
    names = [str(shots / f"a{i}.png") for i in range(3)] + [str(shots / "b.npy")]
    got = [r[0] for r in rows[1:]]
    assert list(dict.fromkeys(got)) == names  # in the order given, each image's rows together
    for name in names:
        one = _single(name, tmp_path / "one.csv")
        lines = one.decode().splitlines()
        assert rows[0][1:] == lines[0].split(",")
        mine = [",".join(r[1:]) for r in rows[1:] if r[0] == name]
        assert mine == lines[1:], name


def test_several_refs_name_each_image_once(shots, tmp_path):
    out = tmp_path / "all.csv"
    assert main(["-q", "locate", str(shots), str(shots / "a0.png"), str(shots / "a*.png"), "-o", str(out)]) == 0
    images = [r[0] for r in list(csv.reader(io.StringIO(out.read_text())))[1:]]
    assert len(dict.fromkeys(images)) == 4


def test_csv_text_is_what_to_csv_writes(shots, tmp_path):
    from edgetruth import locate
    from edgetruth.image_io import read_gray

    for m in ("dynamic_erf_4p", "pae2013", "canny_devernay", "ser_cis"):
        pts = locate.locate(read_gray(shots / "a1.png"), m)
        pts.to_csv(tmp_path / "p.csv")
        names, cells = csv_cells(pts)
        assert ",".join(names) + "\n" + csv_text(names, cells) == (tmp_path / "p.csv").read_text(), m


def _fails(argv, capsys, *texts):
    rc = main(argv)
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    for t in texts:
        assert t in err, err
    return err


@pytest.mark.parametrize("how", ["dir", "file"])
def test_a_bad_image_leaves_the_outputs_untouched(shots, tmp_path, capsys, how):
    (shots / "a2.png").write_bytes(b"not a png at all")  # sorted between good ones
    out = tmp_path / ("out" if how == "dir" else "all.csv")
    if how == "dir":
        out.mkdir()
        (out / "a0.csv").write_text("an earlier result\n")
    else:
        out.write_text("an earlier result\n")
    before = tree_hash(tmp_path)
    _fails(["locate", str(shots), "-o", str(out)], capsys, "a2.png", "cannot be decoded")
    assert tree_hash(tmp_path) == before  # no temporary file left, nothing replaced


def test_a_new_output_folder_is_not_left_behind(shots, tmp_path, capsys):
    (shots / "b.npy").write_bytes(b"\x93NUMPY broken")
    _fails(["locate", str(shots), "-o", str(tmp_path / "new")], capsys, "b.npy")
    assert not (tmp_path / "new").exists()


def test_two_images_with_one_stem_are_refused_before_anything_runs(shots, tmp_path, capsys):
    other = tmp_path / "other"
    other.mkdir()
    cv2.imwrite(str(other / "a0.png"), _frame(3))
    out = tmp_path / "out"
    _fails(["locate", str(shots), str(other), "-o", str(out)], capsys, "a0.png", "both write", "image column")
    assert not out.exists()


@pytest.mark.parametrize("refs,text", [
    (["{D}/empty"], "is a directory with no image files"),
    (["{D}/shots/*.tif"], "no image file matches this pattern"),
    (["{D}/shots/a0.png", "{D}/missing.png"], "no such image"),
])
def test_refs_that_name_no_image(shots, tmp_path, capsys, refs, text):
    (tmp_path / "empty").mkdir()
    _fails(["locate", *[r.format(D=tmp_path) for r in refs], "-o", str(tmp_path / "out")], capsys, text)
    assert not (tmp_path / "out").exists()


def test_batch_output_checks(shots, tmp_path, capsys):
    (tmp_path / "afile").write_text("x")
    _fails(["locate", str(shots), "-o", str(tmp_path / "afile")], capsys, "is a file, not a directory")
    _fails(["locate", str(shots), "-o", str(shots / "a0.png") + "/x.csv"], capsys, "is a file")
    # an input named as the combined output
    (shots / "c.csv").write_text("x")
    _fails(["locate", str(shots / "a0.png"), str(shots / "c.csv"), "-o", str(shots / "c.csv")], capsys,
           "also the input")


def test_one_image_keeps_its_output_rules(shots, tmp_path, capsys):
    """One file: -o is the CSV file, as before (a folder there is an error, not a destination)."""
    _fails(["locate", str(shots / "a0.png"), "-o", str(tmp_path)], capsys, "is a directory")
    assert main(["-q", "locate", str(shots / "a0.png"), "-o", str(tmp_path / "points")]) == 0
    assert (tmp_path / "points").read_text().startswith("x,y,nx,ny,converged")


def test_summary_line(shots, tmp_path, capsys):
    assert main(["locate", str(shots), "-o", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert out.startswith("4 images, ") and "4 CSV files in" in out


def test_help_documents_both_outputs(capsys):
    with pytest.raises(SystemExit):
        main(["locate", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "-o DIR" in text and "-o FILE.csv" in text and "glob" in text and "'image'" in text


def test_formats_doc_describes_the_combined_csv():
    from pathlib import Path

    doc = (Path(__file__).resolve().parents[2] / "docs" / "formats.md").read_text()
    assert "-o FILE.csv" in doc and "`image`" in doc


def test_no_temporary_files_after_success(shots, tmp_path):
    out = tmp_path / "o"
    assert main(["-q", "locate", str(shots), "-o", str(out)]) == 0
    assert main(["-q", "locate", str(shots), "-o", str(tmp_path / "all.csv")]) == 0
    leftovers = [p for p in [*out.iterdir(), *tmp_path.iterdir()] if p.name.startswith(".tmp-")]
    assert not leftovers and os.listdir(out)


@pytest.mark.parametrize("out_name", ["out", "all.csv"])
def test_a_second_formatting_process_writes_the_same_bytes(shots, tmp_path, monkeypatch, out_name):
    """Long batches make their CSV text in a second process (``POOL_FROM_IMAGES``); the files are those of
    the one-process loop, byte for byte, in image order."""
    from edgetruth.cli.commands import locate as cmd

    inline, pooled = tmp_path / "inline" / out_name, tmp_path / "pooled" / out_name
    for where in (inline, pooled):
        where.parent.mkdir()
    assert main(["-q", "locate", str(shots), "-o", str(inline)]) == 0
    monkeypatch.setattr(cmd, "POOL_FROM_IMAGES", 1)
    assert main(["-q", "locate", str(shots), "-o", str(pooled)]) == 0
    assert tree_hash(inline.parent) == tree_hash(pooled.parent)


def test_a_bad_image_with_the_formatting_process_leaves_the_outputs_untouched(shots, tmp_path, capsys, monkeypatch):
    from edgetruth.cli.commands import locate as cmd

    monkeypatch.setattr(cmd, "POOL_FROM_IMAGES", 1)
    (shots / "b.npy").write_bytes(b"\x93NUMPY broken")  # last: the images before it are already formatted
    out = tmp_path / "out"
    out.mkdir()
    (out / "a0.csv").write_text("an earlier result\n")
    before = tree_hash(tmp_path)
    _fails(["locate", str(shots), "-o", str(out)], capsys, "b.npy")
    assert tree_hash(tmp_path) == before
