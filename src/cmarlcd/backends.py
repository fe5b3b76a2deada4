"""Where runs are computed: in this process, in local worker processes, or on Ray.

A backend takes *tasks* tagged with a number, computes them somewhere, and hands back
each task's outcomes when asked (:meth:`Backend.poll`). A task is a list of *batches*
(runs of one config, computed together when the experiment can batch them): one long
batch, or several short ones packed together so that each task is worth sending (a
backend says how long a task should be, :attr:`Backend.task_seconds`). Progress reported
from inside a run (:func:`cmarlcd.progress.report_progress`) reaches the
``on_progress(tag, amount, seconds)`` callback given to the backend. Only the caller
writes to the store.

- :class:`InlineBackend`: this process, one batch at a time (``--workers 1``).
- :class:`ProcessBackend`: a pool of forked local processes. A worker whose parent dies
  (``kill -9``, an out-of-memory kill) exits at once rather than holding the store open;
  Ctrl-C stops the workers.
- :class:`cmarlcd.ray_backend.RayBackend`: tasks on a Ray cluster (the ``[ray]`` extra),
  imported only when chosen.
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
from collections import deque
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from queue import Empty
from typing import Any, Protocol

from cmarlcd.experiments import get_experiment
from cmarlcd.progress import Throttled, install_sink, progress_sink
from cmarlcd.runs import RunSpec

Outcome = tuple[RunSpec, dict[str, Any], float]
Finished = tuple[int, list[Outcome]]
Task = list[list[RunSpec]]
ProgressCallback = Callable[[int, float, float], None]

#: The backends ``--backend`` accepts.
BACKENDS = ("process", "ray")
#: How often a worker checks that its parent is still alive, in seconds (where the
#: operating system cannot tell it, as Linux's parent-death signal does).
PARENT_CHECK_SECONDS = 0.5


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


def execute_task(task: Task) -> list[Outcome]:
    """Every batch of a task, in turn."""
    return [outcome for batch in task for outcome in execute_batch(batch)]


def execute_reporting(tag: int, task: Task, put: Callable[[Any], None]) -> list[Outcome]:
    """:func:`execute_task`, sending ``(tag, amount, seconds)`` progress through ``put``
    (at most every 0.1 s) and flushing what is left when the task ends."""
    sink = Throttled(lambda amount, seconds: put((tag, amount, seconds)))
    install_sink(sink)
    try:
        return execute_task(task)
    finally:
        sink.flush()
        install_sink(None)


def default_workers() -> int:
    """All cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


class Backend(Protocol):
    """Computes tagged batches of runs."""

    capacity: int
    """How many tasks it should hold at once (queued or running)."""
    task_seconds: float
    """Short batches are packed into tasks of about this many estimated seconds."""

    def submit(self, tag: int, task: Task) -> None:
        """Start computing ``task``."""

    def poll(self, timeout: float) -> list[Finished]:
        """The batches finished since the last call, waiting up to ``timeout`` seconds
        for one."""

    def close(self, cancel: bool) -> None:
        """Release the workers; ``cancel`` drops batches not finished."""


class InlineBackend:
    """This process, one task per :meth:`poll`."""

    capacity = 1
    task_seconds = 0.0  # nothing to save by packing

    def __init__(self, on_progress: ProgressCallback) -> None:
        self.on_progress = on_progress
        self.queue: deque[tuple[int, Task]] = deque()

    def submit(self, tag: int, task: Task) -> None:
        self.queue.append((tag, task))

    def poll(self, timeout: float) -> list[Finished]:
        if not self.queue:
            time.sleep(timeout)
            return []
        tag, task = self.queue.popleft()
        with progress_sink(lambda amount, seconds: self.on_progress(tag, amount, seconds)):
            return [(tag, execute_task(task))]

    def close(self, cancel: bool) -> None:
        self.queue.clear()


_progress_queue: Any = None


def _execute_in_worker(tag: int, task: Task) -> Finished:
    return tag, execute_reporting(tag, task, _progress_queue.put)


def _worker_init(queue: Any, threads: int, parent: int) -> None:
    global _progress_queue
    _exit_with_parent(parent)
    _progress_queue = queue
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


class ProcessBackend:
    """A pool of ``workers`` local processes (forked where the system can), each with
    an equal share of the cores for its threads."""

    task_seconds = 0.05  # a task costs a fraction of a millisecond to send

    def __init__(self, workers: int, on_progress: ProgressCallback) -> None:
        self.on_progress = on_progress
        self.capacity = 2 * workers  # one running and one queued per worker
        method = "fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn"
        context = multiprocessing.get_context(method)
        self.queue = context.Queue()
        threads = max(1, default_workers() // workers)
        self.pool = ProcessPoolExecutor(
            workers,
            mp_context=context,
            initializer=_worker_init,
            initargs=(self.queue, threads, os.getpid()),
        )
        self.pending: set[Future] = set()

    def submit(self, tag: int, task: Task) -> None:
        self.pending.add(self.pool.submit(_execute_in_worker, tag, task))

    def poll(self, timeout: float) -> list[Finished]:
        if self.pending:
            done, self.pending = wait(self.pending, timeout=timeout, return_when=FIRST_COMPLETED)
        else:
            done = set()
            time.sleep(timeout)
        self._drain()
        return [future.result() for future in done]

    def _drain(self) -> None:
        while True:
            try:
                tag, amount, seconds = self.queue.get_nowait()
            except Empty:
                return
            self.on_progress(tag, amount, seconds)

    def close(self, cancel: bool) -> None:
        # On Ctrl-C the workers got the signal too and end; do not wait for queued runs.
        self.pool.shutdown(wait=not cancel, cancel_futures=cancel)


def make_backend(
    name: str, workers: int, on_progress: ProgressCallback, address: str | None = None
) -> Backend:
    """The backend called ``name`` (``process``: in-process when ``workers`` is 1)."""
    if name == "ray":
        from cmarlcd.ray_backend import RayBackend

        return RayBackend(workers, on_progress, address)
    if workers == 1:
        return InlineBackend(on_progress)
    return ProcessBackend(workers, on_progress)
