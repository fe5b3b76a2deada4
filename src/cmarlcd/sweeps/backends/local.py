"""Backends on this machine: :class:`InlineBackend` (this process, ``--workers 1``) and
:class:`ProcessBackend` (worker processes that exit with their parent).

**How workers start.** Never as forks of the sweep's process: it runs threads (the claim
heartbeat, the progress display's refresh, a test runner's), and a fork copies any lock
one of them holds (the import lock, a logging or I/O lock) held for ever. Workers come
from :mod:`multiprocessing`'s fork server where the system has one (Linux, macOS), a
single-threaded process started once that has imported the package, and torch where the
sweep trains deep learners, and compiled the sweep's kernels (:mod:`~.preload`); a worker
is a fork of it, ready in a few milliseconds. Elsewhere (Windows) they are spawned fresh
and load the kernels from numba's cache. One rule for every lane: the fork server never
starts CUDA, so a worker on the GPU's lane can. Plug-ins registered in the sweep's
process reach the workers as :mod:`cmarlcd.plugins` says.

**How they end.** A worker that raises hands back the runs it finished and the error,
which ends the sweep (:class:`~cmarlcd.sweeps.runner.RunFailed`); a worker that dies (a
signal, an out-of-memory kill) ends it in the same way, naming the runs it was
computing; nothing waits for a result that cannot come. Workers ignore Ctrl-C: the sweep
stops them. A worker whose sweep's process dies (``kill -9``) exits at once.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import sys
import threading
import time
from collections import deque
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from multiprocessing.connection import Connection, wait
from typing import Any

from cmarlcd import devices
from cmarlcd._moved import MOVED
from cmarlcd.errors import ConfigError
from cmarlcd.limits import check_gpu_tasks, check_workers
from cmarlcd.plugins import Registrations
from cmarlcd.progress import progress_sink
from cmarlcd.runs import RunSpec
from cmarlcd.sweeps.backends import preload
from cmarlcd.sweeps.backends.tasks import (
    Failure,
    Finished,
    ProgressCallback,
    Task,
    run_task,
    uses_device,
    warm_up,
)
from cmarlcd.sweeps.backends.worker import serve

#: [choice] Seconds a worker that was told to end may take before it is killed.
END_SECONDS = 2.0
#: [choice] Seconds a worker may take to start (to import the plug-ins and load the
#: kernels the fork server did not: minutes only where numba compiles them afresh)
#: before the sweep gives up on it.
START_SECONDS = 600.0


class InlineBackend:
    """This process, one task per :meth:`poll`, deep learners on ``device`` (resolved)."""

    capacity = 1
    task_seconds = 0.0  # nothing to save by packing

    def __init__(self, on_progress: ProgressCallback, device: str = devices.DEFAULT_DEVICE) -> None:
        self.on_progress, self.device = on_progress, device
        self.queue: deque[tuple[int, Task]] = deque()

    def prepare(self, specs: Sequence[RunSpec]) -> None:
        warm_up(specs)

    def submit(self, tag: int, task: Task) -> None:
        self.queue.append((tag, task))

    def poll(self, timeout: float) -> list[Finished]:
        if not self.queue:
            time.sleep(timeout)
            return []
        tag, task = self.queue.popleft()
        with progress_sink(lambda amount, seconds: self.on_progress(tag, amount, seconds)):
            outcomes, failure = run_task(task, self.device)
        return [(tag, outcomes, failure)]

    def close(self, cancel: bool) -> None:
        self.queue.clear()


def default_workers() -> int:
    """All cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


# ------------------------------------------------------------------ the fork server


@dataclass
class _Server:
    """What the fork server this process started has loaded."""

    warm: frozenset[str] = frozenset()
    torch: bool = False
    ours: bool = False


_server = _Server()


def worker_context(warm: Sequence[str], deep: bool) -> Any:
    """The :mod:`multiprocessing` context workers start from: the fork server, started
    (again, where the one running lacks them) with the package, the kernels of the
    experiments ``warm`` and, for ``deep`` sweeps, torch; ``spawn`` where there is none."""
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    from multiprocessing import forkserver

    server = forkserver._forkserver  # the context's one server
    running = getattr(server, "_forkserver_pid", None) is not None
    enough = set(warm) <= _server.warm and (_server.torch or not deep)
    if running and (enough or not _server.ours or not hasattr(server, "_stop")):
        return multiprocessing.get_context("forkserver")  # (someone else's: kept)
    if running:
        server._stop()  # ours, without this sweep's kernels: started anew
    warm = sorted(_server.warm | set(warm))
    deep = deep or _server.torch or "torch" in sys.modules
    forkserver.set_forkserver_preload(_preloaded(deep))
    settings = {preload.WARM_UP_ENV: ",".join(warm)}
    if threading.current_thread() is threading.main_thread():
        settings[preload.PARENT_ENV] = str(os.getpid())  # (a thread's end would end it)
    with _environment(settings):
        server.ensure_running()
    _server.warm, _server.torch, _server.ours = frozenset(warm), deep, True
    return multiprocessing.get_context("forkserver")


