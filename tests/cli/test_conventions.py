"""CLI conventions: --version, -q, help text on every option, progress bars only on a terminal
(and none with --no-progress), decoder chatter silenced, corrupt caches rebuilt."""
from __future__ import annotations

import argparse
import fcntl
import os
import pty
import struct
import subprocess
import sys
import termios
from pathlib import Path

import cv2
import numpy as np
import pytest

from edgetruth import __version__, console
from edgetruth.cli import build_parser, main


def _subparsers(parser):
    for a in parser._actions:
        if isinstance(a, argparse._SubParsersAction):
            return a.choices
    return {}


def test_version(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0 and capsys.readouterr().out.strip() == f"edgetruth {__version__}"


def test_every_option_of_every_command_has_help_text():
    parser = build_parser()
    missing = [f"edgetruth {name} {'/'.join(a.option_strings) or a.dest}"
               for name, sub in {"": parser, **_subparsers(parser)}.items()
               for a in sub._actions
               if not isinstance(a, (argparse._HelpAction, argparse._SubParsersAction)) and not a.help]
    assert not missing, missing
    assert {"run", "evaluate", "render", "locate", "study", "methods", "verify", "calibrate-thresholds",
            "bench"} <= set(_subparsers(parser))


def test_commands_that_run_methods_take_plugins_and_thresholds():
    subs = _subparsers(build_parser())
    for name in ("locate", "study", "run", "evaluate", "methods"):
        assert "--plugin" in subs[name]._option_string_actions, name
    for name in ("run", "study", "evaluate", "locate"):
        assert "--thresholds" in subs[name]._option_string_actions, name


def test_bars_draw_only_on_a_terminal(monkeypatch):
    monkeypatch.setattr(sys.stderr, "isatty", lambda: False, raising=False)
    assert not console.bars_enabled(True)
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True, raising=False)
    assert console.bars_enabled(True) and not console.bars_enabled(False)
    console.set_quiet(True)
    try:
        assert not console.bars_enabled(True)
    finally:
        console.set_quiet(False)


def _on_a_terminal(argv: list[str], cwd: Path) -> str:
    """Run the CLI with stdout/stderr on a pseudo-terminal; everything it drew."""
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))  # a terminal 100 columns wide
    p = subprocess.Popen([sys.executable, "-m", "edgetruth", *argv], stdout=slave, stderr=slave, cwd=cwd,
                         stdin=subprocess.DEVNULL)
    os.close(slave)
    chunks = []
    while True:
        try:
            data = os.read(master, 4096)
        except OSError:
            break
        if not data:
            break
        chunks.append(data)
    p.wait(timeout=300)
    os.close(master)
    assert p.returncode == 0, b"".join(chunks).decode(errors="replace")[-2000:]
    return b"".join(chunks).decode(errors="replace")


def test_progress_on_a_terminal_and_silenced_by_no_progress(tmp_path):
    argv = ["study", "synthetic", "--images-per-scenario", "2", "--methods", "canny_pixel,glm1984"]
    shown = _on_a_terminal(argv + ["-o", str(tmp_path / "a")], tmp_path)
    assert "\r" in shown and "synthetic study" in shown
    quiet = _on_a_terminal(argv + ["-o", str(tmp_path / "b"), "--no-progress"], tmp_path)
    assert "synthetic study:" not in quiet and "%|" not in quiet and "report:" in quiet


def test_no_carriage_returns_in_logs(tmp_path):
    r = subprocess.run([sys.executable, "-m", "edgetruth", "study", "synthetic", "--images-per-scenario", "2",
                        "--methods", "canny_pixel", "-o", str(tmp_path / "s")], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0 and "\r" not in r.stdout + r.stderr and r.stderr == ""


def test_quiet_prints_nothing_on_success(tmp_path, capsys):
    img = np.zeros((40, 40), np.uint8)
    img[:, 20:] = 200
    cv2.imwrite(str(tmp_path / "a.png"), img)
    assert main(["-q", "locate", str(tmp_path / "a.png"), "-o", str(tmp_path / "p.csv")]) == 0
    cap = capsys.readouterr()
    assert cap.out == "" and cap.err == "" and (tmp_path / "p.csv").is_file()
    assert main(["locate", str(tmp_path / "a.png"), "-o", str(tmp_path / "p.csv")]) == 0
    assert "points" in capsys.readouterr().out


def test_decoder_chatter_is_silenced(tmp_path, capfd):
    """libpng complains on stderr about a bad CRC; edgetruth's one line must be all the user sees."""
    img = np.zeros((40, 40), np.uint8)
    img[:, 20:] = 200
    ok, buf = cv2.imencode(".png", img)
    data = bytearray(buf.tobytes())
    data[40] ^= 0xFF  # corrupt the image data chunk: CRC mismatch
    (tmp_path / "crc.png").write_bytes(bytes(data))
    rc = main(["locate", str(tmp_path / "crc.png"), "-o", str(tmp_path / "p.csv")])
    err = capfd.readouterr().err
    assert rc == 2 and len(err.strip().splitlines()) == 1 and "cannot be decoded" in err, err
    assert not (tmp_path / "p.csv").exists()


def test_corrupt_study_cache_is_rebuilt(tmp_path, capsys):
    out = tmp_path / "s"
    argv = ["study", "synthetic", "--images-per-scenario", "2", "--methods", "canny_pixel,glm1984", "-o", str(out)]
    assert main(argv) == 0
    table = (out / "tables" / "table6_all_methods.csv").read_text()
    blocks = sorted((out / "cache").glob("*.npz"))
    blocks[0].write_bytes(b"torn")  # a crash mid-write on a filesystem without atomic rename
    blocks[1].write_bytes(blocks[1].read_bytes()[:100])
    assert main(argv) == 0, capsys.readouterr().err
    new = (out / "tables" / "table6_all_methods.csv").read_text()
    strip = lambda t: [",".join(line.split(",")[:9]) for line in t.splitlines()]  # without timings
    assert strip(new) == strip(table)
    (out / "cache" / "key.json").write_text("{oops")
    assert main(argv) == 0
