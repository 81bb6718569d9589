"""Method options on the command line (issue 21, Build 2): ``METHOD:key=value[:key=value]`` on ``locate -m``
and inside ``--methods`` of evaluate, run and study.

1. ``locate -m pae2013:variant=smoothed`` (and plain ``-m pae2013``: the CLI runs the studies' options,
   ``STUDY_OPTIONS``) gives exactly the points ``evaluate`` computes for PAE2013 on the same image
   (``range_undistorted``, the per-image step of ``evaluate``); ``variant=floating`` gives others.
2. A bad option (unknown key, wrong type, a value the method refuses, no value) is one line on stderr
   naming the method and the option, exit 2, and the output that was there is untouched.
3. Labels are canonical and distinct: two variants of one method are two rows with readable names,
   in the canonical order next to their method; reports list the options each method ran with.
"""
from __future__ import annotations

import csv
from types import SimpleNamespace

import numpy as np
import pytest

from edgetruth.cli import build_parser, main
from edgetruth.evaluate import method_order as mo


def _square_image(seed: int = 3) -> np.ndarray:
    """A noisy dark square on a bright ground, blurred (what a rendered target looks like to evaluate)."""
    import cv2

    rng = np.random.default_rng(seed)
    img = np.full((96, 112), 190.0)
    img[28:70, 34:80] = 40.0
    img = cv2.GaussianBlur(img, (0, 0), 1.2)
    return img + rng.normal(0.0, 2.5, img.shape)


def _cal() -> SimpleNamespace:
    fx, cx, cy = 900.0, 56.0, 48.0
    return SimpleNamespace(fx=fx, fy=fx, cy=cy, K=np.array([[fx, 0, cx], [0, fx, cy], [0, 0, 1.0]]))


def _read_xy(path) -> np.ndarray:
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    return np.array([[float(r["x"]), float(r["y"])] for r in rows])


def _cli(argv, capsys):
    rc = main([str(a) for a in argv])
    cap = capsys.readouterr()
    return rc, cap.out, cap.err


@pytest.fixture(scope="module")
def evaluated():
    """What evaluate computes for the square: its target crop, kept candidates and every label's points."""
    from edgetruth.evaluate.ranging.images import range_undistorted
    from edgetruth.evaluate.target import target_candidates

    img = _square_image()
    valid = np.ones(img.shape, bool)
    tc = target_candidates(img, valid)
    labels = ["pae2013", "pae2013:variant=floating"]
    res = range_undistorted(img, valid, "square", 0.1, 2.0, _cal(), labels, {"image": "sq"}, keep_points=True,
                            options=mo.study_options())
    return tc, res


@pytest.mark.parametrize("spec", ["pae2013:variant=smoothed", "pae2013"])
def test_locate_equals_evaluate_for_pae2013(spec, evaluated, tmp_path, capsys):
    tc, res = evaluated
    crop = tmp_path / "crop.npy"
    np.save(crop, tc.crop)
    out = tmp_path / "points.csv"
    rc, stdout, err = _cli(["locate", crop, "-m", spec, "-o", out], capsys)
    assert rc == 0, err
    assert "variant=smoothed" in stdout  # the options that ran are printed
    xy = _read_xy(out)
    assert len(xy) == len(tc.all_candidates)
    x0, y0 = tc.offset
    mine = xy[tc.keep] + [x0, y0]
    ex, ey = res.points["pae2013"]
    assert np.array_equal(mine[:, 0], ex) and np.array_equal(mine[:, 1], ey)
    fx, fy = res.points["pae2013:variant=floating"]
    assert not np.array_equal(fx, ex)  # the other variant is another row with other points


def test_locate_floating_variant_is_the_methods_own_default(evaluated, tmp_path, capsys):
    from edgetruth import locate

    tc, res = evaluated
    crop = tmp_path / "crop.npy"
    np.save(crop, tc.crop)
    out = tmp_path / "points.csv"
    rc, stdout, err = _cli(["locate", crop, "-m", "pae2013:variant=floating", "-o", out], capsys)
    assert rc == 0, err
    ref = locate.locate(tc.crop, "pae2013")  # the Python API keeps the signature's default
    assert np.array_equal(_read_xy(out)[:, 0], ref.x)
    x0, y0 = tc.offset
    fx, _ = res.points["pae2013:variant=floating"]
    assert np.array_equal(_read_xy(out)[tc.keep, 0] + x0, fx)


