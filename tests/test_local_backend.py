"""Local worker processes (``sweeps/backends/local.py``, ``worker.py``) and the plug-ins
that reach them (``plugins.py``): workers that never inherit a lock held by one of the
sweep's threads, a run that raises or a worker that dies ending the sweep in one line,
and plug-ins registered in a user's own script computed by the workers."""

from __future__ import annotations

import _imp
import contextlib
import logging
import os
import re
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from cmarlcd.sweeps.runner import RunFailed, SweepInterrupted, run_sweep
from cmarlcd.sweeps.store import ResultStore
from tests.test_runner import failing_at, specs, stored

ROOT = Path(__file__).resolve().parents[1]


def sweep_to_the_end(path: Path, todo: list, workers: int) -> int:
    """Resume the sweep in ``path`` until it finishes; the runs it found stored."""
    with ResultStore(path) as store:
        return run_sweep(todo, store, workers=workers).reused


@pytest.mark.parametrize("workers", [1, 2])
def test_a_run_that_raises_ends_the_sweep_in_one_line_naming_it(tmp_path, workers) -> None:
    todo = specs(scales=(1,), runs=6)
    with failing_at(1000 + 4, "value"), ResultStore(tmp_path / "s.sqlite") as store:
        with pytest.raises(RunFailed) as info:
            run_sweep(todo, store, workers=workers)
        kept = store.count()
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith('run 4 of toy alg (root seed 0, config {"scale":1}) failed:')
    assert "ValueError: run 1004 of the toy fails" in message
    assert f"{kept} of 6 runs are stored, {6 - kept} left" in message
    assert "Traceback" in info.value.failure.details and "draw" in info.value.failure.details
    assert isinstance(info.value.__cause__, ValueError)  # back from its worker, pickled
    assert kept < 6
    assert sweep_to_the_end(tmp_path / "s.sqlite", todo, workers) == kept
    with ResultStore(tmp_path / "ref.sqlite") as reference, ResultStore(tmp_path / "s.sqlite") as s:
        run_sweep(todo, reference, workers=1)
        assert stored(s, todo) == stored(reference, todo)


def test_a_worker_that_dies_ends_the_sweep_naming_its_run(tmp_path) -> None:
    todo = specs(scales=(1,), runs=6)
    start = time.monotonic()
    with (
        failing_at(1000 + 2, "die"),
        ResultStore(tmp_path / "s.sqlite") as store,
        pytest.raises(RunFailed) as info,
    ):
        run_sweep(todo, store, workers=2)
    assert time.monotonic() - start < 30  # ended, not waited on
    assert re.match(
        r"run 2 of toy alg \(root seed 0, .*\) failed: its worker process was killed by "
        r"SIGKILL \(out of memory\?\); \d of 6 runs are stored",
        str(info.value),
    )
    assert sweep_to_the_end(tmp_path / "s.sqlite", todo, 2) < 6


@contextlib.contextmanager
def threads_holding_locks():
    """Threads that take and hold, again and again, the locks a fork would copy held:
    the import lock and logging's lock (as a test runner's, a progress display's or a
    heartbeat's threads may at any moment)."""
    stop = threading.Event()

    def hold(acquire, release) -> None:
        while not stop.is_set():
            acquire()
            try:
                time.sleep(0.002)
            finally:
                release()
            time.sleep(0.0005)

    logging_lock = logging._lock  # type: ignore[attr-defined]
    threads = [
        threading.Thread(target=hold, args=(_imp.acquire_lock, _imp.release_lock), daemon=True),
        threading.Thread(
            target=hold, args=(logging_lock.acquire, logging_lock.release), daemon=True
        ),
    ]
    for thread in threads:
        thread.start()
    try:
        yield
    finally:
        stop.set()
        for thread in threads:
            thread.join()


def failing_sweeps(tmp_path: Path, times: int) -> dict[str, float]:
    """``times`` interrupted sweeps and ``times`` sweeps whose worker raises, two workers
    each, with threads holding the import and logging locks all along: the slowest sweep
    of each kind, in seconds (a sweep that hangs never ends: the test's time limit)."""
    todo = specs(scales=(1,), runs=4)
    slowest = {"interrupt": 0.0, "value": 0.0}
    with threads_holding_locks():
        for attempt in range(times):
            for error, expected in (("interrupt", SweepInterrupted), ("value", RunFailed)):
                path = tmp_path / f"{error}-{attempt}.sqlite"
                start = time.monotonic()
                with failing_at(1000 + 1, error), ResultStore(path) as store:  # noqa: SIM117
                    with pytest.raises(expected):
                        run_sweep(todo, store, workers=2)
                slowest[error] = max(slowest[error], time.monotonic() - start)
                path.unlink()
    return slowest


def test_failing_sweeps_end_while_threads_hold_locks(tmp_path) -> None:
    """The short form of the stress test below."""
    slowest = failing_sweeps(tmp_path, 5)
    assert max(slowest.values()) < 30, slowest


@pytest.mark.slow
def test_two_hundred_failing_sweeps_of_each_kind_end_while_threads_hold_locks(tmp_path) -> None:
    slowest = failing_sweeps(tmp_path, 200)
    assert max(slowest.values()) < 30, slowest


# ------------------------------------------------------------------ plug-ins in a script

