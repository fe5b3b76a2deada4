"""The runner: seeds derived from data, resumable sweeps, worker-independent results."""

from __future__ import annotations

import contextlib
import json
import math
import multiprocessing
import os
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from cmarlcd.experiments import register
from cmarlcd.progress import Throttled
from cmarlcd.runs import Experiment, RunSpec, Settings
from cmarlcd.sweeps.runner import SweepInterrupted, SweepObserver, run_sweep
from cmarlcd.sweeps.store import ResultStore


def sweep_pid() -> int:
    """The process of the sweep this run belongs to (a worker's parent, or this one)."""
    parent = multiprocessing.parent_process()
    return parent.pid if parent is not None else os.getpid()


def fail_flag(pid: int | None = None) -> Path:
    """A file that makes one toy run of the sweep in process ``pid`` fail: it reaches the
    sweep's worker processes, which start fresh, as a global variable would not."""
    return Path(tempfile.gettempdir()) / f"cmarlcd-toy-fail-{pid or sweep_pid()}.json"


@contextlib.contextmanager
def failing_at(index: int, error: str = "interrupt"):
    """Within the block, run ``index`` of the toy (scale * 1000 + run) raises: a
    KeyboardInterrupt (``interrupt``, as Ctrl-C), a ValueError (``value``), or the worker
    process dies (``die``)."""
    flag = fail_flag(os.getpid())
    flag.write_text(json.dumps({"index": index, "error": error}))
    try:
        yield
    finally:
        flag.unlink(missing_ok=True)


@dataclass(frozen=True)
class Toy(Settings):
    scale: int
    x: int | None = None

    def to_config(self) -> dict:
        return {"scale": self.scale} if self.x is None else {"scale": self.scale, "x": self.x}


def draw(toy: Toy, seed: np.random.SeedSequence) -> dict:
    """A toy experiment: a few numbers from the run's own stream."""
    flag = fail_flag()
    if flag.exists():
        fail = json.loads(flag.read_text())
        if fail["index"] == toy.scale * 1000 + int(seed.spawn_key[-1]):
            if fail["error"] == "interrupt":
                raise KeyboardInterrupt
            if fail["error"] == "die":
                os.kill(os.getpid(), signal.SIGKILL)
            raise ValueError(f"run {fail['index']} of the toy fails")
    rng = np.random.default_rng(seed)
    return {"values": (toy.scale * rng.random(3)).tolist()}


register(Experiment("toy", Toy, draw))


def specs(scales=(1, 2), runs=4, root_seed=0) -> list[RunSpec]:
    return [RunSpec.make("toy", "alg", Toy(s), root_seed, r) for s in scales for r in range(runs)]


def sweep(store: ResultStore, todo: list[RunSpec], workers: int = 1):
    return run_sweep(todo, store, workers=workers)


def stored(store: ResultStore, todo: list[RunSpec]) -> list:
    return [r.metrics for r in store.get(s.key for s in todo)]


def test_seed_depends_on_root_config_and_index_only() -> None:
    a = RunSpec.make("toy", "alg", Toy(1, 2), 7, 3)
    same = RunSpec.make("toy", "other-alg", Toy(scale=1, x=2), 7, 3)
    assert (
        a.seed_sequence().generate_state(4).tolist()
        == same.seed_sequence().generate_state(4).tolist()
    )
    for other in (
        RunSpec.make("toy", "alg", Toy(1, 2), 8, 3),
        RunSpec.make("toy", "alg", Toy(1, 2), 7, 4),
        RunSpec.make("toy", "alg", Toy(2, 2), 7, 3),
    ):
        assert (
            other.seed_sequence().generate_state(4) != a.seed_sequence().generate_state(4)
        ).any()


def test_results_do_not_depend_on_workers_or_on_the_rest_of_the_sweep(tmp_path) -> None:
    todo = specs()
    with ResultStore(tmp_path / "one.sqlite") as one, ResultStore(tmp_path / "two.sqlite") as two:
        sweep(one, todo, workers=1)
        sweep(two, todo, workers=2)
        assert stored(one, todo) == stored(two, todo)
    alone = specs(scales=(2,), runs=4)
    with ResultStore(tmp_path / "alone.sqlite") as store:
        sweep(store, alone)
        assert stored(store, alone) == stored(ResultStore(tmp_path / "one.sqlite"), alone)


def test_rerun_recomputes_nothing(tmp_path) -> None:
    todo = specs()
    with ResultStore(tmp_path / "s.sqlite") as store:
        first = sweep(store, todo)
        again = sweep(store, todo)
    assert (first.computed, first.reused) == (8, 0)
    assert (again.computed, again.reused) == (0, 8)


@pytest.mark.parametrize("workers", [1, 2])
def test_interrupted_sweep_resumes_where_it_stopped(tmp_path, workers: int) -> None:
    todo = specs(scales=(1,), runs=6)
    reference = tmp_path / "ref.sqlite"
    with ResultStore(reference) as store:
        sweep(store, todo)
    # scale 1, run 3 raises KeyboardInterrupt (as Ctrl-C)
    with (
        failing_at(1000 + 3),
        ResultStore(tmp_path / "s.sqlite") as store,
        pytest.raises(SweepInterrupted) as info,
    ):
        sweep(store, todo, workers=workers)
    assert "run the same command again" in str(info.value)
    with ResultStore(tmp_path / "s.sqlite") as store:
        kept = store.count()
        assert kept < 6
        resumed = sweep(store, todo, workers=workers)
        assert (resumed.reused, resumed.computed) == (kept, 6 - kept)
        assert stored(store, todo) == stored(ResultStore(reference), todo)


