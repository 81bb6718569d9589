"""A real two-node Ray cluster on this machine: a head and a second node started with ``ray start``
(separate raylets, one CPU each, a private temporary directory), ``edgetruth render --backend ray
--files driver`` across both (the file bytes come back to the driver, as when workers do not share
its disk), the second node killed mid-run: the run finishes on the survivor, the dataset is
byte-identical to a local run, and every process the test started is gone afterwards.

- While the second node renders its first images, another driver's task holds the head's one
  CPU, so the kill lands after a known share on the second node; then the head renders the rest.
- Clean-up is by process: each node runs ``ray start --block`` in a process group of its own; a
  reaper process kills those groups, every process still naming the cluster's private
  directory, and all their descendants (Ray gives each worker a process group of its own), when
  the test ends or when this test process dies first.  ``ray stop`` is not used: it stops every
  Ray process on the machine, other users' too, whatever their temporary directory.
- Ray rewrites a 127.0.0.1 node address to the host's own address (``resolve_ip_for_localhost``);
  traffic to it stays on this machine.
- The driver is a fresh process: Ray 2.60 fails object transfers between nodes for a driver that
  already ran an earlier Ray session in the same process (``OwnerDiedError``).
"""
from __future__ import annotations

import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from edgetruth.render.testing import write_patch_spec

N_IMAGES = 600
KILL_AT = 150  # images recorded when the second node is killed

# When its stdin closes (the test says so, or the test process died): kills the processes given
# (one pid a line: each ``ray start``, leader of its process group), their groups, every process
# naming ROOT, and all their descendants; then deletes ROOT and prints how many are left.
_REAPER = r"""
import os, shutil, signal, sys, time
root, groups = sys.argv[1], set()
for line in sys.stdin:
    groups.add(int(line))
def ours():
    procs = {}
    for p in os.listdir("/proc"):
        if p.isdigit() and int(p) != os.getpid():
            try:
                st = open(f"/proc/{p}/stat").read().rsplit(")", 1)[1].split()
                cmd = open(f"/proc/{p}/cmdline", "rb").read().decode(errors="replace")
            except (OSError, IndexError):
                continue
            if st[0] != "Z":
                procs[int(p)] = (int(st[1]), int(st[2]), cmd)
    out = {p for p, (pp, g, cmd) in procs.items() if p in groups or g in groups or root in cmd}
    while True:  # and their descendants
        more = {p for p, (pp, g, cmd) in procs.items() if pp in out and p not in out}
        if not more:
            return out
        out |= more
for _ in range(100):
    for g in groups:
        try: os.killpg(g, signal.SIGKILL)
        except OSError: pass
    left = ours()
    if not left:
        break
    for p in left:
        try: os.kill(p, signal.SIGKILL)
        except OSError: pass
    time.sleep(0.1)
shutil.rmtree(root, ignore_errors=True)
print(len(ours()))
"""


# Another Ray driver holding the head node's CPU with one task until a file appears.
_HOLD = r"""
import os, sys, time
import ray
from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

address, head, held, release = sys.argv[1:5]
ray.init(address=address, log_to_driver=False)


@ray.remote(num_cpus=1)
def hold(held, release):
    open(held, "w").close()
    while not os.path.exists(release):
        time.sleep(0.02)


ray.get(hold.options(scheduling_strategy=NodeAffinitySchedulingStrategy(head, soft=False)).remote(held, release))
"""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _ray_start(args: list[str], log: Path, env: dict) -> subprocess.Popen:
    ray_cli = str(Path(sys.executable).with_name("ray"))
    # --block: the node's processes stay in this one's process group (start_new_session)
    return subprocess.Popen([ray_cli, "start", "--block", "--num-cpus", "1", "--node-ip-address", "127.0.0.1",
                             "--disable-usage-stats", *args], stdout=log.open("w"), stderr=subprocess.STDOUT,
                            env=env, start_new_session=True)


