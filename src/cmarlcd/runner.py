"""Fan runs out over worker processes and commit each result to the store.

Backends: ``workers == 1`` runs in-process; otherwise a pool of forked local processes
(spawned where fork is unavailable). Results come back to the parent, which alone writes
to the store, one transaction per run, as each finishes. Runs of one config that the
experiment can batch (seeds stacked in one model) travel together, ``seed_batch`` at a
time. A worker whose parent dies (``kill -9``, an out-of-memory kill) exits at once
rather than holding the store open; Ctrl-C stops the workers and keeps every finished run.

How a sweep is shown is up to the caller: the runner reports to a :class:`SweepObserver`
(the command line draws it with rich; the default shows nothing).
"""

from __future__ import annotations

import contextlib
import ctypes
import multiprocessing
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass, field
from queue import Empty
from typing import Any

from cmarlcd.errors import require
from cmarlcd.experiments import get_experiment
from cmarlcd.progress import Throttled, install_sink, progress_sink
from cmarlcd.runs import RunSpec
from cmarlcd.store import ResultStore

Outcome = tuple[RunSpec, dict[str, Any], float]

#: How often a worker checks that its parent is still alive, in seconds (where the
#: operating system cannot tell it, as Linux's parent-death signal does).
PARENT_CHECK_SECONDS = 0.5


class SweepObserver:
    """Receives a sweep's progress; the default ignores it."""

    def start(
        self,
        description: str,
        runs: int,
        stored_runs: int,
        work: float,
        stored_work: float,
        unit: str = "runs",
    ) -> None:
        """The sweep has ``runs`` runs (``stored_runs`` already stored) and ``work``
        progress units (``unit``) in all, ``stored_work`` of them done by the stored runs."""

    def advance(self, work: float) -> None:
        """``work`` more units are done."""

    def run_finished(self) -> None:
        """One more run is computed and stored."""

    def finish(self) -> None:
        """The sweep has ended (finished or interrupted)."""


def execute(spec: RunSpec) -> Outcome:
    """Compute one run (in whatever process calls it)."""
    start = time.perf_counter()
    metrics = get_experiment(spec.experiment).run(spec.config, spec.seed_sequence())
    return spec, metrics, time.perf_counter() - start


def execute_batch(specs: list[RunSpec]) -> list[Outcome]:
    """Compute runs that share one config, together when the experiment can batch them."""
    experiment = get_experiment(specs[0].experiment)
    if len(specs) == 1 or experiment.run_batch is None:
        return [execute(spec) for spec in specs]
    start = time.perf_counter()
    results = experiment.run_batch(specs[0].config, [s.seed_sequence() for s in specs])
    seconds = (time.perf_counter() - start) / len(specs)
    return [(spec, metrics, seconds) for spec, metrics in zip(specs, results, strict=True)]


_worker_sink: Throttled | None = None


def _execute_in_worker(specs: list[RunSpec]) -> list[Outcome]:
    """:func:`execute_batch` in a pool worker, sending on the progress it still holds."""
    try:
        return execute_batch(specs)
    finally:
        if _worker_sink is not None:
            _worker_sink.flush()


def _worker_init(queue: Any, threads: int, parent: int) -> None:
    global _worker_sink
    _exit_with_parent(parent)
    _worker_sink = Throttled(queue.put)
    install_sink(_worker_sink)
    os.environ["OMP_NUM_THREADS"] = str(threads)
    if "torch" in sys.modules:  # forked from a parent that imported it
        sys.modules["torch"].set_num_threads(threads)