def test_workers_must_be_positive(tmp_path) -> None:
    with ResultStore(tmp_path / "s.sqlite") as store, pytest.raises(ValueError, match="workers"):
        sweep(store, specs(), workers=0)


def test_worker_progress_is_batched_but_never_lost() -> None:
    sent: list[tuple[float, float]] = []
    sink = Throttled(lambda amount, seconds: sent.append((amount, seconds)), interval=3600.0)
    for amount in (200, 200, 150):
        sink(amount, amount * 1e-3)
    assert sent == []  # held back: one message per interval, not per call
    sink.flush()
    assert sent == [(550, pytest.approx(0.55))]
    eager = Throttled(lambda amount, seconds: sent.append((amount, seconds)), interval=0.0)
    eager(7)  # no estimate: the seconds are unknown
    assert sent[-1][0] == 7 and math.isnan(sent[-1][1])


class Recording(SweepObserver):
    def __init__(self) -> None:
        self.total = self.stored = self.done = 0.0
        self.cost = self.stored_cost = self.cost_done = 0.0
        self.runs = 0

    def start(self, sections) -> None:
        (section,) = sections
        self.total, self.stored, self.unit = section.work, section.stored_work, section.unit
        self.cost, self.stored_cost = section.cost, section.stored_cost

    def advance(self, section: str, work: float, cost: float, kind: str = "") -> None:
        self.done += work
        self.cost_done += cost

    def run_finished(self, section: str, *measure) -> None:
        self.runs += 1


@pytest.mark.parametrize("workers", [1, 2])
def test_progress_has_a_total_and_reaches_it(tmp_path, workers: int) -> None:
    """A DSN sweep counts episodes: the total is known at the start, and the workers'
    reports (throttled through a queue) add up to exactly that total."""
    from cmarlcd.experiments.sensor_network import DsnSweep

    specs = DsnSweep(episodes=(40, 80), runs=2, eval_episodes=30, curve_points=4).specs()
    with ResultStore(tmp_path / "s.sqlite") as store:
        first = Recording()
        run_sweep(specs[:1], store, workers=1, observer=first)
        seen = Recording()
        run_sweep(specs, store, workers=workers, observer=seen)
    assert seen.unit == "episodes" and seen.total == seen.stored + seen.done
    assert seen.cost == pytest.approx(seen.stored_cost + seen.cost_done)
    assert seen.stored == first.total and seen.runs == len(specs) - 1


def descendants_of(pid: int) -> dict[int, int]:
    """Every process under ``pid``, with its depth (1: a child; Linux /proc)."""
    parents: dict[int, int] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            parents[int(stat.parent.name)] = int(stat.read_text().rsplit(")", 1)[1].split()[1])
        except OSError:
            continue
    found, todo = {}, [(pid, 0)]
    while todo:
        parent, depth = todo.pop()
        for child in (c for c, p in parents.items() if p == parent):
            found[child] = depth + 1
            todo.append((child, depth + 1))
    return found


def alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"  # a zombie has exited


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_workers_exit_when_the_sweep_s_parent_is_killed(tmp_path) -> None:
    """kill -9 of the parent (an OOM killer, a scheduler) must not leave workers behind,
    nor the fork server they come from (the workers are its children: the sweep's
    grandchildren)."""
    command = [
        sys.executable,
        "-m",
        "cmarlcd",
        "dsn",
        "--algorithms",
        "cmarl-cd",
        "--episodes",
        "20000000",
        "--runs",
        "2",
        "--workers",
        "2",
        "--no-progress",
        "--store",
        str(tmp_path / "s.sqlite"),
        "--figures",
        str(tmp_path / "f"),
    ]
    parent = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    workers: dict[int, int] = {}
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            workers = descendants_of(parent.pid)
            if sum(depth >= 2 for depth in workers.values()) >= 2:
                break
            time.sleep(0.2)
        assert sum(depth >= 2 for depth in workers.values()) >= 2, "no workers started"
        time.sleep(1.0)  # the workers are now deep in compiled training loops
        os.kill(parent.pid, signal.SIGKILL)
        parent.wait()
        deadline = time.monotonic() + 10  # at once as a rule (a compiled chunk takes ~30 s)
        while any(alive(w) for w in workers) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not any(alive(w) for w in workers)
    finally:
        parent.kill()
        for w in workers:
            if alive(w):
                os.kill(w, signal.SIGKILL)


def test_a_task_packs_runs_of_one_kind_only(tmp_path) -> None:
    """Short runs are packed into tasks of one experiment, algorithm and section, so a
    task's progress is counted in one kind's estimated seconds."""
    from cmarlcd import registry
    from cmarlcd.experiments import compare
    from cmarlcd.sweeps.runner import _batches, _Sweep, kind_of

    learners = tuple(registry.REPEATED_LEARNERS[n] for n in ("cmarl-cd", "iql", "lenient"))
    specs = compare.Comparison(learners, ("climbing", "penalty-10"), runs=5).specs()
    with ResultStore(tmp_path / "s.sqlite") as store:
        sweep = _Sweep(specs, store, "", SweepObserver(), lambda spec: "compare")
        sweep.batches = _batches(specs, 1)
        tasks = sweep._tasks(task_seconds=1e9)  # as much packing as one kind allows
    assert len(tasks) == 3
    for task in tasks:
        assert len({kind_of(spec) for batch in task for spec in batch}) == 1