def _wait(cond, timeout_s: float, what: str, logs=()) -> None:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if cond():
            return
        time.sleep(0.1)
    tails = "\n".join(f"--- {p}:\n" + p.read_text()[-1500:] for p in logs if p.exists())
    raise AssertionError(f"{what} not within {timeout_s:.0f} s\n{tails}")


def _tree(roots: set[int]) -> dict[int, str]:
    """{pid: command line} of ``roots`` and all their descendants (Ray puts its worker processes
    in process groups of their own, so a group does not hold a node's workers; its raylet does)."""
    procs = {}
    for p in Path("/proc").iterdir():
        try:
            if p.name.isdigit():
                st = (p / "stat").read_text().rsplit(")", 1)[1].split()
                if st[0] != "Z":
                    procs[int(p.name)] = (int(st[1]), (p / "cmdline").read_bytes().decode(errors="replace"))
        except (OSError, IndexError, ValueError):
            pass
    out, frontier = {}, set(roots)
    while frontier:
        out.update({pid: procs[pid][1] for pid in frontier if pid in procs})
        frontier = {pid for pid, (ppid, _) in procs.items() if ppid in frontier and pid not in out}
    return out


def _kill_tree(root: int) -> None:
    for pid in _tree({root}):  # everything at once: orphans would leave the tree
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def _recorded(out: Path) -> int:
    try:
        return max(0, (out / "journal.jsonl").read_bytes().count(b"\n") - 1)
    except OSError:
        return 0


