"""Fan runs out over worker processes and commit each result to the store.

A *run* is a :class:`RunSpec`: (experiment, algorithm, config, root seed, run index).
Its random streams come from :meth:`RunSpec.seed_sequence`, a
:class:`numpy.random.SeedSequence` built from the root seed, a digest of the experiment
and config, and the run index, so a run's result never depends on which worker ran it,
how many workers there were, or which other runs were in the same sweep. The algorithm
name is deliberately left out of the seed: algorithms compared under the same config
see the same random games (common random numbers).

Backends: ``workers == 1`` runs in-process; otherwise a pool of forked local processes
(spawned where fork is unavailable). Results come back to the parent, which alone
writes to the store, one transaction per run, as each finishes.
"""

from __future__ import annotations

import hashlib
import multiprocessing
import os
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass, field
from queue import Empty
from typing import Any

import numpy as np
from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    ProgressColumn,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)
from rich.text import Text

from cmarlcd.errors import require
from cmarlcd.store import ResultStore, RunKey, canonical_json

RunFunction = Callable[[dict[str, Any], np.random.SeedSequence], dict[str, Any]]
BatchFunction = Callable[[dict[str, Any], list[np.random.SeedSequence]], list[dict[str, Any]]]


@dataclass(frozen=True)
class Experiment:
    """What the runner needs to know about an experiment.

    Attributes:
        name: the store's experiment name.
        run: computes one run's metrics from its config and seed sequence.
        warm_up: compiles the kernels once in the parent before workers fork.
        cost: a rough relative cost of a config, used to start expensive runs first.
        run_batch: optional; computes several runs of one config together (e.g. seeds
            stacked in one model). It must give each run the metrics ``run`` would.
        batch_limit: how many runs of a config may share one ``run_batch`` call (1: none).
    """

    name: str
    run: RunFunction
    warm_up: Callable[[], None] = lambda: None
    cost: Callable[[Mapping[str, Any]], float] = lambda config: 1.0
    run_batch: BatchFunction | None = None
    batch_limit: Callable[[Mapping[str, Any]], int] = lambda config: 1


_REGISTRY: dict[str, Experiment] = {}


def register(experiment: Experiment) -> Experiment:
    """Make ``experiment`` runnable by name (also inside worker processes)."""
    _REGISTRY[experiment.name] = experiment
    return experiment


def get_experiment(name: str) -> Experiment:
    """The registered experiment ``name`` (the built-in ones register on import)."""
    if name not in _REGISTRY:
        import cmarlcd.experiments  # noqa: F401  (a spawned worker starts with an empty registry)
    return _REGISTRY[name]


@dataclass(frozen=True)
class RunSpec:
    """One run: everything needed to compute it, and its identity in the store."""

    experiment: str
    algorithm: str
    config_json: str
    root_seed: int
    run_index: int
    stream_json: str = ""
    """The part of the config that defines the random streams (default: all of it)."""

    @classmethod
    def make(
        cls,
        experiment: str,
        algorithm: str,
        config: Mapping[str, Any],
        root_seed: int,
        index: int,
        stream: Mapping[str, Any] | None = None,
    ) -> RunSpec:
        """A run of ``config``; ``stream`` (a sub-config) seeds it when given, so settings
        outside it (e.g. evaluation budgets) leave the run's random streams unchanged."""
        config_json = canonical_json(config)
        stream_json = config_json if stream is None else canonical_json(stream)
        return cls(experiment, algorithm, config_json, int(root_seed), int(index), stream_json)

    @property
    def key(self) -> RunKey:
        return RunKey(
            self.experiment, self.algorithm, self.config_json, self.root_seed, self.run_index
        )

    @property
    def config(self) -> dict[str, Any]:
        import json

        return json.loads(self.config_json)

    def seed_sequence(self) -> np.random.SeedSequence:
        """The run's root of randomness: (root seed; digest of experiment+stream, index)."""
        stream = self.stream_json or self.config_json
        digest = hashlib.sha256(f"{self.experiment}\n{stream}".encode()).digest()
        words = [int.from_bytes(digest[i : i + 4], "little") for i in range(0, 16, 4)]
        return np.random.SeedSequence(self.root_seed, spawn_key=(*words, self.run_index))


