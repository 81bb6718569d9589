"""A real two-node Ray cluster on this machine: a head and a second node started with ``ray start``
(separate raylets, one CPU each, their own temporary directory), a render across both with the file
bytes sent back to the driver (the mode for workers that do not share its disk), the second node
killed mid-run: the run finishes on the survivor, the dataset is byte-identical to a local run, and
every process the test started is gone afterwards.

Clean-up is by process: the nodes run with ``ray start --block`` in process groups of their own,
which are killed, then anything still naming the cluster's private temporary directory.  (``ray
stop`` is not used: it stops every Ray process on the machine, other users' too, whatever the
temporary directory.)  Ray rewrites a 127.0.0.1 node address to the host's own address
(``resolve_ip_for_localhost``); traffic to that address stays on this machine."""
from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import pytest

from edgetruth.render.testing import write_patch_spec

N_IMAGES = 400
KILL_AFTER = 20  # images the second node has rendered when it is killed


def _warm_worker() -> str:
    import ray

    import edgetruth.render.task  # noqa: F401
    import edgetruth.render.variants  # noqa: F401 -- before Mitsuba
    import mitsuba  # noqa: F401

    return ray.get_runtime_context().get_node_id()


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _processes_of(pgids: set[int], marker: str | None = None) -> dict[int, str]:
    """Live processes in the given process groups or naming ``marker`` (our temp dir) in their command line."""
    out = {}
    for p in Path("/proc").iterdir():
        if not p.name.isdigit():
            continue
        try:
            stat = (p / "stat").read_text()
            if stat.rsplit(")", 1)[1].split()[0] == "Z":
                continue
            pgid = int(stat.rsplit(")", 1)[1].split()[2])
            cmd = (p / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except (OSError, IndexError, ValueError):
            continue
        if pgid in pgids or (marker and marker in cmd):
            out[int(p.name)] = cmd[:120]
    return out


def _ray_start(args: list[str], log: Path, env: dict) -> subprocess.Popen:
    ray_cli = str(Path(sys.executable).with_name("ray"))
    # --block: the node's processes stay children of this one, in a process group of their own
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


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="finds and kills the cluster's processes via /proc")
def test_two_node_render_survives_losing_a_node_and_matches_a_local_run(tmp_path, monkeypatch):
    ray = pytest.importorskip("ray", reason="ray is not installed: pip install 'edgetruth[test]'")
    if not Path(sys.executable).with_name("ray").exists():
        pytest.skip("the `ray` command is not installed next to this Python")
    from edgetruth.render.driver import render_spec

    spec = write_patch_spec(tmp_path, N_IMAGES, name="cluster")
    t0 = time.perf_counter()
    render_spec(spec, tmp_path / "local", progress=False, announce=lambda s: None)
    t_local = time.perf_counter() - t0

    # a short private root: Ray's socket paths must stay under ~107 characters, and nothing of
    # another Ray user on this machine is touched (`ray stop` would stop every Ray process here)
    root = Path(tempfile.mkdtemp(prefix="etray-", dir="/tmp"))
    env = dict(os.environ, RAY_AUTH_MODE="disabled", RAY_USAGE_STATS_ENABLED="0",
               # notice a dead node in ~1 s, not ~30 s
               RAY_health_check_period_ms="200", RAY_health_check_failure_threshold="5",
               RAY_health_check_initial_delay_ms="0", RAY_health_check_timeout_ms="500")
    for k in ("RAY_AUTH_MODE", "RAY_USAGE_STATS_ENABLED"):
        monkeypatch.setenv(k, env[k])
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    port = _free_port()
    address = f"127.0.0.1:{port}"
    logs = [root / "head.log", root / "node.log"]
    head = node = None
    try:
        t0 = time.perf_counter()
        head = _ray_start(["--head", "--port", str(port), "--temp-dir", str(root / "head"),
                           "--include-dashboard", "false"], logs[0], env)

        def gcs_up():
            try:
                socket.create_connection(("127.0.0.1", port), 0.5).close()
                return True
            except OSError:
                return head.poll() is not None  # (reported below)

        _wait(gcs_up, 120, "the head node", logs)
        assert head.poll() is None, logs[0].read_text()[-2000:]
        node = _ray_start(["--address", address, "--temp-dir", str(root / "node")], logs[1], env)
        ray.init(address=address, include_dashboard=False, log_to_driver=False)
        _wait(lambda: len([n for n in ray.nodes() if n["Alive"]]) == 2, 120, "the second node", logs)
        t_cluster = time.perf_counter() - t0
        assert ray.cluster_resources().get("CPU") == 2.0
        second = next(n["NodeID"] for n in ray.nodes() if "node:__internal_head__" not in n["Resources"])
        # start a worker process on the second node (Python, edgetruth, Mitsuba imported) so that it
        # takes its share from the first images on; the render's tasks reuse it
        from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

        warm = ray.remote(num_cpus=1)(_warm_worker).options(
            scheduling_strategy=NodeAffinitySchedulingStrategy(second, soft=False))
        assert ray.get(warm.remote(), timeout=120) == second

        out = tmp_path / "cluster"
        seen: dict = {}

        t: dict = {}

        def kill_second_node():  # once the second node has rendered KILL_AFTER images
            while t.get("tasks_per_node", {}).get(second, 0) < KILL_AFTER:
                time.sleep(0.005)
            os.killpg(node.pid, signal.SIGKILL)
            seen["killed_at"] = (out / "journal.jsonl").read_bytes().count(b"\n") - 1
            seen["second_at_kill"] = t["tasks_per_node"][second]

        killer = threading.Thread(target=kill_second_node, daemon=True)
        killer.start()
        t0 = time.perf_counter()
        render_spec(spec, out, progress=False, announce=lambda s: None, backend="ray", files="driver", timings=t)
        t_render = time.perf_counter() - t0
        killer.join(timeout=1)
        per_node = dict(t["tasks_per_node"])
        assert "killed_at" in seen, f"the run ended before the second node rendered {KILL_AFTER} images: {per_node}"
        assert seen["killed_at"] < N_IMAGES - 50, "the second node was killed too late to matter"
        assert per_node[second] >= KILL_AFTER and sum(per_node.values()) == N_IMAGES
        assert t["n_rendered"] == N_IMAGES and t["n_written_by_driver"] == N_IMAGES
        _wait(lambda: len([n for n in ray.nodes() if n["Alive"]]) == 1, 60, "the dead node to be noticed")
        a = {p.name: p.read_bytes() for p in sorted((tmp_path / "local").iterdir())}
        b = {p.name: p.read_bytes() for p in sorted(out.iterdir())}
        assert a.keys() == b.keys() and a == b  # every file, manifest included
        print(f"{N_IMAGES} tiny images: local {t_local:.1f} s; two-node cluster up in {t_cluster:.1f} s; "
              f"render {t_render:.1f} s, the second node killed when {seen['killed_at']} images were recorded "
              f"({seen['second_at_kill']} of them its own); images per node: head "
              f"{N_IMAGES - per_node[second]}, second {per_node[second]}")
    finally:
        if ray.is_initialized():
            ray.shutdown()
        groups = {p.pid for p in (head, node) if p is not None}
        for g in groups:
            try:
                os.killpg(g, signal.SIGKILL)
            except ProcessLookupError:
                pass
        for p in (head, node):
            if p is not None:
                p.wait(timeout=30)
        # anything else of this cluster (e.g. a worker that left the group) is found by its temp dir
        for _ in range(50):
            left = _processes_of(groups, str(root))
            if not left:
                break
            for pid in left:
                try:
                    os.kill(pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
            time.sleep(0.2)
        shutil.rmtree(root, ignore_errors=True)
    assert not _processes_of(groups, str(root)), "processes of the test cluster are still running"
