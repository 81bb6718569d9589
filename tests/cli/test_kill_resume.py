"""A render killed with SIGKILL at random moments -- and at each step of the final compaction of its
journal into manifest.json -- and resumed each time ends byte-identical to an uninterrupted run; no
file under a final name is ever partial; images already recorded are never rendered again."""
from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from edgetruth.render.dataset.reader import load_manifest
from edgetruth.render.testing import write_tiny_spec

N_KILLS = 6
N_IMAGES = 12


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


_MAIN = "import sys; from edgetruth.cli import main; sys.exit(main(sys.argv[1:]))"


def _cmd(spec: Path, out: Path, workers: int, prelude: str = "") -> list[str]:
    return [sys.executable, "-c", prelude + _MAIN, "render", str(spec), "-o", str(out), "--no-progress",
            "--workers", str(workers)]


def _spec(tmp_path: Path) -> Path:
    # 256 spp: each image takes long enough that random kills land between, and inside, renders
    spec = write_tiny_spec(tmp_path, spp=256)
    spec.write_text(spec.read_text().replace("count = 2", f"count = {N_IMAGES - 1}"))
    return spec


def _recorded(out: Path) -> int:
    j = out / "journal.jsonl"
    try:
        return max(0, j.read_bytes().count(b"\n") - 1)
    except OSError:
        return 0


def _check_invariants(out: Path, reference: dict[str, bytes], inodes: dict[str, int], when: str) -> None:
    """At the moment of a kill: the manifest parses, every recorded image's files are whole
    (== reference), every final-named file is whole, recorded files were not rewritten."""
    if not out.exists():
        return
    now = _final_files(out)
    if "manifest.json" in now:
        json.loads(now["manifest.json"])  # never partial
        for e in load_manifest(out)["images"].values():  # manifest + journal (torn tail ignored)
            for f in e["files"].values():
                assert (out / f["path"]).read_bytes() == reference[f["path"]], f"{f['path']} {when}"
    for name, data in now.items():
        if name not in ("manifest.json", "journal.jsonl"):
            assert data == reference[name], f"{name} is partial or differs {when}"
    for path, ino in inodes.items():
        assert os.stat(out / path).st_ino == ino, f"{path} was re-rendered although recorded ({when})"


def _inodes(out: Path) -> dict[str, int]:
    if not (out / "manifest.json").is_file():
        return {}
    return {f["path"]: os.stat(out / f["path"]).st_ino
            for e in load_manifest(out)["images"].values() for f in e["files"].values()}


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    from edgetruth.render.dataset.driver import render_spec

    root = tmp_path_factory.mktemp("killref")
    spec = _spec(root)
    render_spec(spec, root / "ref", progress=False, announce=lambda s: None)  # uninterrupted, in-process
    ref = _final_files(root / "ref")
    assert len(ref) == N_IMAGES * 3 + 1
    return spec, ref


