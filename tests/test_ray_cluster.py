"""A real Ray cluster of two nodes on this machine, every node on loopback only: a sweep
through ``--address`` stores what local processes store; a worker node removed in the
middle of a sweep has its tasks rerun on the other node; a cluster that goes away ends
the sweep in one line, keeping what was stored."""

from __future__ import annotations

import ipaddress
import os
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

from cmarlcd.sweeps.backends.ray_cluster import GRACE_SECONDS, HEAD_CHECK_SECONDS, LOST_SECONDS
from tests.helpers import stored

ray = pytest.importorskip("ray")
pytestmark = pytest.mark.slow  # a cluster takes seconds to start, the sweeps tens

LOOPBACK = "127.0.0.1"
STORE_BYTES = 80 * 1024**2
#: A sweep long enough to be cut in the middle (about a second a run on one core).
LONG_DSN = ["dsn", "--algorithms", "cmarl-cd", "--episodes", "200000", "--runs", "16"]
LONG_DSN += ["--eval-episodes", "500"]


def listening() -> set[tuple[str, int]]:
    """Every (address, port) this machine listens on (Linux's /proc/net/tcp{,6})."""
    found = set()
    for table, width in (("/proc/net/tcp", 8), ("/proc/net/tcp6", 32)):
        for line in Path(table).read_text().splitlines()[1:]:
            fields = line.split()
            host, _, port = fields[1].partition(":")
            if fields[3] == "0A" and len(host) == width:
                raw = b"".join(bytes.fromhex(host[i : i + 8])[::-1] for i in range(0, width, 8))
                found.add((str(ipaddress.ip_address(raw)), int(port, 16)))
    return found


def is_loopback(address: str) -> bool:
    ip = ipaddress.ip_address(address)
    mapped = getattr(ip, "ipv4_mapped", None)
    return ip.is_loopback or (mapped is not None and mapped.is_loopback)


@pytest.fixture
def cluster():
    """A head of one CPU and a worker node of one CPU, both on 127.0.0.1."""
    from ray.cluster_utils import Cluster

    os.environ["RAY_USAGE_STATS_ENABLED"] = "0"  # no report to the outside world
    before = listening()
    nodes = Cluster(
        initialize_head=True,
        head_node_args={
            "num_cpus": 1,
            "node_ip_address": LOOPBACK,
            "include_dashboard": False,
            "object_store_memory": STORE_BYTES,
        },
    )
    worker = nodes.add_node(num_cpus=1, node_ip_address=LOOPBACK, object_store_memory=STORE_BYTES)
    nodes.wait_for_nodes()
    opened = listening() - before
    yield nodes, worker, opened
    nodes.shutdown()


def cli(*args: str, store: Path, wait: bool = True):
    command = [sys.executable, "-m", "cmarlcd", *args, "--no-progress"]
    command += ["--store", str(store), "--figures", str(store.parent / "figures")]
    env = dict(os.environ, RAY_USAGE_STATS_ENABLED="0")
    if not wait:
        return subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    return subprocess.run(command, capture_output=True, text=True, env=env, timeout=600)


def count(store: Path) -> int:
    try:
        with sqlite3.connect(f"file:{store}?mode=ro", uri=True, timeout=5) as conn:
            return conn.execute("SELECT COUNT(*) FROM runs").fetchone()[0]
    except sqlite3.Error:
        return 0


def wait_for_runs(store: Path, runs: int, sweep: subprocess.Popen) -> None:
    deadline = time.monotonic() + 300
    while count(store) < runs and sweep.poll() is None and time.monotonic() < deadline:
        time.sleep(0.2)
    assert count(store) >= runs and sweep.poll() is None, "the sweep ended too soon"


def test_a_two_node_loopback_cluster_stores_what_local_processes_store(cluster, tmp_path):
    nodes, _, opened = cluster
    assert opened and all(is_loopback(address) for address, _ in opened), opened
    sweep = ["repeated", "--agents", "2-3", "--actions", "2-3", "--runs", "3"]
    on_ray = cli(*sweep, "--backend", "ray", "--address", nodes.address, store=tmp_path / "r.db")
    assert on_ray.returncode == 0, on_ray.stderr
    local = cli(*sweep, "--workers", "2", store=tmp_path / "p.db")
    assert local.returncode == 0, local.stderr
    assert len(stored(tmp_path / "r.db")) == 12
    assert stored(tmp_path / "r.db") == stored(tmp_path / "p.db")


def test_a_worker_node_removed_mid_sweep_has_its_tasks_rerun(cluster, tmp_path):
    """Every run stored exactly once, and the tables equal an uninterrupted sweep's."""
    nodes, worker, _ = cluster
    store = tmp_path / "r.db"
    sweep = cli(*LONG_DSN, "--backend", "ray", "--address", nodes.address, store=store, wait=False)
    wait_for_runs(store, 3, sweep)
    nodes.remove_node(worker)  # its running task dies with it; Ray reruns it on the head
    out, err = sweep.communicate(timeout=600)
    assert sweep.returncode == 0, err.decode()
    assert "retries" not in out.decode() + err.decode()  # Ray's notices stay off the terminal
    local = cli(*LONG_DSN, "--workers", "2", store=tmp_path / "p.db")
    assert local.returncode == 0, local.stderr
    assert count(store) == 16 and stored(store) == stored(tmp_path / "p.db")


def test_a_cluster_that_goes_away_ends_the_sweep_in_one_line(cluster, tmp_path):
    """Within the documented bound, keeping the runs stored before; then the same
    command on local processes resumes from them."""
    nodes, _, _ = cluster
    store = tmp_path / "r.db"
    sweep = cli(*LONG_DSN, "--backend", "ray", "--address", nodes.address, store=store, wait=False)
    wait_for_runs(store, 2, sweep)
    gone = time.monotonic()
    nodes.shutdown()
    out, err = sweep.communicate(timeout=LOST_SECONDS + GRACE_SECONDS + 60)
    took = time.monotonic() - gone
    assert sweep.returncode == 2, err.decode()[-3000:]
    assert took < LOST_SECONDS + HEAD_CHECK_SECONDS + GRACE_SECONDS + 10
    lines = err.decode().strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: --backend: the Ray cluster at"), lines
    assert "run the same command again" in lines[0] and out.decode().strip() == ""
    kept = count(store)
    assert kept >= 2
    resumed = cli(*LONG_DSN, "--workers", "2", "--json", store=store)
    assert resumed.returncode == 0, resumed.stderr
    assert f'"runs_reused": {kept}' in resumed.stdout and count(store) == 16


def test_a_cluster_that_cannot_be_reached_is_one_line_and_leaves_no_store(tmp_path):
    import socket

    with socket.socket() as free:  # a loopback port nothing listens on
        free.bind((LOOPBACK, 0))
        port = free.getsockname()[1]
    store = tmp_path / "r.db"
    start = time.monotonic()
    done = cli("repeated", "--backend", "ray", "--address", f"{LOOPBACK}:{port}", store=store)
    assert done.returncode == 2 and time.monotonic() - start < 30
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "cannot reach the Ray cluster" in lines[0], lines
    assert not store.exists()