def _preloaded(deep: bool) -> list[str]:
    """The modules the fork server imports: the package's that this process has (not the
    command line's, nor the reports' with their plotting library, nor the old names of
    moved modules), torch for deep sweeps, and :mod:`~.preload` last."""
    ours = sorted(
        name
        for name in list(sys.modules)
        if (name == "cmarlcd" or name.startswith("cmarlcd."))
        and not name.startswith(("cmarlcd.cli", "cmarlcd.__main__", "cmarlcd.reports"))
        and name not in MOVED
        and name != preload.__name__
    )
    return [*(["torch"] if deep else []), *ours, preload.__name__]


@contextlib.contextmanager
def _environment(settings: dict[str, str]) -> Iterator[None]:
    """``settings`` in this process's environment within the block (which a process
    started there inherits)."""
    saved = {name: os.environ.get(name) for name in settings}
    os.environ.update(settings)
    try:
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


# ------------------------------------------------------------------ the workers


@dataclass
class _Lane:
    """Workers that compute on one device, and the tasks sent to it not yet finished
    (``queue``: not yet given to a worker)."""

    size: int
    device: str
    queue: deque[tuple[int, Task]] = field(default_factory=deque)
    pending: int = 0


@dataclass
class _Worker:
    process: Any
    conn: Connection
    lane: _Lane
    started: float = field(default_factory=time.monotonic)
    ready: bool = False
    alive: bool = True
    eof: bool = False
    task: tuple[int, Task] | None = None