def _exit_with_parent(parent: int) -> None:
    """End this worker as soon as the process that started it is gone."""
    if sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            pr_set_pdeathsig = 1
            ctypes.CDLL(None, use_errno=True).prctl(pr_set_pdeathsig, signal.SIGKILL)
    if os.getppid() != parent:  # the parent died before the signal was armed
        os._exit(1)

    def watch() -> None:  # elsewhere (or as a second line): poll, between compiled calls
        while os.getppid() == parent:
            time.sleep(PARENT_CHECK_SECONDS)
        os._exit(1)

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()


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
    observer: SweepObserver | None = None,
    description: str = "runs",
    seed_batch: int = 1,
) -> SweepResult:
    """Compute every spec not yet in ``store`` and commit each as it finishes.

    Runs of one config whose experiment can batch them are computed ``seed_batch`` at a
    time in one call (the results are the same as one by one).
    """
    workers = default_workers() if workers is None else workers
    require(workers >= 1, "workers", f"must be >= 1 (got {workers})")
    require(seed_batch >= 1, "seed_batch", f"must be >= 1 (got {seed_batch})")
    observer = observer or SweepObserver()
    todo = _order_by_cost(store_missing(store, specs))
    result = SweepResult(total=len(specs), reused=len(specs) - len(todo))
    missing = set(todo)
    stored_work = sum(_work(s) for s in specs if s not in missing)
    unit = get_experiment(specs[0].experiment).work_unit if specs else "runs"
    total = sum(map(_work, specs))
    observer.start(description, len(specs), result.reused, total, stored_work, unit)
    start = time.perf_counter()

    def commit(spec: RunSpec, metrics: dict[str, Any], seconds: float) -> None:
        store.put(spec.key, metrics, seconds, version)
        result.computed += 1
        result.run_seconds.append(seconds)
        if get_experiment(spec.experiment).work(spec.config) is None:
            observer.advance(1.0)
        observer.run_finished()

    try:
        if todo:
            _dispatch(_batches(todo, seed_batch), workers, commit, observer.advance)
    except KeyboardInterrupt:
        result.interrupted = True
        raise SweepInterrupted(result) from None
    finally:
        result.wall_seconds = time.perf_counter() - start
        observer.finish()
    return result


def _work(spec: RunSpec) -> float:
    """The progress units of one run (the run itself, for an experiment that reports none)."""
    work = get_experiment(spec.experiment).work(spec.config)
    return 1.0 if work is None else float(work)


def store_missing(store: ResultStore, specs: Sequence[RunSpec]) -> list[RunSpec]:
    missing = set(store.missing(s.key for s in specs))
    return [s for s in specs if s.key in missing]


def _order_by_cost(specs: list[RunSpec]) -> list[RunSpec]:
    """Longest first, so the slowest runs do not start last (results are unaffected)."""
    return sorted(specs, key=lambda s: -get_experiment(s.experiment).cost(s.config))


def _batches(todo: list[RunSpec], seed_batch: int) -> list[list[RunSpec]]:
    """Group runs of one batchable config into batches of up to ``seed_batch``."""
    groups: dict[tuple[str, str], list[RunSpec]] = {}
    for spec in todo:
        groups.setdefault((spec.experiment, spec.config_json), []).append(spec)
    batches = []
    for specs in groups.values():
        batchable = get_experiment(specs[0].experiment).batchable(specs[0].config)
        limit = seed_batch if batchable else 1
        batches += [specs[i : i + limit] for i in range(0, len(specs), limit)]
    return batches


def _dispatch(
    batches: list[list[RunSpec]],
    workers: int,
    commit: Callable[[RunSpec, dict[str, Any], float], None],
    advance: Callable[[float], None],
) -> None:
    for name in {b[0].experiment for b in batches}:
        get_experiment(name).warm_up()
    workers = min(workers, len(batches))
    if workers == 1:
        with progress_sink(advance):
            for batch in batches:
                for outcome in execute_batch(batch):
                    commit(*outcome)
        return
    method = "fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn"
    context = multiprocessing.get_context(method)
    queue = context.Queue()
    threads = max(1, default_workers() // workers)
    pool = ProcessPoolExecutor(
        workers,
        mp_context=context,
        initializer=_worker_init,
        initargs=(queue, threads, os.getpid()),
    )
    try:
        pending: set[Future] = {pool.submit(_execute_in_worker, batch) for batch in batches}
        while pending:
            done, pending = wait(pending, timeout=0.2, return_when=FIRST_COMPLETED)
            _drain(queue, advance)
            for future in done:
                for outcome in future.result():
                    commit(*outcome)
        _drain(queue, advance)
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