def execute(spec: RunSpec) -> tuple[RunSpec, dict[str, Any], float]:
    """Compute one run (in whatever process calls it)."""
    start = time.perf_counter()
    metrics = get_experiment(spec.experiment).run(spec.config, spec.seed_sequence())
    return spec, metrics, time.perf_counter() - start


def _execute_in_worker(specs: list[RunSpec]) -> list[tuple[RunSpec, dict[str, Any], float]]:
    """:func:`execute_batch` in a pool worker, sending on the progress it still holds."""
    try:
        return execute_batch(specs)
    finally:
        if isinstance(_progress_sink, _Throttled):
            _progress_sink.flush()


def execute_batch(specs: list[RunSpec]) -> list[tuple[RunSpec, dict[str, Any], float]]:
    """Compute runs that share one config, together when the experiment can batch them."""
    experiment = get_experiment(specs[0].experiment)
    if len(specs) == 1 or experiment.run_batch is None:
        return [execute(spec) for spec in specs]
    start = time.perf_counter()
    results = experiment.run_batch(specs[0].config, [s.seed_sequence() for s in specs])
    seconds = (time.perf_counter() - start) / len(specs)
    return [(spec, metrics, seconds) for spec, metrics in zip(specs, results, strict=True)]


# Progress from inside runs (e.g. environment steps): a run calls report_progress(n); the
# runner shows the rate. In worker processes the amounts travel over a queue.
_progress_sink: Callable[[float], None] | None = None


def report_progress(amount: float) -> None:
    """Tell the running sweep that ``amount`` units of work (env steps) were done."""
    if _progress_sink is not None:
        _progress_sink(amount)


class _Throttled:
    """Sums progress amounts and forwards them at most every ``interval`` seconds, so a
    worker's fast inner loop does not cost a queue message (and a pipe write) each time."""

    def __init__(self, put: Callable[[float], None], interval: float = 0.1) -> None:
        self.put, self.interval = put, interval
        self.pending, self.last = 0.0, time.monotonic()

    def __call__(self, amount: float) -> None:
        self.pending += amount
        if time.monotonic() - self.last >= self.interval:
            self.flush()

    def flush(self) -> None:
        if self.pending:
            self.put(self.pending)
        self.pending, self.last = 0.0, time.monotonic()


def _worker_init(queue: Any, threads: int) -> None:
    global _progress_sink
    _progress_sink = _Throttled(queue.put)
    os.environ["OMP_NUM_THREADS"] = str(threads)
    if "torch" in sys.modules:  # forked from a parent that imported it
        sys.modules["torch"].set_num_threads(threads)


