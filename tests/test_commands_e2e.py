"""End to end: every command that computes, run as a user runs it.

Each case is one command line in a subprocess, with nothing started beforehand and a
budget of seconds, on one backend: ``process`` (local worker processes), ``ray-local``
(``--backend ray``: the command starts its own local Ray, and stops it) or
``ray-address`` (``--address`` to a loopback cluster started for the module with ``ray
start``, as a user starts one; the command starts nothing itself). Each checks the exit
status, that stderr holds no traceback, the runs stored (as many as the budget makes,
and on Ray the same runs, metric for metric, as on local processes) and that no process
is left behind.

"Left behind" is precise and does not depend on process names: every command runs with a
marker of its own in its environment (:data:`MARKER`, inherited by every child) and in a
session of its own (kept by every child: Ray's processes rename themselves, which can
blank what /proc shows of their environment, but they do not leave the session). A
process with either, alive :data:`SETTLE_SECONDS` after the command returned, was left
behind.

The path "a cluster that goes away ends the sweep in one line with exit status 2" is
covered by ``tests/test_ray_cluster.py::test_a_cluster_that_goes_away_ends_the_sweep_in_one_line``
(also a command in a subprocess), so it is not repeated here.
"""

from __future__ import annotations

import contextlib
import importlib.util
import os
import secrets
import shutil
import signal
import socket
import sqlite3
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.helpers import stored

pytestmark = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads Linux's /proc")

HAS_RAY = importlib.util.find_spec("ray") is not None
HAS_TORCH = importlib.util.find_spec("torch") is not None
#: The variable every command (and the loopback cluster) carries a unique value of.
MARKER = "CMARLCD_E2E_TAG"
#: Seconds a command may take (each takes seconds; a cold numba cache adds minutes).
COMMAND_SECONDS = 600.0
#: Seconds after a command returned by which every process it started must be gone.
SETTLE_SECONDS = 10.0
LOOPBACK = "127.0.0.1"
STORE_BYTES = 80 * 1024**2  # the smallest object store Ray accepts

# ------------------------------------------------------------------------ processes


def session_of(pid: int) -> int | None:
    """The session ``pid`` is in (None if it is gone or a zombie)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    state, _ppid, _pgrp, session = stat.rpartition(")")[2].split()[:4]
    return None if state in ("Z", "X") else int(session)


def processes(tag: str, session: int) -> dict[int, str]:
    """Every live process with ``MARKER=tag`` in its environment or in ``session``:
    pid -> command line. Processes that cannot be read are not ours (read errors are
    ignored)."""
    needle = f"{MARKER}={tag}".encode()
    found = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        pid = int(entry.name)
        try:
            environ = (entry / "environ").read_bytes().split(b"\0")
            cmdline = (entry / "cmdline").read_bytes()
        except OSError:
            continue
        in_session = session_of(pid)
        if in_session is not None and (needle in environ or in_session == session):
            found[pid] = cmdline.replace(b"\0", b" ").decode(errors="replace").strip()[:200]
    return found


def settle(find: Callable[[], dict[int, str]], seconds: float = SETTLE_SECONDS) -> dict[int, str]:
    """What ``find`` still finds after up to ``seconds`` (empty as soon as it is)."""
    deadline = time.monotonic() + seconds
    while (found := find()) and time.monotonic() < deadline:
        time.sleep(0.2)
    return found


def kill(pids: dict[int, str], sig: int = signal.SIGKILL) -> None:
    """Signal each of ``pids`` (processes of this module: its marker or its session)."""
    for pid in pids:
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.kill(pid, sig)


@dataclass
class Outcome:
    """A finished command: its exit status and output, the processes of its run seen
    while it ran and those still alive :data:`SETTLE_SECONDS` after it returned."""

    returncode: int
    stdout: str
    stderr: str
    pid: int
    seen: dict[int, str]
    left: dict[int, str]


def run_command(args: list[str], env: dict[str, str]) -> Outcome:
    """``python -m cmarlcd ARGS`` in a subprocess of its own session, with a marker of
    its own and ``env`` added to this environment; whatever it leaves behind is
    reported, then killed."""
    tag = uuid.uuid4().hex
    full_env = {**os.environ, "RAY_USAGE_STATS_ENABLED": "0", MARKER: tag, **env}
    command = subprocess.Popen(
        [sys.executable, "-m", "cmarlcd", *args],
        env=full_env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    seen: dict[int, str] = {}
    ended = threading.Event()

    def watch() -> None:
        while not ended.wait(0.25):
            seen.update(processes(tag, command.pid))

    watcher = threading.Thread(target=watch, daemon=True)
    watcher.start()
    try:
        out, err = command.communicate(timeout=COMMAND_SECONDS)
    except subprocess.TimeoutExpired:
        kill(processes(tag, command.pid))
        out, err = command.communicate()
        pytest.fail(f"{args[0]} took over {COMMAND_SECONDS:.0f} s: {err[-2000:]}")
    finally:
        ended.set()
        watcher.join()
    left = settle(lambda: processes(tag, command.pid))
    kill(left)  # the machine stays clean whatever the verdict
    return Outcome(command.returncode, out, err, command.pid, seen, left)


def free_ports(count: int) -> list[int]:
    """``count`` loopback ports nothing listens on (now)."""
    with contextlib.ExitStack() as stack:
        sockets = [stack.enter_context(socket.socket()) for _ in range(count)]
        for sock in sockets:
            sock.bind((LOOPBACK, 0))
        return [sock.getsockname()[1] for sock in sockets]


# --------------------------------------------------------------------------- stores


def count_runs(store: Path) -> int:
    """Rows of the store's ``runs`` table (read-only)."""
    with contextlib.closing(sqlite3.connect(f"file:{store}?mode=ro", uri=True)) as conn:
        return conn.execute("SELECT COUNT(*) FROM runs").fetchone()[0]


