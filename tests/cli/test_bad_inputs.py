"""Bad input everywhere: one line naming the input and the fix, exit 2 (CLI) or ValueError (API),
no traceback, and existing outputs untouched."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from edgetruth.cli import build_parser, main

from tests.support.files import tree_hash

# --- bad files -----------------------------------------------------------------------------------
GOOD = np.zeros((40, 40), np.uint8)
GOOD[:, 20:] = 200


def _exr(path: Path, channels: dict) -> None:
    import OpenEXR

    with OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage},
                      {k: np.ascontiguousarray(v, np.float32) for k, v in channels.items()}) as f:
        f.write(str(path))


def _make_bad_images(d: Path) -> None:
    cv2.imwrite(str(d / "good.png"), GOOD)
    png = (d / "good.png").read_bytes()
    (d / "trunc.png").write_bytes(png[: len(png) // 2])
    (d / "garbage.png").write_bytes(b"not an image at all")
    (d / "empty.png").write_bytes(b"")
    (d / "header_only.png").write_bytes(png[:8])
    cv2.imwrite(str(d / "good.tif"), GOOD.astype(np.uint16))
    tif = (d / "good.tif").read_bytes()
    (d / "trunc.tif").write_bytes(tif[:20])
    _exr(d / "good.exr", {"Y": GOOD})
    exr = (d / "good.exr").read_bytes()
    (d / "garbage.exr").write_bytes(b"\x76\x2f\x31\x01garbage")
    (d / "empty.exr").write_bytes(b"")
    nan = GOOD.astype(np.float32)
    nan[5, 5] = np.nan
    _exr(d / "nan.exr", {"Y": nan})
    inf = GOOD.astype(np.float32)
    inf[7, 3] = -np.inf
    _exr(d / "inf.exr", {"Y": inf})
    # colour with an alpha that is not fully opaque: what lies behind is unknown (colour itself is read by luma)
    _exr(d / "rgba.exr", {"R": GOOD, "G": GOOD * 0.5, "B": GOOD, "A": np.where(GOOD > 0, 1.0, 0.5)})
    _exr(d / "tiny.exr", {"Y": np.zeros((2, 2))})
    (d / "trunc.exr").write_bytes(exr[: len(exr) // 2])
    np.save(d / "nan.npy", nan)
    np.save(d / "inf.npy", np.where(GOOD > 0, np.inf, 0.0))
    np.save(d / "3d.npy", np.zeros((4, 4, 4)))
    np.save(d / "1d.npy", np.zeros(10))
    np.save(d / "0d.npy", np.float64(1.0))
    np.save(d / "zero.npy", np.zeros((0, 5)))
    np.save(d / "str.npy", np.array([["a", "b", "c"]] * 3))
    np.save(d / "complex.npy", np.zeros((8, 8), complex))
    np.save(d / "object.npy", np.array([[1, None]], dtype=object), allow_pickle=True)
    np.save(d / "2x2.npy", np.zeros((2, 2)))
    (d / "bad.npy").write_bytes(b"\x93NUMPY garbage")
    cv2.imwrite(str(d / "alpha.png"), np.dstack([GOOD, GOOD // 2, GOOD, np.where(GOOD > 0, 255, 0).astype(np.uint8)]))
    cv2.imwrite(str(d / "1x1.png"), np.zeros((1, 1), np.uint8))
    (d / "image.txt").write_text("1 2 3")
    (d / "adir").mkdir()
    (d / "thr_bad.json").write_text("{not json")
    (d / "thr_tau.json").write_text(json.dumps({"models": {"4p": {"tau": [0.9, 0.2, 0.1]}}}))
    (d / "thr_nokey.json").write_text(json.dumps({"models": {}}))
    # a PNG whose header claims 60000 x 60000 pixels (decoding it would allocate gigabytes)
    import struct
    import zlib

    ihdr = struct.pack(">IIBBBBB", 60000, 60000, 8, 0, 0, 0, 0)
    chunk = b"IHDR" + ihdr
    (d / "huge.png").write_bytes(b"\x89PNG\r\n\x1a\n" + struct.pack(">I", len(ihdr)) + chunk
                                 + struct.pack(">I", zlib.crc32(chunk)) + png[33:])
    os.mkfifo(d / "fifo.png")  # a named pipe: reading it would block forever
    os.mkfifo(d / "fifo.toml")
    os.mkfifo(d / "fifo.json")
    (d / "afile").write_text("a regular file, not a directory")


@pytest.fixture(scope="module")
def bad(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("bad")
    _make_bad_images(d)
    return d


# --- the CLI cases: (id, argv with {B} = bad-files dir, {O} = output, expected text in the error) --
LOCATE_FILES = [
    ("trunc.png", "cannot be decoded"), ("garbage.png", "cannot be decoded"), ("empty.png", "cannot be decoded"),
    ("header_only.png", "cannot be decoded"), ("trunc.tif", "cannot be decoded"),
    ("garbage.exr", "EXR"), ("empty.exr", "EXR"), ("nan.exr", "NaN or Inf"), ("inf.exr", "NaN or Inf"),
    ("rgba.exr", "not fully opaque"), ("tiny.exr", "too small"), ("nan.npy", "NaN or Inf"), ("inf.npy", "NaN or Inf"),
    ("3d.npy", "2-D"), ("1d.npy", "2-D"), ("0d.npy", "2-D"), ("zero.npy", "too small"), ("str.npy", "not numeric"),
    ("complex.npy", "complex"), ("object.npy", ".npy"), ("2x2.npy", "too small"), ("bad.npy", ".npy"),
    ("alpha.png", "not fully opaque"), ("1x1.png", "too small"), ("image.txt", "cannot be decoded"),
    ("adir", "is a directory"), ("missing.png", "no such image"),
    ("huge.png", "60000 x 60000"), ("fifo.png", "not a regular file"),
]
CASES = [(f"locate-{f}", ["locate", "{B}/" + f, "-o", "{O}/points.csv"], msg) for f, msg in LOCATE_FILES]
CASES += [
    ("locate-method", ["locate", "{B}/good.png", "-m", "nope", "-o", "{O}/points.csv"], "unknown method"),
    ("locate-sigma-nan", ["locate", "{B}/good.png", "--sigma", "nan", "-o", "{O}/points.csv"], "sigma"),
    ("locate-sigma-neg", ["locate", "{B}/good.png", "--sigma", "-1", "-o", "{O}/points.csv"], "sigma"),
    ("locate-sigma-big", ["locate", "{B}/good.png", "--sigma", "1e9", "-o", "{O}/points.csv"], "sigma"),
    ("locate-sigma-text", ["locate", "{B}/good.png", "--sigma", "wide", "-o", "{O}/points.csv"], "--sigma"),
    ("locate-low-gt-high", ["locate", "{B}/good.png", "--low", "9", "--high", "1", "-o", "{O}/points.csv"], "low"),
    ("locate-low-neg", ["locate", "{B}/good.png", "--low", "-1", "--high", "1", "-o", "{O}/points.csv"], "low"),
    ("locate-thr-missing", ["locate", "{B}/good.png", "--thresholds", "{B}/none.json", "-o", "{O}/points.csv"],
     "does not exist"),
    ("locate-thr-json", ["locate", "{B}/good.png", "--thresholds", "{B}/thr_bad.json", "-o", "{O}/points.csv"],
     "thr_bad.json"),
    ("locate-thr-tau", ["locate", "{B}/good.png", "--thresholds", "{B}/thr_tau.json", "-o", "{O}/points.csv"],
     "thr_tau.json"),
    ("locate-thr-nokey", ["locate", "{B}/good.png", "--thresholds", "{B}/thr_nokey.json", "-o", "{O}/points.csv"],
     "thr_nokey.json"),
    ("locate-thr-method", ["locate", "{B}/good.png", "-m", "glm1984", "--thresholds", "{B}/thr_tau.json",
                           "-o", "{O}/points.csv"], "dynamic_erf"),
    ("locate-out-dir", ["locate", "{B}/good.png", "-o", "{O}"], "is a directory"),
    ("locate-out-parent", ["locate", "{B}/good.png", "-o", "{O}/no/such/points.csv"], "does not exist"),
    ("locate-out-unwritable", ["locate", "{B}/good.png", "-o", "/proc/points.csv"], "cannot write"),
    ("locate-no-output", ["locate", "{B}/good.png"], "-o"),
    ("locate-out-is-input", ["locate", "{B}/good.png", "-o", "{B}/good.png"], "also the input"),
    ("locate-out-is-input-relative", ["locate", "{B}/good.png", "-o", "{B}/adir/../good.png"], "also the input"),
    ("locate-out-parent-file", ["locate", "{B}/good.png", "-o", "{B}/afile/points.csv"], "is a file"),
    ("locate-thr-fifo", ["locate", "{B}/good.png", "--thresholds", "{B}/fifo.json", "-o", "{O}/points.csv"],
     "not a regular file"),
    ("locate-plugin-missing", ["locate", "{B}/good.png", "--plugin", "{B}/none.py", "-o", "{O}/points.csv"],
     "no such file"),
    # render: options and outputs (specs are below)
    ("render-only-text", ["render", "{SPEC}", "-o", "{O}", "--only", "x"], "--only"),
    ("render-only-range", ["render", "{SPEC}", "-o", "{O}", "--only", "999"],
     "has images 0-2, and 1 of the indices asked for lie beyond them"),
    ("render-only-reversed", ["render", "{SPEC}", "-o", "{O}", "--only", "2-1"], "--only"),
    ("render-workers-0", ["render", "{SPEC}", "-o", "{O}", "--workers", "0"], "--workers"),
    ("render-workers-text", ["render", "{SPEC}", "-o", "{O}", "--workers", "many"], "--workers"),
    ("render-backend", ["render", "{SPEC}", "-o", "{O}", "--backend", "dask"], "--backend"),
    ("render-address-local", ["render", "{SPEC}", "-o", "{O}", "--address", "head:6379"], "--address"),
    ("render-address-garbage", ["render", "{SPEC}", "-o", "{O}", "--backend", "ray", "--address", "garbage"],
     "--address"),
    ("render-address-dead", ["render", "{SPEC}", "-o", "{O}", "--backend", "ray", "--address", "127.0.0.1:1"],
     "nothing answers"),
    ("render-variant", ["render", "{SPEC}", "-o", "{O}", "--variant", "nosuch_rgb"], "--variant"),
    ("render-out-is-file", ["render", "{SPEC}", "-o", "{B}/good.png"], "is a file"),
    ("render-out-unwritable", ["render", "{SPEC}", "-o", "/proc/edgetruth-out"], "cannot create"),
    ("render-other-spec", ["render", "{OTHER}", "-o", "{O}"], "another spec"),
    ("render-spec-missing", ["render", "no-such-spec", "-o", "{O}"], "not found"),
    ("render-spec-dir", ["render", "{B}/adir/", "-o", "{O}"], "is a directory"),
    ("render-spec-fifo", ["render", "{B}/fifo.toml", "-o", "{O}"], "not a regular file"),
    ("render-out-parent-file", ["render", "{SPEC}", "-o", "{B}/afile/data"], "is a file"),
    ("render-out-foreign", ["render", "{SPEC}", "-o", "{B}"], "not an edgetruth dataset"),
    # verify
    ("verify-missing", ["verify", "{B}/no-such-dir"], "no such directory"),
    ("verify-file", ["verify", "{B}/good.png"], "not a directory"),
    ("verify-no-manifest", ["verify", "{B}/adir"], "no manifest.json"),
    ("verify-bad-json", ["verify", "{BADMAN}/json"], "not valid JSON"),
    ("verify-not-dict", ["verify", "{BADMAN}/list"], "not an edgetruth manifest"),
    ("verify-bad-sha", ["verify", "{BADMAN}/sha"], "not an edgetruth manifest"),
    # others
    ("methods-extra-arg", ["methods", "extra"], "unrecognized"),
    ("study-negative", ["study", "synthetic", "--images-per-scenario", "-3", "-o", "{O}/s"], "must be at least 1"),
    ("study-method", ["study", "synthetic", "--methods", "nope", "-o", "{O}/s"], "unknown method"),
    ("study-which", ["study", "nosuch"], "invalid choice"),
    ("run-undistort", ["run", "--undistort", "both", "-o", "{O}/r"], "invalid choice: 'both'"),
    ("evaluate-undistort", ["evaluate", "{B}/adir", "--undistort", "pixels"], "invalid choice: 'pixels'"),
    ("calib-step-0", ["calibrate-thresholds", "--step", "0", "-o", "{O}/t.json"], "--step"),
    ("calib-step-big", ["calibrate-thresholds", "--step", "2", "-o", "{O}/t.json"], "--step"),
    ("calib-count-0", ["calibrate-thresholds", "--images-per-scenario", "0", "-o", "{O}/t.json"],
     "--images-per-scenario"),
    ("calib-out-parent", ["calibrate-thresholds", "-o", "{O}/no/such/t.json", "--images-per-scenario", "1"],
     "does not exist"),
    # the output is checked before the calibration runs (it used to fail after it)
    ("calib-out-parent-file", ["calibrate-thresholds", "-o", "{B}/afile/t.json"], "is a file"),
    ("calib-dataset-not", ["calibrate-thresholds", "--dataset", "{B}/adir", "-o", "{O}/../t.json"], "no manifest.json"),
    ("calib-dataset-missing", ["calibrate-thresholds", "--dataset", "{B}/nothere", "-o", "{O}/../t.json"],
     "no such directory"),
    ("calib-out-dir", ["calibrate-thresholds", "-o", "{O}"], "is a directory"),
    # run: the output must be a new directory or an earlier run's
    ("run-out-file", ["run", "-o", "{B}/good.png"], "is a file"),
    ("run-out-parent-file", ["run", "-o", "{B}/afile/run"], "is a file"),
    ("run-out-dataset", ["run", "-o", "{O}"], "not an edgetruth run directory"),
    ("run-thr-missing", ["run", "-o", "{O}/../newrun", "--thresholds", "{B}/none.json"], "does not exist"),
    ("run-plugin-bad", ["run", "--plugin", "no_such_module_xyz", "-o", "{O}/../newrun"], "no module named"),
    ("study-out-dataset", ["study", "synthetic", "-o", "{O}"], "holds no synthetic study"),
    ("study-out-file", ["study", "synthetic", "-o", "{B}/good.png"], "is a file"),
    ("study-thr-bad", ["study", "synthetic", "-o", "{O}/../s", "--thresholds", "{B}/thr_tau.json"], "thr_tau.json"),
    # evaluate
    ("evaluate-not-dataset", ["evaluate", "{B}/adir"], "no manifest.json"),
    ("evaluate-missing", ["evaluate", "{B}/nothere"], "no such directory"),
    ("evaluate-no-boards", ["evaluate", "{O}/../boardless"], "--calibration"),
    ("evaluate-cal-missing", ["evaluate", "{O}", "--calibration", "{B}/none.json", "-o", "{O}/../ev"], "no such"),
    ("evaluate-cal-bad", ["evaluate", "{O}", "--calibration", "{B}/thr_bad.json", "-o", "{O}/../ev"], "JSON"),
    ("evaluate-cal-shape", ["evaluate", "{O}", "--calibration", "{B}/thr_tau.json", "-o", "{O}/../ev"],
     "not an edgetruth calibration"),
    ("evaluate-cal-fifo", ["evaluate", "{O}", "--calibration", "{B}/fifo.json", "-o", "{O}/../ev"],
     "not a regular file"),
    ("evaluate-out-dataset", ["evaluate", "{O}", "-o", "{O}"], "not an edgetruth run directory"),
    ("evaluate-method", ["evaluate", "{O}", "--methods", "nope"], "unknown method"),
    ("evaluate-camthr-missing", ["evaluate", "{O}", "--camera-thresholds", "{B}/none.json", "-o", "{O}/../ev"],
     "does not exist"),
    ("run-camthr-bad", ["run", "-o", "{O}/../newrun", "--camera-thresholds", "{B}/thr_tau.json"], "thr_tau.json"),
    ("bench-only", ["bench", "--only", "nothing"], "invalid choice"),
]

# spec-value cases: text substitutions in the tiny spec -> expected text
SPEC_CASES = [
    ("count-0", ("count = 2", "count = 0"), "count"), ("count-neg", ("count = 2", "count = -1"), "count"),
    ("count-float", ("count = 2", "count = 2.5"), "count"), ("count-text", ("count = 2", 'count = "two"'), "count"),
    ("spp-0", ("spp = 4", "spp = 0"), "spp"), ("spp-text", ("spp = 4", 'spp = "many"'), "spp"),
    ("sampler", ('"multijitter"', '"nosuch"'), "sampler"), ("target", ('target = "T2"', 'target = "T9"'), "target"),
    ("kind", ('kind = "checkerboard"', 'kind = "sphere"'), "kind"),
    ("dist-neg", ("[60, 90]", "[-60, 90]"), "distance_range_cm"),
    ("dist-reversed", ("[60, 90]", "[90, 60]"), "distance_range_cm"),
    ("dist-short", ("[60, 90]", "[60]"), "distance_range_cm"),
    ("dist-text", ("[60, 90]", '"far"'), "distance_range_cm"),
    ("irradiance-neg", ("irradiance_w_m2 = 0.0044\n\n", "irradiance_w_m2 = -1\n\n"), "irradiance"),
    ("irradiance-nan", ("irradiance_w_m2 = 0.0044\n\n", "irradiance_w_m2 = nan\n\n"), "irradiance"),
    ("tilt", ("tilt_max_deg = 5", "tilt_max_deg = 95"), "tilt_max_deg"),
    ("lateral", ("lateral_fraction = 0.5", "lateral_fraction = 3"), "lateral_fraction"),
    ("camera-missing", ("tiny_cam.toml", "nope_cam.toml"), "camera file"),
    ("unknown-key", ("count = 2", 'count = 2\ncolour = "red"'), "unknown key(s)"),
    ("no-group-name", ('name = "T2"\n', ""), "name"),
    ("duplicate-group", ('name = "cal"', 'name = "T2"'), "unique"),
    ("toml-syntax", ("[[group]]\nname = \"cal\"", "[[[group]]\nname = \"cal\""), "invalid TOML"),
    ("spec-name", ('name = "tiny"', 'name = "../evil"'), "name"),
    ("sensor-bits", ("[[group]]\nname = \"T2\"", "[sensor]\nbits = -3\n[[group]]\nname = \"T2\""), "bits"),
    ("sensor-key", ("[[group]]\nname = \"T2\"", "[sensor]\nfoo = 3\n[[group]]\nname = \"T2\""), "unknown key(s)"),
    ("sensor-qe", ("[[group]]\nname = \"T2\"", "[sensor]\nqe = 7\n[[group]]\nname = \"T2\""), "qe"),
    ("camera-scale", ("spp = 4", "spp = 4\ncamera_scale = 0"), "camera_scale"),
    ("target-size", ("spp = 4", "spp = 4\ntarget_size_m = -0.1"), "target_size_m"),
    ("checker-cols", ("cols = 6", "cols = 0"), "checkerboard: cols"),
    ("checker-key", ("cols = 6", "colz = 6"), "unknown key(s)"),
    ("no-groups", (None, None), "group"),
    ("unknown-table", ("[[group]]\nname = \"T2\"", "[lights]\nn = 2\n[[group]]\nname = \"T2\""), "unknown table(s)"),
]


def _spec_variant(base: Path, d: Path, case: str, old, new) -> Path:
    text = base.read_text()
    if old is None:
        text = text.split("[[group]]")[0]
    else:
        assert old in text, (case, old)
        text = text.replace(old, new, 1)
    p = d / f"bad-{case}.toml"
    p.write_text(text)
    return p


def _bad_manifests(d: Path) -> Path:
    root = d / "badman"
    for name, text in [("json", "{oops"), ("list", "[1, 2]"),
                       ("sha", json.dumps({"n_images": 1, "images": {"a": {"files": {"png": {"path": "a.png",
                                                                                              "sha256": "xyz"}}}}}))]:
        (root / name).mkdir(parents=True)
        (root / name / "manifest.json").write_text(text)
    return root


def _check_one_line_error(rc: int, err: str, command: str, expect: str) -> None:
    assert rc == 2, err
    assert "Traceback" not in err
    lines = [l for l in err.splitlines() if l.strip()]
    assert len(lines) == 1, err  # argparse's usage errors too (OneLineParser)
    last = lines[-1]
    # argparse reports arguments left over after a subcommand as the top-level parser
    assert last.startswith((f"edgetruth {command}: error:", "edgetruth: error:")), err
    assert expect in last, (expect, last)


@pytest.fixture
def env(tmp_path, bad, dataset_copy):
    """The output dir is an existing dataset (must stay untouched) + the spec that made it."""
    spec, out = dataset_copy
    (out / "points.csv").write_text("x,y\n1,2\n")  # an existing locate output
    other = tmp_path / "other.toml"
    other.write_text(spec.read_text().replace("count = 2", "count = 1"))
    boardless = out.parent / "boardless"  # the dataset without its checkerboard: nothing to calibrate from
    shutil.copytree(out, boardless)
    m = json.loads((boardless / "manifest.json").read_text())
    m["images"] = {k: v for k, v in m["images"].items() if v["kind"] != "checkerboard"}
    (boardless / "manifest.json").write_text(json.dumps(m))
    return {"B": str(bad), "O": str(out), "SPEC": str(spec), "OTHER": str(other),
            "BADMAN": str(_bad_manifests(tmp_path)), "out": out}


def _run_cli(argv, capsys):
    try:
        rc = main(argv)
    except SystemExit as exc:  # argparse
        rc = exc.code
    cap = capsys.readouterr()
    return rc, cap.err


@pytest.mark.parametrize("case, argv, expect", CASES, ids=[c[0] for c in CASES])
def test_cli_bad_input(case, argv, expect, env, capsys):
    argv = [a.format(**env) for a in argv]
    before = tree_hash(env["out"])
    rc, err = _run_cli(argv, capsys)
    _check_one_line_error(rc, err, argv[0], expect)
    assert tree_hash(env["out"]) == before, "the existing output changed"


@pytest.mark.parametrize("case, sub, expect", SPEC_CASES, ids=[c[0] for c in SPEC_CASES])
def test_render_bad_spec_values(case, sub, expect, env, tmp_path, capsys):
    spec = _spec_variant(Path(env["SPEC"]), tmp_path, case, *sub)
    before = tree_hash(env["out"])
    rc, err = _run_cli(["render", str(spec), "-o", env["O"]], capsys)
    _check_one_line_error(rc, err, "render", expect)
    assert tree_hash(env["out"]) == before
    new = tmp_path / "fresh"
    rc, err = _run_cli(["render", str(spec), "-o", str(new)], capsys)
    assert rc == 2 and not new.exists(), "a rejected spec must not create its output directory"


@pytest.mark.parametrize("case, sub, expect", SPEC_CASES, ids=[c[0] for c in SPEC_CASES])
def test_load_spec_raises_one_line_value_error(case, sub, expect, tiny_dataset, tmp_path):
    from edgetruth.render.dataset.spec import load_spec

    spec = _spec_variant(tiny_dataset[0], tmp_path, case, *sub)
    with pytest.raises(ValueError) as info:
        load_spec(spec)
    assert expect in str(info.value) and "\n" not in str(info.value)


def test_every_command_rejects_an_unknown_option(capsys):
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    commands = sorted(sub.choices)
    assert {"locate", "render", "verify", "methods"} <= set(commands)
    for cmd in commands:
        rc, err = _run_cli([cmd, "--no-such-option"], capsys)
        assert rc == 2 and "error:" in err.strip().splitlines()[-1] and "Traceback" not in err, cmd


def test_study_zero_images_is_rejected(capsys, tmp_path):
    rc, err = _run_cli(["study", "synthetic", "--images-per-scenario", "0", "-o", str(tmp_path / "s")], capsys)
    assert rc == 2


def test_bench_zero_repeats_is_rejected(capsys):
    rc, err = _run_cli(["bench", "--repeats", "0"], capsys)
    assert rc == 2


# --- a few via subprocess: the real entry point prints no traceback ---------------------------
@pytest.mark.parametrize("argv", [
    ["locate", "{B}/trunc.png", "-o", "{O}/points.csv"],
    ["locate", "{B}/nan.npy", "-m", "nope", "-o", "{O}/points.csv"],
    ["render", "{B}/adir/x.toml", "-o", "{O}"],
    ["render", "{SPEC}", "-o", "{O}", "--backend", "ray", "--address", "127.0.0.1:1"],
    ["verify", "{BADMAN}/json"],
], ids=["locate-trunc", "locate-method", "render-spec", "render-address", "verify-json"])
def test_subprocess_no_traceback(argv, env):
    argv = [a.format(**env) for a in argv]
    before = tree_hash(env["out"])
    code = "import sys; from edgetruth.cli import main; sys.exit(main(sys.argv[1:]))"
    r = subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert r.stderr.strip().splitlines()[-1].startswith(f"edgetruth {argv[0]}: error:")
    assert tree_hash(env["out"]) == before


def test_truncated_exr_is_one_line(env, capfd):
    """The EXR decoder (C library) must not print its own diagnostics before edgetruth's line."""
    argv = ["locate", f"{env['B']}/trunc.exr", "-o", f"{env['O']}/points.csv"]
    try:
        rc = main(argv)
    except SystemExit as exc:
        rc = exc.code
    err = capfd.readouterr().err
    assert rc == 2 and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1, err