def _alive_nodes(address: str, env: dict) -> list[tuple[str, bool]]:
    """(node id, is head) of the live nodes, asked in a short-lived process (no Ray session here)."""
    code = ("import ray, sys; ray.init(address=sys.argv[1], log_to_driver=False); "
            "[print(n['NodeID'], 'node:__internal_head__' in n['Resources']) for n in ray.nodes() if n['Alive']]")
    r = subprocess.run([sys.executable, "-c", code, address], capture_output=True, text=True, env=env, timeout=120)
    return [(a, b == "True") for a, b in re.findall(r"^([0-9a-f]{56}) (True|False)$", r.stdout, re.M)]


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="finds and kills the cluster's processes via /proc")
def test_two_node_render_survives_losing_a_node_and_matches_a_local_run(tmp_path):
    pytest.importorskip("ray", reason="ray is not installed: pip install 'edgetruth[test]'")
    if not Path(sys.executable).with_name("ray").exists():
        pytest.skip("the `ray` command is not installed next to this Python")
    from edgetruth.render.dataset.driver import render_spec

    spec = write_patch_spec(tmp_path, N_IMAGES, name="cluster")
    t0 = time.perf_counter()
    render_spec(spec, tmp_path / "local", progress=False, announce=lambda s: None)
    t_local = time.perf_counter() - t0

    # a short private root: Ray's socket paths must stay under ~107 characters
    root = Path(tempfile.mkdtemp(prefix="etray-", dir="/tmp"))
    env = {k: v for k, v in os.environ.items() if k != "RAY_ADDRESS"}
    env.update(RAY_AUTH_MODE="disabled", RAY_USAGE_STATS_ENABLED="0",
               # notice a dead node in ~1 s, not ~30 s
               RAY_health_check_period_ms="200", RAY_health_check_failure_threshold="5",
               RAY_health_check_initial_delay_ms="0", RAY_health_check_timeout_ms="500")
    reaper = subprocess.Popen([sys.executable, "-c", _REAPER, str(root)], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, text=True, start_new_session=True)
    port = _free_port()
    address = f"127.0.0.1:{port}"
    logs = [root / "head.log", root / "node.log"]
    try:
        t0 = time.perf_counter()
        head = _ray_start(["--head", "--port", str(port), "--temp-dir", str(root / "head"),
                           "--include-dashboard", "false"], logs[0], env)
        reaper.stdin.write(f"{head.pid}\n")
        reaper.stdin.flush()

        def gcs_up():
            try:
                socket.create_connection(("127.0.0.1", port), 0.5).close()
                return True
            except OSError:
                return head.poll() is not None

        _wait(gcs_up, 120, "the head node", logs)
        assert head.poll() is None, logs[0].read_text()[-2000:]
        node = _ray_start(["--address", address, "--temp-dir", str(root / "node")], logs[1], env)
        reaper.stdin.write(f"{node.pid}\n")
        reaper.stdin.flush()
        nodes: list = []

        def both_up():
            nodes[:] = _alive_nodes(address, env)
            return len(nodes) == 2

        _wait(both_up, 120, "the second node", logs)
        second = next(n for n, is_head in nodes if not is_head)
        t_cluster = time.perf_counter() - t0

        # hold the head's one CPU with a task of another driver until the second node has rendered
        # KILL_AT images: then the second node dies, the hold ends, and the head renders the rest
        head_id = next(n for n, is_head in nodes if is_head)
        hold = subprocess.Popen([sys.executable, "-c", _HOLD, address, head_id, str(root / "held"), str(root / "release")],
                                env=env, start_new_session=True, stdout=subprocess.DEVNULL,
                                stderr=(root / "hold.log").open("w"))
        reaper.stdin.write(f"{hold.pid}\n")
        reaper.stdin.flush()
        _wait(lambda: (root / "held").exists(), 120, "the head's CPU to be held", logs + [root / "hold.log"])
        out = tmp_path / "cluster"
        t0 = time.perf_counter()
        logs += [root / "driver.out", root / "driver.err"]
        with logs[2].open("w") as fo, logs[3].open("w") as fe:
            driver = subprocess.Popen([sys.executable, "-m", "edgetruth", "render", str(spec), "-o", str(out),
                                       "--backend", "ray", "--address", address, "--files", "driver", "--no-progress"],
                                      stdout=fo, stderr=fe, env=env)
        # the head's CPU is held, so every image recorded so far is the second node's
        _wait(lambda: _recorded(out) >= KILL_AT or driver.poll() is not None, 300, "the second node to render", logs)
        assert driver.poll() is None, logs[3].read_text()[-3000:]
        _kill_tree(node.pid)  # its raylet, workers, agents: the whole node, at once
        killed_at = _recorded(out)
        (root / "release").touch()  # the head takes over
        hold.wait(timeout=120)
        driver.wait(timeout=300)
        t_render = time.perf_counter() - t0
        stdout = logs[2].read_text()
        assert driver.returncode == 0, logs[3].read_text()[-3000:]
        assert killed_at < N_IMAGES - 100, "the second node was killed too late to matter"
        per_node = dict((k, int(v)) for k, v in re.findall(r"([0-9a-f]{12}) (\d+)", stdout.split("per Ray node:")[-1]))
        assert per_node.get(second[:12], 0) >= KILL_AT, f"the second node's share is missing: {stdout}"
        assert per_node.get(head_id[:12], 0) >= N_IMAGES - per_node[second[:12]] > 0, stdout  # the rest: the head
        assert sum(per_node.values()) == N_IMAGES, stdout
        assert f"{N_IMAGES}/{N_IMAGES} images" in stdout
        a = {p.name: p.read_bytes() for p in sorted((tmp_path / "local").iterdir())}
        b = {p.name: p.read_bytes() for p in sorted(out.iterdir())}
        assert a.keys() == b.keys() and a == b  # every file, manifest included
        print(f"{N_IMAGES} tiny images: local {t_local:.1f} s; two-node cluster up in {t_cluster:.1f} s; render "
              f"{t_render:.1f} s (driver start included), the second node killed at {killed_at} images recorded; "
              f"images per node: head {N_IMAGES - per_node[second[:12]]}, second {per_node[second[:12]]}")
    finally:
        reaper.stdin.close()  # kill the cluster, wait for it to be gone
        left = reaper.stdout.read().strip()
        reaper.wait(timeout=60)
        shutil.rmtree(root, ignore_errors=True)
    assert left == "0", f"{left} processes of the test cluster are still running"