# ---------------------------------------------------------------------------- cases


@dataclass(frozen=True)
class Case:
    """A command with a budget of seconds, and the runs that budget stores (counted
    here from the budget, not asked of the code; None: the command stores nothing)."""

    name: str
    args: str
    """Its options, separated by spaces."""
    runs: int | None
    on_ray: bool = True
    """False for ``theory`` (no --backend)."""

    def command_line(self, where: Path) -> list[str]:
        """The command line, its outputs under ``where``."""
        if self.runs is None:  # theory: no store, no progress bar
            return [self.name, *self.args.split(), "--figures", str(where / "figures")]
        outputs = ["--store", str(where / "runs.sqlite"), "--figures", str(where / "figures")]
        return [self.name, *self.args.split(), *WORKERS, *outputs, "--no-progress"]


#: Two workers: the runs are few, and on a machine of many cores the default (all of them)
#: would have a local Ray start as many worker processes.
WORKERS = ("--workers", "2")
#: Deep learners train on a path of their own (torch, stacked seeds): one command has one.
SCALING_ALGORITHMS = ["cmarl-cd", *(["vdn"] if HAS_TORCH else [])]
#: reproduce --preset smoke --no-compare: Tables 1-2 (1 run per cell of the paper's
#: grids: agents 2-7 x actions 2-5, agents 4-7 x actions 3-5), 1 DSN run of CMARL-CD and
#: of LA-OCA, 1 round of every pairing of the tournament (VDN and QMIX play with torch:
#: 4 algorithms, 10 pairings; else 2, 3) and the Theorem 1 check (2 runs).
REPRODUCE_RUNS = 1 * (6 * 4 + 4 * 3) + 1 * 2 + 1 * (10 if HAS_TORCH else 3) + 2