# --- the locate API: ValueError (InputError) naming the input ---------------------------------
def _img():
    return GOOD.astype(np.float64)


API_CASES = [
    ("unknown-method", lambda L: L.locate(_img(), "nope"), "unknown method"),
    ("method-none", lambda L: L.locate(_img(), None), "unknown method"),
    ("image-none", lambda L: L.locate(None), "image"),
    ("image-ragged", lambda L: L.locate([[1, 2], [3]]), "image"),
    ("image-str", lambda L: L.candidates("image.png"), "not numeric"),
    ("image-dict", lambda L: L.locate({"a": 1}), "not numeric"),
    ("image-3d", lambda L: L.locate(np.zeros((5, 5, 3))), "2-D"),
    ("image-empty", lambda L: L.locate(np.zeros((0, 0), np.int8)), "too small"),
    ("image-nan", lambda L: L.candidates(np.full((10, 10), np.nan)), "NaN or Inf"),
    ("image-complex", lambda L: L.locate(np.zeros((9, 9), complex)), "complex"),
    ("sigma-nan", lambda L: L.candidates(_img(), sigma_px=float("nan")), "sigma"),
    ("sigma-neg", lambda L: L.candidates(_img(), sigma_px=-1), "sigma"),
    ("low-gt-high", lambda L: L.candidates(_img(), low=10, high=1), "low"),
    ("low-nan", lambda L: L.candidates(_img(), low=float("nan"), high=1), "low"),
    ("refine-shape", lambda L: L.refine(np.zeros((30, 30)), L.candidates(_img()), "glm1984"), "candidates"),
    ("refine-method", lambda L: L.refine(_img(), L.candidates(_img()), "nope"), "unknown method"),
    ("refine-nan", lambda L: L.refine(np.where(_img() > 0, np.nan, 0), L.candidates(_img()), "glm1984"), "NaN"),
    ("refine-tau-order", lambda L: L.refine(_img(), L.candidates(_img()), "dynamic_erf_4p", tau=(0.9, 0.1, 0.5)),
     "thresholds"),
    ("refine-tau-len", lambda L: L.refine(_img(), L.candidates(_img()), "dynamic_erf_2p", tau=(0.1,)), "thresholds"),
]
API_CASES += [
    ("sigma-text", lambda L: L.candidates(_img(), sigma_px="wide"), "must be numbers"),
    ("refine-cand-none", lambda L: L.refine(_img(), None, "glm1984"), "locate.candidates"),
    ("refine-unknown-option", lambda L: L.refine(_img(), L.candidates(_img()), "hagara_aef2011", window=3),
     "no option"),
    ("refine-unknown-option-glm", lambda L: L.refine(_img(), L.candidates(_img()), "glm1984", foo=1), "no option"),
]


@pytest.mark.parametrize("case, call, expect", API_CASES, ids=[c[0] for c in API_CASES])
def test_locate_api_bad_input_is_value_error(case, call, expect):
    from edgetruth import locate

    with pytest.raises(ValueError) as info:
        call(locate)
    assert expect in str(info.value)