def default_workers() -> int:
    """All cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


@dataclass
class SweepResult:
    """How a sweep went: how many runs were computed now and how many came from the store."""

    total: int
    computed: int = 0
    reused: int = 0
    wall_seconds: float = 0.0
    interrupted: bool = False
    run_seconds: list[float] = field(default_factory=list)


class SweepInterrupted(RuntimeError):
    """The sweep was stopped (Ctrl-C); finished runs are in the store."""

    def __init__(self, result: SweepResult) -> None:
        self.result = result
        left = result.total - result.reused - result.computed
        super().__init__(
            f"interrupted: {result.reused + result.computed} of {result.total} runs are stored,"
            f" {left} left; run the same command again to resume"
        )


def run_sweep(
    specs: Sequence[RunSpec],
    store: ResultStore,
    *,
    workers: int | None = None,
    version: str = "",
    console: Console | None = None,
    description: str = "runs",
    show_progress: bool = True,
) -> SweepResult:
    """Compute every spec not yet in ``store`` and commit each as it finishes."""
    workers = default_workers() if workers is None else workers
    require(workers >= 1, "workers", f"must be >= 1 (got {workers})")
    todo = _order_by_cost(store_missing(store, specs))
    result = SweepResult(total=len(specs), reused=len(specs) - len(todo))
    start = time.perf_counter()
    progress = _progress(console, show_progress)
    with progress:
        task = progress.add_task(description, total=len(specs), completed=result.reused)
        steps_task: list[Any] = []

        def commit(spec: RunSpec, metrics: dict[str, Any], seconds: float) -> None:
            store.put(spec.key, metrics, seconds, version)
            result.computed += 1
            result.run_seconds.append(seconds)
            progress.advance(task)

        def advance_steps(amount: float) -> None:
            if not steps_task:
                steps_task.append(progress.add_task("  env steps", total=None))
            progress.advance(steps_task[0], amount)

        try:
            if todo:
                _dispatch(_batches(todo), workers, commit, advance_steps)
        except KeyboardInterrupt:
            result.interrupted = True
            result.wall_seconds = time.perf_counter() - start
            raise SweepInterrupted(result) from None
    result.wall_seconds = time.perf_counter() - start
    return result


def store_missing(store: ResultStore, specs: Sequence[RunSpec]) -> list[RunSpec]:
    missing = set(store.missing(s.key for s in specs))
    return [s for s in specs if s.key in missing]


def _order_by_cost(specs: list[RunSpec]) -> list[RunSpec]:
    """Longest first, so the slowest runs do not start last (results are unaffected)."""
    return sorted(specs, key=lambda s: -get_experiment(s.experiment).cost(s.config))


def _batches(todo: list[RunSpec]) -> list[list[RunSpec]]:
    """Group runs of one config into batches of up to the experiment's batch limit."""
    groups: dict[tuple[str, str], list[RunSpec]] = {}
    for spec in todo:
        groups.setdefault((spec.experiment, spec.config_json), []).append(spec)
    batches = []
    for specs in groups.values():
        limit = max(1, get_experiment(specs[0].experiment).batch_limit(specs[0].config))
        batches += [specs[i : i + limit] for i in range(0, len(specs), limit)]
    return batches


def _dispatch(
    batches: list[list[RunSpec]],
    workers: int,
    commit: Callable[[RunSpec, dict[str, Any], float], None],
    advance_steps: Callable[[float], None],
) -> None:
    global _progress_sink
    for name in {b[0].experiment for b in batches}:
        get_experiment(name).warm_up()
    workers = min(workers, len(batches))
    if workers == 1:
        _progress_sink = advance_steps
        try:
            for batch in batches:
                for outcome in execute_batch(batch):
                    commit(*outcome)
        finally:
            _progress_sink = None
        return
    method = "fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn"
    context = multiprocessing.get_context(method)
    queue = context.Queue()
    threads = max(1, default_workers() // workers)
    pool = ProcessPoolExecutor(
        workers, mp_context=context, initializer=_worker_init, initargs=(queue, threads)
    )
    try:
        pending: set[Future] = {pool.submit(_execute_in_worker, batch) for batch in batches}
        while pending:
            done, pending = wait(pending, timeout=0.2, return_when=FIRST_COMPLETED)
            _drain(queue, advance_steps)
            for future in done:
                for outcome in future.result():
                    commit(*outcome)
    except BaseException:
        # Ctrl-C reaches the workers too and ends them; do not wait for queued runs.
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown(wait=True)


def _drain(queue: Any, advance: Callable[[float], None]) -> None:
    total = 0.0
    while True:
        try:
            total += queue.get_nowait()
        except Empty:
            break
    if total:
        advance(total)


class RateColumn(ProgressColumn):
    """Units per second of a task (env steps/s for in-run progress)."""

    def render(self, task: Any) -> Text:
        speed = task.finished_speed or task.speed
        if task.total is not None or speed is None:  # only for open-ended in-run counters
            return Text("")
        return Text(f"{speed:,.0f}/s")


def _progress(console: Console | None, show: bool) -> Progress:
    return Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("elapsed"),
        TimeElapsedColumn(),
        TextColumn("eta"),
        TimeRemainingColumn(),
        RateColumn(),
        console=console or Console(stderr=True),
        disable=not show,
        transient=False,
    )