CASES = [
    # agents 2-3 x actions 2 x 2 runs
    Case("repeated", "--case 1 --agents 2-3 --actions 2 --runs 2", 2 * 1 * 2),
    # 1 algorithm x 2 runs (one run covers every budget L)
    Case("dsn", "--algorithms cmarl-cd --episodes 300 --runs 2 --eval-episodes 20", 1 * 2),
    # 2 algorithms: 3 pairings (each against itself too) x 1 round
    Case(
        "tournament",
        "--algorithms cmarl-cd,la-oca --rounds 1 --learn-episodes 200 --eval-episodes 50",
        3 * 1,
    ),
    # 5 tournaments (the defaults, 2 switches, 1 hit rate, γ 0) x 1 pairing x 1 round; one
    # learner has no opponent, so no claim is checked: no hit rate is favoured (no second
    # γ dial) and the study points nowhere (no combination)
    Case(
        "readings",
        "--algorithms cmarl-cd --rounds 1 --hit-rates 1 --gammas 0 --learn-episodes 200 "
        "--eval-episodes 50",
        5 * 1 * 1,
    ),
    # computed in the command's own process: no --backend, no store
    Case("theory", "--starts 5", None, on_ray=False),
    # 2 learners x 2 games x 2 runs
    Case("compare", "--learners cmarl-cd,iql --games climbing,penalty-0 --runs 2", 2 * 2 * 2),
    # 1 size x the algorithms x 2 runs
    Case(
        "scaling",
        f"--preset quick --sizes 2x3/2 --algorithms {','.join(SCALING_ALGORITHMS)} "
        "--episodes 200 --runs 2 --eval-episodes 20",
        1 * len(SCALING_ALGORITHMS) * 2,
    ),
    # (the uniform random baseline + 1 learner) x 2 runs
    Case(
        "train",
        "--env cmarlcd.games.sensor_network:SensorNetworkEnv --algorithms cmarl-cd "
        "--episodes 200 --runs 2 --eval-episodes 10 --curve-points 2",
        (1 + 1) * 2,
    ),
    # the smallest preset: every part once, in seconds
    Case("reproduce", "--preset smoke --no-compare", REPRODUCE_RUNS),
]

BACKENDS = ("process", "ray-local", "ray-address")
NEEDS_RAY = pytest.mark.skipif(not HAS_RAY, reason="needs Ray: pip install 'cmarl-cd[ray]'")
#: The cases of the default run (the CI's): every command on local processes (a few
#: seconds each) and one on a Ray the command starts itself, the path that once died in
#: silence; the other Ray cases (about 8 s each, for Ray's start and stop) are slow.
QUICK = {("repeated", "ray-local")}


def _marks(case: Case, backend: str) -> tuple:
    if backend == "process":
        return ()
    return (NEEDS_RAY,) if (case.name, backend) in QUICK else (NEEDS_RAY, pytest.mark.slow)


PARAMS = [
    pytest.param(case, backend, id=f"{case.name}-{backend}", marks=_marks(case, backend))
    for backend in BACKENDS  # every command on one backend, then the next
    for case in CASES
    if backend == "process" or case.on_ray
]

# ------------------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def ray_tmpdir() -> Iterator[Path]:
    """Where the commands' Ray keeps its sessions (RAY_TMPDIR): a folder of this module,
    removed with it, so that their logs and sockets do not pile up in /tmp/ray and no
    cluster another program recorded there is taken for the loopback one. Short: Ray's
    socket paths must fit in 107 bytes."""
    root = Path(tempfile.mkdtemp(prefix="e2e-", dir="/tmp"))
    yield root
    shutil.rmtree(root, ignore_errors=True)


@pytest.fixture(scope="module")
def references() -> dict[str, Path]:
    """Each command's store from local processes, by command (filled by its process case,
    or on demand: :func:`reference`)."""
    return {}


def reference(case: Case, references: dict[str, Path], where: Path, env: dict[str, str]) -> Path:
    """The store ``case`` makes on local processes (its process case's, or made now)."""
    if case.name not in references:
        done = run_command(case.command_line(where), env)
        assert done.returncode == 0, done.stderr[-3000:]
        references[case.name] = where / "runs.sqlite"
    return references[case.name]


@dataclass(frozen=True)
class LoopbackCluster:
    """A cluster started with ``ray start``: its address, what a client needs to join it
    (its token), and how to find its processes (its marker and session)."""

    address: str
    client_env: dict[str, str]
    tag: str
    session: int

    def processes(self) -> dict[int, str]:
        return processes(self.tag, self.session)


