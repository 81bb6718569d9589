"""A generation killed with SIGKILL at random moments and resumed each time ends byte-identical
to an uninterrupted run; no file under a final name is ever partial; complete images are never
rendered again."""
from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

from edgetruth.render.testing import write_tiny_spec

N_KILLS = 5


def _final_files(d: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(d.iterdir()) if p.is_file() and not p.name.startswith(".tmp-")}


def _children(pid: int) -> list[int]:
    out = []
    for status in Path("/proc").glob("[0-9]*/status"):
        try:
            if f"\nPPid:\t{pid}\n" in status.read_text():
                out.append(int(status.parent.name))
        except OSError:
            pass
    return out


def _gone(pids: list[int], timeout_s: float = 10.0) -> bool:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        alive = []
        for p in pids:
            try:
                if "State:\tZ" not in Path(f"/proc/{p}/status").read_text():
                    alive.append(p)
            except OSError:
                pass
        if not alive:
            return True
        time.sleep(0.1)
    return False


def _cmd(spec: Path, out: Path, workers: int) -> list[str]:
    code = "import sys; from edgetruth.cli import main; sys.exit(main(sys.argv[1:]))"
    return [sys.executable, "-c", code, "render", str(spec), "-o", str(out), "--no-progress",
            "--workers", str(workers)]


def test_sigkill_at_random_moments_then_resume_is_byte_identical(tmp_path):
    from edgetruth.render.driver import render_spec

    spec = write_tiny_spec(tmp_path, spp=8)
    spec.write_text(spec.read_text().replace("count = 2", "count = 5"))  # 6 images
    ref = tmp_path / "ref"
    t0 = time.perf_counter()
    render_spec(spec, ref, progress=False, announce=lambda s: None)  # uninterrupted, in-process
    reference = _final_files(ref)
    assert len(reference) == 6 * 3 + 1

    # how long one uninterrupted CLI run takes here (interpreter start, probe, renders): kill moments
    # are drawn inside it, so the test kills mid-way on a fast idle machine and on a loaded one alike
    t_run = time.perf_counter()
    timing = subprocess.run(_cmd(spec, tmp_path / "timing", workers=1), capture_output=True, text=True, timeout=300)
    assert timing.returncode == 0, timing.stderr
    t_run = time.perf_counter() - t_run

    out = tmp_path / "killed"
    rng = random.Random(20240607)
    kills = attempts = 0
    inodes: dict[str, int] = {}
    while kills < N_KILLS:
        attempts += 1
        assert attempts <= 6 * N_KILLS, "could not kill the run mid-way often enough"
        # complete images before this run: their files must never be rewritten
        if (out / "manifest.json").is_file():
            m = json.loads((out / "manifest.json").read_text())
            inodes = {f["path"]: os.stat(out / f["path"]).st_ino
                      for e in m["images"].values() for f in e["files"].values()}
        proc = subprocess.Popen(_cmd(spec, out, workers=1 + attempts % 2), stdout=subprocess.DEVNULL,
                                stderr=subprocess.PIPE, env=dict(os.environ, PYTHONUNBUFFERED="1"))
        time.sleep(rng.uniform(0.05, 0.9) * t_run)
        workers: list[int] = []
        if proc.poll() is None:
            workers = _children(proc.pid)  # pool workers, variant probe, resource tracker
            proc.send_signal(signal.SIGKILL)
            kills += 1
        proc.wait()
        if sys.platform.startswith("linux"):  # workers die with the driver: no orphan keeps writing
            assert _gone(workers), f"processes {workers} outlived the killed driver"
        proc.stderr.close()
        # invariants at the moment of the kill: every final-named file is whole (== reference bytes)
        now = _final_files(out) if out.exists() else {}
        for name, data in now.items():
            if name == "manifest.json":
                m = json.loads(data)  # parses: never partial
                for n, e in m["images"].items():
                    assert all((out / f["path"]).read_bytes() == reference[f["path"]] for f in e["files"].values())
            else:
                assert data == reference[name], f"{name} is partial or differs after kill {kills}"
        for path, ino in inodes.items():
            assert os.stat(out / path).st_ino == ino, f"{path} was re-rendered although complete"
        if proc.returncode == 0 and kills < N_KILLS:  # finished before the kill: start over
            for p in out.iterdir():
                p.unlink()
            inodes = {}
    r = subprocess.run(_cmd(spec, out, workers=2), capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "Traceback" not in r.stderr
    assert _final_files(out) == reference
    assert not [p for p in out.iterdir() if p.name.startswith(".tmp-")]
    assert time.perf_counter() - t0 < 300