PLUGINS = '''
from dataclasses import dataclass, replace
import json, os, sys

import numpy as np

from cmarlcd import registry
from cmarlcd.experiments import register
from cmarlcd.registry import Game, Learner, register_game, register_learner
from cmarlcd.runs import Experiment, RunSpec, Settings
from cmarlcd.sweeps.runner import run_sweep
from cmarlcd.sweeps.store import ResultStore


@dataclass(frozen=True)
class Lookup(Settings):
    learner: str
    game: str


def lookup(settings, seed):
    """A run that needs the learner and the game registered below, by name."""
    config = registry.require_learner(settings.learner)
    spec = registry.stochastic_games()[settings.game]()
    return {"temperature": config.temperature, "agents": len(spec.agents), "pid": os.getpid(),
            "draw": float(np.random.default_rng(seed).random())}


def register_all():
    cmarl = registry.REGISTRY["cmarl-cd"]
    register_learner(Learner("my-cmarl", cmarl.kind, replace(cmarl.stochastic, temperature=0.25)))
    register_game(Game("my-dsn", "the DSN again", "mine", registry.GAMES["dsn"].spec))
    register(Experiment("lookup", Lookup, lookup))


# REGISTRATION


def main():
    todo = [RunSpec.make("lookup", "my-cmarl", Lookup("my-cmarl", "my-dsn"), 0, i)
            for i in range(4)]
    with ResultStore(sys.argv[1]) as store:
        try:
            run_sweep(todo, store, workers=int(sys.argv[2]))
        except Exception as error:
            print(f"error: {error}", file=sys.stderr)
            sys.exit(2)
        runs = [r.metrics for r in store.get(s.key for s in todo)]
        print(json.dumps({"pid": os.getpid(), "runs": runs}))


# MAIN
'''

GUARDED = "if __name__ == '__main__':\n    main()"


def run_script(
    tmp_path: Path, registration: str, main: str, workers: int
) -> subprocess.CompletedProcess:
    script = tmp_path / f"plugins_{workers}_{abs(hash(registration + main))}.py"
    script.write_text(PLUGINS.replace("# REGISTRATION", registration).replace("# MAIN", main))
    return subprocess.run(
        [sys.executable, str(script), str(tmp_path / f"{script.stem}.sqlite"), str(workers)],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "PYTHONPATH": str(ROOT / "src")},
    )


def test_plugins_registered_at_the_top_of_a_script_reach_the_workers(tmp_path) -> None:
    """An experiment, a learner and a game registered at the top level of the script that
    starts the sweep (its sweep under the usual main guard): the workers compute its
    runs, and they are the runs one process computes."""
    import json

    results, sweeps = {}, {}
    for workers in (1, 2):
        done = run_script(tmp_path, "register_all()", GUARDED, workers)
        assert done.returncode == 0, done.stderr[-3000:]
        printed = json.loads(done.stdout)
        results[workers], sweeps[workers] = printed["runs"], printed["pid"]
    from cmarlcd.games import sensor_network

    assert {m["temperature"] for m in results[2]} == {0.25}
    assert {m["agents"] for m in results[2]} == {len(sensor_network.SPEC.agents)}
    assert {m["pid"] for m in results[1]} == {sweeps[1]}  # one worker: the sweep's process
    assert sweeps[2] not in {m["pid"] for m in results[2]}  # computed by worker processes
    assert [m["draw"] for m in results[2]] == [m["draw"] for m in results[1]]


def test_plugins_registered_under_the_main_guard_are_refused_in_one_line(tmp_path) -> None:
    main = "if __name__ == '__main__':\n    register_all()\n    main()"
    done = run_script(tmp_path, "", main, 2)
    assert done.returncode == 2, done.stderr[-3000:]
    (line,) = done.stderr.strip().splitlines()
    assert "does not know the learner 'my-cmarl', game 'my-dsn', experiment 'lookup'" in line
    assert "at the top level of a module" in line


def test_a_script_that_sweeps_at_import_ends_in_one_line(tmp_path) -> None:
    """Without the main guard each worker, importing the script, would start a sweep of
    its own: it cannot, and the sweep says how to fix the script."""
    done = run_script(tmp_path, "register_all()", "main()", 2)
    assert done.returncode == 2
    # the sweep's line; each worker's own (its copy of the script's main() printing the
    # refusal) shares the stream and may land before, after, or inside it
    ended = re.search(
        r"error: a worker process exited with status \d+ while it started \(its error is "
        r"above; a script that starts a sweep does so under `if __name__ == '__main__':`\)",
        done.stderr,
    )
    assert ended, done.stderr
    assert "was asked to start a sweep too" in done.stderr  # the worker's own refusal


def test_a_command_whose_run_fails_ends_in_one_line_with_its_traceback_kept(tmp_path) -> None:
    done = subprocess.run(
        [
            sys.executable, "-m", "cmarlcd", "train", "--env", "tests.tiny_env:make_breaking",
            "--env-kwargs", '{"state": "integer"}', "--algorithms", "cmarl-cd",
            "--episodes", "200", "--runs", "2", "--workers", "2",
            "--no-progress", "--store", str(tmp_path / "s.sqlite"), "--figures", str(tmp_path),
        ],
        capture_output=True, text=True, timeout=300, cwd=ROOT,
    )  # fmt: skip
    assert done.returncode == 2
    (line,) = done.stderr.strip().splitlines()
    assert re.match(
        r"error: run [01] of train (random|cmarl-cd) \(root seed \d+, config \{.*\}\) failed: "
        r"RuntimeError: the tiny game broke at its 30th step; 0 of 4 runs are stored, "
        r"4 left; run the same command again to resume \(traceback: .*\)$",
        line,
    )
    traceback_file = Path(line.rsplit("(traceback: ", 1)[1].rstrip(")"))
    assert "BreakingEnv" in traceback_file.read_text() or "step" in traceback_file.read_text()
    traceback_file.unlink()