@pytest.mark.slow
def test_sigkill_at_random_moments_then_resume_is_byte_identical(tmp_path, reference):
    spec, ref = reference
    t0 = time.perf_counter()
    # one uninterrupted CLI run: when the first image is recorded and when it ends.  Half the kills
    # fall anywhere in a run (start-up, manifest creation, ...), half inside the rendering phase.
    t_run = time.perf_counter()
    proc = subprocess.Popen(_cmd(spec, tmp_path / "timing", workers=1), stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE)
    t_first = None
    while proc.poll() is None:
        if t_first is None and _recorded(tmp_path / "timing"):
            t_first = time.perf_counter() - t_run
        time.sleep(0.005)
    assert proc.returncode == 0, proc.stderr.read().decode()
    proc.stderr.close()
    t_run = time.perf_counter() - t_run
    t_first = t_first if t_first is not None else 0.5 * t_run

    out = tmp_path / "killed"
    rng = random.Random(20240607)
    kills = attempts = 0
    while kills < N_KILLS:
        attempts += 1
        assert attempts <= 6 * N_KILLS, "could not kill the run mid-way often enough"
        inodes = _inodes(out)
        proc = subprocess.Popen(_cmd(spec, out, workers=1 + attempts % 2), stdout=subprocess.DEVNULL,
                                stderr=subprocess.PIPE, env=dict(os.environ, PYTHONUNBUFFERED="1"))
        if kills % 2:
            time.sleep(rng.uniform(0.05, 0.95) * t_run)
        else:  # inside the rendering phase: after this run records its first image
            start, recorded = time.perf_counter(), _recorded(out)
            while proc.poll() is None and _recorded(out) == recorded and time.perf_counter() - start < 2 * t_run:
                time.sleep(0.002)
            time.sleep(rng.uniform(0.0, 0.9) * max(t_run - t_first, 0.05))
        workers: list[int] = []
        if proc.poll() is None:
            workers = _children(proc.pid)  # pool workers, variant probe, resource tracker
            proc.send_signal(signal.SIGKILL)
            kills += 1
        proc.wait()
        if sys.platform.startswith("linux"):  # workers die with the driver: no orphan keeps writing
            assert _gone(workers), f"processes {workers} outlived the killed driver"
        proc.stderr.close()
        _check_invariants(out, ref, inodes, f"after kill {kills}")
        if proc.returncode == 0 and kills < N_KILLS:  # finished before the kill: start over
            for p in out.iterdir():
                p.unlink()
    r = subprocess.run(_cmd(spec, out, workers=2), capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "Traceback" not in r.stderr
    assert _final_files(out) == ref
    assert not [p for p in out.iterdir() if p.name.startswith(".tmp-")]
    assert time.perf_counter() - t0 < 300


# The final compaction, step by step: a SIGKILL (from the driver itself, at an exact point)
#  - "entries": while the merged manifest is being written to its temporary file,
#  - "rename": the temporary is complete and synced, not yet renamed over manifest.json,
#  - "unlink": manifest.json replaced, the (now merged) journal not yet deleted.
_KILL_AT = {
    "entries": """
from edgetruth.render.dataset import journal as _j
_orig, _n = _j._entry_line, [0]
def _line(*a):
    _n[0] += 1
    if _n[0] == 5:
        import os, signal; os.kill(os.getpid(), signal.SIGKILL)
    return _orig(*a)
_j._entry_line = _line
""",
    "rename": """
import os as _os
_orig = _os.replace
def _replace(src, dst):
    from pathlib import Path
    if Path(dst).name == "manifest.json" and (Path(dst).parent / "journal.jsonl").exists():
        import signal; _os.kill(_os.getpid(), signal.SIGKILL)
    return _orig(src, dst)
_os.replace = _replace
""",
    "unlink": """
import pathlib as _p
_orig = _p.Path.unlink
def _unlink(self, *a, **k):
    if self.name == "journal.jsonl":
        import os, signal; os.kill(os.getpid(), signal.SIGKILL)
    return _orig(self, *a, **k)
_p.Path.unlink = _unlink
""",
}


@pytest.mark.parametrize("point", list(_KILL_AT))
def test_sigkill_during_compaction_then_resume_is_byte_identical(tmp_path, reference, point):
    spec, ref = reference
    out = tmp_path / "out"
    r = subprocess.run(_cmd(spec, out, workers=1, prelude=_KILL_AT[point] + "\n"), capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == -signal.SIGKILL, r.stderr  # killed inside the compaction
    assert (out / "journal.jsonl").exists()
    _check_invariants(out, ref, {}, f"at {point}")
    assert len(load_manifest(out)["images"]) == N_IMAGES  # every image is recorded (manifest or journal)
    inodes = _inodes(out)
    r = subprocess.run(_cmd(spec, out, workers=1), capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "nothing to do" in r.stdout  # resumed: no image rendered again, only compacted
    assert _final_files(out) == ref
    assert not [p for p in out.iterdir() if p.name.startswith(".tmp-") or p.name == "journal.jsonl"]
    _check_invariants(out, ref, inodes, f"after resuming from {point}")