@pytest.fixture(scope="module")
def loopback_cluster() -> Iterator[LoopbackCluster]:
    """One head of 2 CPUs, started as a user starts one (``ray start --head
    --node-ip-address=127.0.0.1``), in a session of its own, with token authentication
    and a token of this module (Ray 2.60 turns 127.0.0.1 into the machine's outside
    address and listens on every interface); stopped at the end by signalling its
    processes (``ray stop`` would stop every Ray on the machine)."""
    ray_cli = Path(sys.executable).with_name("ray")
    if not ray_cli.exists():
        pytest.skip("no `ray` command beside this Python")
    root = Path(tempfile.mkdtemp(prefix="e2e-head-", dir="/tmp"))  # short: socket paths
    port, agent_port = free_ports(2)
    client_env = {"RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": secrets.token_hex(32)}
    tag = uuid.uuid4().hex
    env = {**os.environ, "RAY_USAGE_STATS_ENABLED": "0", MARKER: tag, **client_env}
    start = [
        *(str(ray_cli), "start", "--head", f"--node-ip-address={LOOPBACK}", f"--port={port}"),
        *(f"--dashboard-agent-listen-port={agent_port}", "--num-cpus=2"),
        *("--include-dashboard=false", "--disable-usage-stats", f"--temp-dir={root}"),
        f"--object-store-memory={STORE_BYTES}",
    ]
    head = subprocess.Popen(
        start,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,
    )
    cluster = LoopbackCluster(f"{LOOPBACK}:{port}", client_env, tag, head.pid)
    try:
        out, _ = head.communicate(timeout=120)
        assert head.returncode == 0, out[-3000:]
        yield cluster
    finally:
        kill(cluster.processes(), signal.SIGTERM)
        kill(settle(cluster.processes, 3.0))  # its GCS and raylet take their time
        shutil.rmtree(root, ignore_errors=True)


# ---------------------------------------------------------------------------- tests


@pytest.mark.parametrize(("case", "backend"), PARAMS)
def test_a_command_run_as_a_user_runs_it(
    case: Case,
    backend: str,
    tmp_path: Path,
    ray_tmpdir: Path,
    references: dict[str, Path],
    request: pytest.FixtureRequest,
) -> None:
    """Exit status 0, no traceback, the runs the budget makes (on Ray: the same as on
    local processes), nothing left behind; on Ray, a local Ray the command started
    itself, or the cluster's own processes alone, as they were."""
    env = {"RAY_TMPDIR": str(ray_tmpdir)}
    args = case.command_line(tmp_path)
    cluster: LoopbackCluster | None = None
    before: dict[int, str] = {}
    if backend == "ray-local":
        args += ["--backend", "ray"]
    elif backend == "ray-address":
        cluster = request.getfixturevalue("loopback_cluster")
        args += ["--backend", "ray", "--address", cluster.address]
        env |= cluster.client_env
        before = cluster.processes()

    done = run_command(args, env)

    assert done.returncode == 0, done.stderr[-3000:]
    assert "Traceback" not in done.stderr, done.stderr[-3000:]
    assert not done.left, f"left behind: {done.left}"
    if backend == "ray-local":
        programs = {line.split(" ", 1)[0].rsplit("/", 1)[-1] for line in done.seen.values()}
        assert {"gcs_server", "raylet"} <= programs, f"no local Ray started: {done.seen}"
    if cluster is not None:
        assert set(done.seen) <= {done.pid}, f"started on this side: {done.seen}"
        made = settle(lambda: {p: c for p, c in cluster.processes().items() if p not in before})
        assert not made, f"left behind on the cluster: {made}"
    store = tmp_path / "runs.sqlite"
    if case.runs is None:  # theory: its figure is its result
        assert list((tmp_path / "figures").glob("*.png")) and not store.exists()
        return
    assert count_runs(store) == case.runs
    if backend == "process":
        references[case.name] = store
    else:
        local = reference(case, references, tmp_path / "process", env)
        assert stored(store) == stored(local)


def test_progress_into_a_log_is_plain_lines(tmp_path: Path) -> None:
    """stderr a pipe, as under nohup or a batch job: the progress is plain lines (rich
    alone would draw nothing until the end), the first at the start, the last ``done``."""
    case = CASES[2]  # the tournament: 3 pairings x 1 round
    args = [a for a in case.command_line(tmp_path) if a != "--no-progress"]
    done = run_command(args, {})
    assert done.returncode == 0, done.stderr[-3000:]
    lines = [line for line in done.stderr.splitlines() if line.startswith("[")]
    assert lines[0].startswith("[0:00:00] battlefield 0% 0/750 episodes eta "), lines
    assert lines[-1].endswith("] done") and len(lines) >= 2, lines
    assert count_runs(tmp_path / "runs.sqlite") == case.runs
