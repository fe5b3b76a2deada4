"""Backends on this machine: :class:`InlineBackend` (this process, ``--workers 1``) and
:class:`ProcessBackend` (a pool of forked worker processes that exit with their parent).
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
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from queue import Empty
from typing import Any

from cmarlcd import devices
from cmarlcd.limits import check_gpu_tasks, check_workers
from cmarlcd.progress import progress_sink
from cmarlcd.sweeps.backends.tasks import (
    Finished,
    ProgressCallback,
    Task,
    execute_reporting,
    execute_task,
    uses_device,
)

#: How often a worker checks that its parent is still alive, in seconds (where the
#: operating system cannot tell it, as Linux's parent-death signal does).
PARENT_CHECK_SECONDS = 0.5


class InlineBackend:
    """This process, one task per :meth:`poll`, deep learners on ``device`` (resolved)."""

    capacity = 1
    task_seconds = 0.0  # nothing to save by packing

    def __init__(self, on_progress: ProgressCallback, device: str = devices.DEFAULT_DEVICE) -> None:
        self.on_progress, self.device = on_progress, device
        self.queue: deque[tuple[int, Task]] = deque()

    def submit(self, tag: int, task: Task) -> None:
        self.queue.append((tag, task))

    def poll(self, timeout: float) -> list[Finished]:
        if not self.queue:
            time.sleep(timeout)
            return []
        tag, task = self.queue.popleft()
        with progress_sink(lambda amount, seconds: self.on_progress(tag, amount, seconds)):
            return [(tag, execute_task(task, self.device))]

    def close(self, cancel: bool) -> None:
        self.queue.clear()


_progress_queue: Any = None


def default_workers() -> int:
    """All cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def _execute_in_worker(tag: int, task: Task, device: str) -> Finished:
    return tag, execute_reporting(tag, task, _progress_queue.put, device)


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
    an equal share of the cores for its threads.

    On the CPU every worker takes any task. With a GPU (``device``, resolved; the parent
    has not started CUDA, :mod:`cmarlcd.devices`, so a worker can) the tasks that train
    deep learners go to ``gpu_tasks`` of the workers (:data:`cmarlcd.devices.GPU_TASKS`;
    at most all but one), which compute on the card, and the others to the rest, on the
    CPU (:meth:`has_room` tells the sweep which lane has room). One worker with a GPU
    is the GPU's lane alone and takes every task, the tabular ones on the CPU.
    """

    task_seconds = 0.05  # a task costs a fraction of a millisecond to send

    def __init__(
        self,
        workers: int,
        on_progress: ProgressCallback,
        device: str = devices.DEFAULT_DEVICE,
        gpu_tasks: int = devices.GPU_TASKS,
    ) -> None:
        check_workers(workers)
        check_gpu_tasks(gpu_tasks)
        self.on_progress = on_progress
        self.capacity = 2 * workers  # one running and one queued per worker
        method = "fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn"
        context = multiprocessing.get_context(method)
        threads = max(1, default_workers() // workers)
        on_gpu = device != devices.DEFAULT_DEVICE
        # one worker with a GPU is the GPU's lane and takes the tabular tasks too
        gpu_workers = min(gpu_tasks, max(workers - 1, 1)) if on_gpu else 0
        self.lanes: list[_Lane] = []
        if workers > gpu_workers:
            cpu_workers = workers - gpu_workers
            self.lanes.append(_Lane(cpu_workers, devices.DEFAULT_DEVICE, context, threads))
        if gpu_workers:
            # CUDA cannot start in a process forked after its parent started it (an
            # earlier sweep in this process on the GPU alone): such a lane is spawned
            started = "torch" in sys.modules and sys.modules["torch"].cuda.is_initialized()
            gpu_context = multiprocessing.get_context("spawn") if started else context
            self.lanes.append(_Lane(gpu_workers, device, gpu_context, threads))

    def _lane(self, task: Task) -> _Lane:
        """The GPU's lane (the last) for a task that trains deep learners, the CPU's (the
        first) for the others; the one lane there is where there is one."""
        return self.lanes[-1] if uses_device(task) else self.lanes[0]

    def has_room(self, task: Task) -> bool:
        """Whether the lane ``task`` goes to has a free place (one running and one queued
        per worker)."""
        lane = self._lane(task)
        return len(lane.pending) < 2 * lane.workers

    def full(self) -> bool:
        """Whether every lane is full."""
        return all(len(lane.pending) >= 2 * lane.workers for lane in self.lanes)

    def submit(self, tag: int, task: Task) -> None:
        lane = self._lane(task)
        lane.pending.add(lane.pool.submit(_execute_in_worker, tag, task, lane.device))

    def poll(self, timeout: float) -> list[Finished]:
        pending = {future for lane in self.lanes for future in lane.pending}
        if pending:
            done, _ = wait(pending, timeout=timeout, return_when=FIRST_COMPLETED)
            for lane in self.lanes:
                lane.pending -= done
        else:
            done = set()
            time.sleep(timeout)
        self._drain()
        return [future.result() for future in done]

    def _drain(self) -> None:
        """Hand on the progress every lane's workers reported."""
        for lane in self.lanes:
            while True:
                try:
                    tag, amount, seconds = lane.queue.get_nowait()
                except Empty:
                    break
                self.on_progress(tag, amount, seconds)

    def close(self, cancel: bool) -> None:
        # On Ctrl-C the workers got the signal too and end; do not wait for queued runs.
        for lane in self.lanes:
            lane.pool.shutdown(wait=not cancel, cancel_futures=cancel)


class _Lane:
    """Worker processes that compute on one device, the queue their progress comes
    back on, and their tasks not yet polled."""

    def __init__(self, workers: int, device: str, context: Any, threads: int) -> None:
        self.workers, self.device = workers, device
        self.queue = context.Queue()
        self.pool = ProcessPoolExecutor(
            workers,
            mp_context=context,
            initializer=_worker_init,
            initargs=(self.queue, threads, os.getpid()),
        )
        self.pending: set[Future] = set()