BAD = [
    ("pae2013:variant=nope", ["pae2013", "variant", "floating, smoothed, basic"]),
    ("pae2013:varient=smoothed", ["pae2013", "varient", "variant=floating"]),
    ("pae2013:order=two", ["pae2013", "order", "integer"]),
    ("pae2013:order=1.5", ["pae2013", "order", "integer"]),
    ("pae2013:order", ["pae2013", "key=value"]),
    ("pae2013:", ["pae2013", "key=value"]),
    ("pae2013:order=1:order=2", ["order", "twice"]),
    ("glm1984:half=9", ["glm1984", "half"]),
    ("canny_devernay:strict=yes", ["canny_devernay", "strict", "true or false"]),
    ("dynamic_erf_4p:maxit=x", ["dynamic_erf_4p", "maxit", "integer"]),
    ("nope:variant=x", ["unknown method", "nope"]),
    ("pae2013,glm1984", ["one method"]),
]


@pytest.mark.parametrize("spec, expect", BAD, ids=[b[0] for b in BAD])
def test_locate_bad_option_is_one_line_exit_2(spec, expect, tmp_path, capsys):
    img = tmp_path / "img.npy"
    np.save(img, _square_image())
    out = tmp_path / "points.csv"
    out.write_text("x,y\n1,2\n")
    rc, _, err = _cli(["locate", img, "-m", spec, "-o", out], capsys)
    assert rc == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("edgetruth locate: error:"), err
    for word in expect:
        assert word in lines[0], (word, lines[0])
    assert out.read_text() == "x,y\n1,2\n"


@pytest.mark.parametrize("argv", [
    ["study", "synthetic", "--methods", "dynamic_erf_4p,pae2013:variant=nope", "-o", "{O}/s"],
    ["study", "board", "zhang1998", "--methods", "pae2013:order=x", "-o", "{O}/s"],
    ["evaluate", "{O}/none", "--methods", "pae2013:variant=nope", "-o", "{O}/s"],
    ["run", "--methods", "glm1984:half=99", "-o", "{O}/s"],
], ids=["study-synthetic", "study-board", "evaluate", "run"])
def test_lists_refuse_a_bad_option_before_writing(argv, tmp_path, capsys):
    rc, _, err = _cli([a.replace("{O}", str(tmp_path)) for a in argv], capsys)
    assert rc == 2
    assert len(err.strip().splitlines()) == 1, err
    assert "error:" in err and ("variant" in err or "order" in err or "half" in err)
    assert not (tmp_path / "s").exists()


def test_method_specs_are_canonical_and_distinct():
    got = mo.method_specs("dynamic_erf_4p, pae2013:order=1:variant=floating,pae2013,pae2013:variant=floating,order=1,"
                          "glm1984:half=3,dynamic_erf_4p")
    assert got == ["dynamic_erf_4p", "pae2013:variant=floating:order=1", "pae2013", "glm1984:half=3"]
    assert mo.method_specs("patch_psf_fit:psf_sigma_px=1:curved=false") == ["patch_psf_fit:psf_sigma_px=1:curved=false"]
    assert mo.method_specs("pae2013:threshold=none") == ["pae2013:threshold=none"]
    assert mo.ordered(got) == ["glm1984:half=3", "pae2013", "pae2013:variant=floating:order=1", "dynamic_erf_4p"]
    assert mo.label("pae2013:variant=floating:order=1") == "PAE2013 (variant=floating, order=1)"
    assert mo.label("pae2013") == "PAE2013"
    with pytest.raises(ValueError, match="names no method"):
        mo.method_specs("order=1,pae2013")


def test_resolve_adds_a_labels_options_to_the_studys():
    opts = mo.study_options()
    assert mo.resolve("pae2013", opts) == ("pae2013", {"variant": "smoothed"})
    assert mo.resolve("pae2013:order=1", opts) == ("pae2013", {"variant": "smoothed", "order": 1})
    assert mo.resolve("pae2013:variant=floating", opts) == ("pae2013", {"variant": "floating"})
    assert mo.resolve("glm1984:half=3", opts) == ("glm1984", {"half": 3})


def test_options_line_lists_what_ran():
    line = mo.options_line(["pae2013", "pae2013:variant=floating", "dynamic_erf_4p"])
    assert "PAE2013: variant=smoothed" in line
    assert "PAE2013 (variant=floating): variant=floating" in line
    assert "the others" in line


def test_two_variants_are_two_rows(evaluated):
    _, res = evaluated
    rows = {r["method"]: r for r in res.rows}
    assert set(rows) == {"pae2013", "pae2013:variant=floating"}
    assert all(r["status"] == "ok" for r in rows.values())


def test_help_documents_the_syntax():
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command").choices
    for cmd in ("locate", "evaluate", "run", "study"):
        text = " ".join(sub[cmd].format_help().split())
        assert "METHOD:key=value" in text, cmd
        assert "variant=smoothed" in text, cmd