class ProcessBackend:
    """``workers`` local processes, each with an equal share of the cores for its threads.

    On the CPU every worker takes any task. With a GPU (``device``, resolved) the tasks
    that train deep learners go to ``gpu_tasks`` of the workers
    (:data:`cmarlcd.devices.GPU_TASKS`; at most all but one), which compute on the card,
    and the others to the rest, on the CPU (:meth:`has_room` tells the sweep which lane
    has room). One worker with a GPU is the GPU's lane alone and takes every task, the
    tabular ones on the CPU. The workers start with the first task (:meth:`prepare` says
    what they load first).
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
        self.threads = max(1, default_workers() // workers)
        on_gpu = device != devices.DEFAULT_DEVICE
        # one worker with a GPU is the GPU's lane and takes the tabular tasks too
        gpu_workers = min(gpu_tasks, max(workers - 1, 1)) if on_gpu else 0
        self.lanes: list[_Lane] = []
        if workers > gpu_workers:
            self.lanes.append(_Lane(workers - gpu_workers, devices.DEFAULT_DEVICE))
        if gpu_workers:
            self.lanes.append(_Lane(gpu_workers, device))
        self.workers: list[_Worker] = []
        self.warm: list[str] = []
        self.deep = False
        self.lost: list[Finished] = []

    def prepare(self, specs: Sequence[RunSpec]) -> None:
        """The workers will compute ``specs``: they start with those experiments' kernels
        loaded (and torch, where a run trains a deep learner)."""
        self.warm = sorted({spec.experiment for spec in specs})
        configs = {(spec.experiment, spec.config_json): spec for spec in specs}
        self.deep = any(uses_device([[spec]]) for spec in configs.values())

    def _lane(self, task: Task) -> _Lane:
        """The GPU's lane (the last) for a task that trains deep learners, the CPU's (the
        first) for the others; the one lane there is where there is one."""
        return self.lanes[-1] if uses_device(task) else self.lanes[0]

    def has_room(self, task: Task) -> bool:
        """Whether the lane ``task`` goes to has a free place (one running and one queued
        per worker)."""
        lane = self._lane(task)
        return lane.pending < 2 * lane.size

    def full(self) -> bool:
        """Whether every lane is full."""
        return all(lane.pending >= 2 * lane.size for lane in self.lanes)

    def submit(self, tag: int, task: Task) -> None:
        lane = self._lane(task)
        lane.queue.append((tag, task))
        lane.pending += 1
        if not self.workers:
            self._start()
        self._dispatch()

    def _start(self) -> None:
        context = worker_context(self.warm, self.deep)
        registrations = Registrations.current()
        for lane in self.lanes:
            for _ in range(lane.size):
                ours, theirs = context.Pipe()
                process = context.Process(
                    target=serve,
                    args=(theirs, lane.device, self.threads, registrations, self.warm),
                    name=f"cmarl-cd worker {len(self.workers) + 1}",
                )
                try:
                    process.start()
                except (OSError, EOFError) as exc:  # the fork server is gone
                    self.lost.append(_lost(f"a worker process could not start ({exc})"))
                    return
                finally:
                    theirs.close()
                self.workers.append(_Worker(process, ours, lane))

    def _dispatch(self) -> None:
        """Give each idle worker the next task of its lane."""
        for worker in self.workers:
            queue = worker.lane.queue
            if worker.alive and worker.ready and worker.task is None and queue:
                worker.task = queue.popleft()
                with contextlib.suppress(OSError):  # died meanwhile: its sentinel says so
                    worker.conn.send(worker.task)

    def poll(self, timeout: float) -> list[Finished]:
        finished, self.lost = self.lost, []
        live = [worker for worker in self.workers if worker.alive]
        if finished or not live:
            time.sleep(0 if finished else timeout)
            return finished
        waits = [w.conn for w in live if not w.eof] + [w.process.sentinel for w in live]
        ready = set(wait(waits, timeout))
        for worker in live:
            if worker.conn in ready:
                finished += self._read(worker)
        for worker in live:
            if worker.process.sentinel in ready:
                finished += self._died(worker)
            elif not worker.ready and time.monotonic() - worker.started > START_SECONDS:
                worker.alive = False
                worker.process.kill()
                finished.append(_lost(f"a worker process did not start in {START_SECONDS:.0f} s"))
        self._dispatch()
        return finished

    def _read(self, worker: _Worker) -> list[Finished]:
        """Every message ``worker`` has sent; its finished tasks."""
        finished: list[Finished] = []
        while not worker.eof and worker.conn.poll():
            try:
                message = worker.conn.recv()
            except (EOFError, OSError):
                worker.eof = True  # it is ending: its sentinel says how
                break
            kind, *body = message
            if kind == "progress":
                self.on_progress(*body)
            elif kind == "ready":
                if body[0] is not None:
                    raise ConfigError("workers", body[0])
                worker.ready = True
            else:  # done
                finished.append(tuple(body))  # type: ignore[arg-type]
                worker.task = None
                worker.lane.pending -= 1
        return finished

    def _died(self, worker: _Worker) -> list[Finished]:
        """A worker that ended on its own: the task it held fails, naming its runs."""
        finished = self._read(worker)  # what it sent before it went
        worker.alive = False
        worker.process.join(END_SECONDS)
        how = _how_it_ended(worker.process.exitcode)
        if worker.task is not None:
            tag, task = worker.task
            runs = tuple(spec for batch in task for spec in batch)
            worker.task = None
            worker.lane.pending -= 1
            failure = Failure(runs, f"its worker process {how}")
            return [*finished, (tag, [], failure)]
        if not worker.ready:
            return [
                *finished,
                _lost(
                    f"a worker process {how} while it started (its error is above; a "
                    "script that starts a sweep does so under `if __name__ == '__main__':`)"
                ),
            ]
        return [*finished, _lost(f"a worker process {how}")]

    def close(self, cancel: bool) -> None:
        """End the workers: told to where they are idle and ``cancel`` is not set,
        killed otherwise (and where they do not end within :data:`END_SECONDS`)."""
        for worker in self.workers:
            if worker.alive and not cancel and worker.task is None:
                with contextlib.suppress(OSError):
                    worker.conn.send(None)
        deadline = time.monotonic() + END_SECONDS
        for worker in self.workers:
            if cancel or worker.task is not None:
                worker.process.kill()
            worker.process.join(max(deadline - time.monotonic(), 0))
            if worker.process.exitcode is None:
                worker.process.kill()
                worker.process.join(END_SECONDS)
            worker.conn.close()
        self.workers = []
        for lane in self.lanes:
            lane.queue.clear()
            lane.pending = 0


def _lost(error: str) -> Finished:
    """A failure of no task in particular (a worker lost while starting or idle)."""
    return (None, [], Failure((), error))  # type: ignore[return-value]


def _how_it_ended(exitcode: int | None) -> str:
    if exitcode is None:
        return "stopped answering"
    if exitcode >= 0:
        return f"exited with status {exitcode}"
    name = signal.Signals(-exitcode).name
    return f"was killed by {name}" + (" (out of memory?)" if name == "SIGKILL" else "")
