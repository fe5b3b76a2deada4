"""Runs on a Ray cluster (``--backend ray [--address ADDR]``; the ``[ray]`` extra).

Each batch of runs (one run, or the seeds of a deep config stacked in one model) is one
Ray task of one CPU; short runs are packed into tasks of about :attr:`RayBackend.task_seconds`
estimated seconds. Results come back to the sweep's process, the store's one writer.
A task whose worker or node dies is retried by Ray (:data:`TASK_RETRIES` times); a run is
stored once whatever happens, because the store keeps the first result of a key and the
results are the same by seed. Progress from inside the runs reaches the driver through a
small actor.

Without an address, a local Ray is started with ``workers`` CPUs (all cores by default)
and stopped at the end. With ``--address``, the sweep joins that cluster; every node
needs the same cmarl-cd version installed (checked: a task on a node with another
version fails with a message saying so).

**Bounded waits.** A cluster that does not answer ends the sweep in one line
(:class:`cmarlcd.errors.BackendLost`) within a bounded time, keeping every run stored
before: its head must accept a connection within :data:`REACH_SECONDS` and Ray's
handshake finish within :data:`CONNECT_SECONDS`; during the sweep the head is asked every
:data:`HEAD_CHECK_SECONDS` and a head silent for :data:`LOST_SECONDS` ends it. A worker
node that dies is not an end: Ray reruns its tasks elsewhere (:data:`TASK_RETRIES`). A
cluster whose nodes listen on loopback only (``127.0.0.1``, as ``ray start
--node-ip-address=127.0.0.1`` or ``ray.cluster_utils.Cluster`` make them) is joined at
that address: Ray's own client would rewrite a loopback address to the machine's outside
address, where such a cluster answers nothing.

Ray is imported only here, and only when the backend is chosen.
"""

from __future__ import annotations

import contextlib
import importlib.util
import logging
import math
import os
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from cmarlcd import devices
from cmarlcd.errors import BackendLost, ConfigError, require
from cmarlcd.plugins import Registrations, missing_message
from cmarlcd.runs import RunSpec
from cmarlcd.sweeps.backends.ray_address import (  # noqa: F401  (re-exported)
    KEEP_LOOPBACK_ENV,
    REACH_SECONDS,
    answers,
    head_of,
    is_loopback,
    join_address,
    keep_loopback,
    listens_on_loopback_only,
    outside_address,
    reach,
)
from cmarlcd.sweeps.backends.tasks import (
    Finished,
    ProgressCallback,
    Task,
    run_reporting,
    uses_device,
    warm_up,
)
from cmarlcd.version import __version__

#: How many times Ray reruns a task whose worker process or node died.
TASK_RETRIES = 3
#: [choice] Seconds for Ray's handshake with a reachable cluster (Ray itself would wait
#: minutes for a node it cannot find, printing nothing).
CONNECT_SECONDS = 60.0
#: [choice] During a sweep: how often the head is asked whether it is there, and how long
#: it may be silent before the sweep ends (well within Ray's own 60 s, after which Ray
#: kills the driver with a stack trace).
HEAD_CHECK_SECONDS = 2.0
LOST_SECONDS = 20.0
#: How a task on a node with another cmarl-cd version starts its error.
VERSION_MISMATCH = "this Ray node runs cmarl-cd"
#: How a task on a node without the sweep's plug-ins starts its error.
PLUGINS_MISSING = "on a Ray node,"
#: [choice] Memory for Ray's object store when this sweep starts a local Ray: results are
#: small (a few kB a run), so the smallest store Ray accepts is plenty.
LOCAL_OBJECT_STORE_BYTES = 80 * 1024**2


def why(exc: BaseException) -> str:
    """The first line of ``exc``, and of the error it wraps where that says more (Ray's
    "failed to connect" hides the cause: a token refused, a version apart)."""

    def first(error: BaseException) -> str:
        return (str(error).strip().splitlines() or [type(error).__name__])[0]

    text, cause = first(exc), exc.__cause__ or exc.__context__
    if cause is not None and first(cause) not in text:
        text += f" ({type(cause).__name__}: {first(cause)})"
    return text


def ray_module() -> Any:
    """``ray``, or a one-line error saying how to install it."""
    require(
        importlib.util.find_spec("ray") is not None,
        "backend",
        "ray needs Ray: pip install 'cmarl-cd[ray]'",
    )
    import ray

    return ray


def cluster_device(device: str, gpus: float) -> str:
    """The device the cluster's deep tasks use: ``cpu``, or ``cuda`` where the cluster
    has a GPU, or part of one (``auto`` takes one if it has any). Ray gives each deep
    task its share of a GPU, which the task sees as ``cuda:0``, so ``cuda:N`` other than
    ``cuda:0`` is refused, and so is a GPU asked of a cluster without one (its tasks
    would wait forever)."""
    devices.check_device(device)
    if device == "auto":
        return "cuda" if gpus else devices.DEFAULT_DEVICE
    if device == devices.DEFAULT_DEVICE:
        return device
    require(
        device in ("cuda", "cuda:0"),
        "device",
        f"{device}: on Ray each task is given its GPU by Ray; use --device cuda",
    )
    require(gpus > 0, "device", f"{device}: the Ray cluster has no GPU")
    return "cuda"


def _compute(
    tag: int, task: Task, relay: Any, version: str, device: str, plugins: Registrations
) -> Finished:
    """One task: its outcomes (and why it stopped, where a run failed), its progress sent
    to ``relay`` on the way, its deep learners on ``device`` as this node resolves it (a
    task given a GPU by Ray sees that one as ``cuda:0``), the sweep's ``plugins``
    imported first (their modules must be importable on the node)."""
    if version != __version__:
        raise RuntimeError(
            f"{VERSION_MISMATCH} {__version__}, the sweep {version}: install the same "
            "version on every node"
        )
    missing = missing_message(plugins)
    if missing is not None:
        raise RuntimeError(f"{PLUGINS_MISSING} {missing}")
    os.environ["OMP_NUM_THREADS"] = "1"
    try:
        import torch

        torch.set_num_threads(1)
    except ImportError:
        pass
    resolved = devices.resolve(device)
    return run_reporting(tag, task, lambda item: relay.add.remote(*item), resolved)


@contextlib.contextmanager
def _silenced_stderr() -> Iterator[None]:
    """Send what is written to file descriptor 2 (C++ logs included) nowhere."""
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with open(os.devnull, "wb") as devnull:
            os.dup2(devnull.fileno(), 2)
            yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


class _Relay:
    """Collects progress from the tasks until the driver takes it."""

    def __init__(self) -> None:
        self.items: list[tuple[int, float, float]] = []

    def add(self, tag: int, amount: float, seconds: float) -> None:
        self.items.append((tag, amount, seconds))

    def take(self) -> list[tuple[int, float, float]]:
        items, self.items = self.items, []
        return items


#: Called with the one-line message when the head has been silent for LOST_SECONDS and
#: the sweep has not ended itself within GRACE_SECONDS more (its main thread blocked in a
#: Ray call on the dead cluster). The command line sets it to print the line and leave;
#: a library caller may set its own (by default the watch only marks the backend lost).
on_lost: Callable[[str], None] | None = None
#: Seconds the sweep's own thread has to end the sweep once the head is lost.
GRACE_SECONDS = 5.0


class HeadWatch:
    """A thread that asks the cluster's head every :data:`HEAD_CHECK_SECONDS` whether it
    is there (a TCP connection to its port), and once it has been silent for
    :data:`LOST_SECONDS` sets :attr:`lost` to the message that ends the sweep."""

    def __init__(self, head: tuple[str, int] | None, address: str) -> None:
        self.head, self.address = head, address
        self.lost: str | None = None
        self.stop = threading.Event()
        if head is not None:
            threading.Thread(target=self._watch, name="ray-head-watch", daemon=True).start()

    def _watch(self) -> None:
        heard = time.monotonic()
        while not self.stop.wait(HEAD_CHECK_SECONDS):
            if answers(*self.head, HEAD_CHECK_SECONDS) is None:
                heard = time.monotonic()
            elif time.monotonic() - heard > LOST_SECONDS:
                self.lost = (
                    f"--backend: the Ray cluster at {self.address} stopped answering (no "
                    f"reply from its head for {LOST_SECONDS:.0f} s); the runs stored before "
                    "are kept: run the same command again to resume"
                )
                if not self.stop.wait(GRACE_SECONDS) and on_lost is not None:
                    on_lost(self.lost)
                return


def quiet_cluster_messages() -> None:
    """Keep the cluster's own notices (a task retried after its node died...) off the
    terminal: Ray prints them to stdout from a thread of its own, where they would break
    a ``--json`` document; they go to the ``cmarlcd.ray`` logger instead. (Ray offers no
    switch for it: its module-level printer is replaced; should Ray rename it, nothing
    changes but the notices.)"""
    with contextlib.suppress(ImportError, AttributeError):
        from ray._private import worker

        log = logging.getLogger("cmarlcd.ray")

        def to_log(data: dict, ignore_prefix: bool = False) -> None:
            for line in data.get("lines", []):
                log.info("%s: %s", data.get("pid", "ray"), line)

        if worker.print_to_stdstream is not to_log:
            worker.print_to_stdstream = to_log


def gcs_head(ray: Any) -> tuple[str, int] | None:
    """``(host, port)`` of the cluster's head this process joined (None if unknown)."""
    with contextlib.suppress(Exception):
        return head_of(ray.get_runtime_context().gcs_address)
    return None


class RayBackend:
    """Tasks on a Ray cluster: the one at ``address``, or a local one of ``workers``
    CPUs."""

    #: [choice] A Ray task costs milliseconds to schedule and return: short runs go in
    #: tasks of about a second (estimated), long ones (a deep seed batch) alone.
    task_seconds = 1.0

    def __init__(
        self,
        workers: int | None,
        on_progress: ProgressCallback,
        address: str | None = None,
        device: str = devices.DEFAULT_DEVICE,
        gpu_tasks: int = devices.GPU_TASKS,
    ) -> None:
        head = reach(address) if address not in (None, "auto") else None
        joined = join_address(address, head)
        self.ray = ray = ray_module()
        self.on_progress = on_progress
        self.address = address or "a local Ray"
        self.lost = False
        self.failure: BaseException | None = None
        self.started_here = not ray.is_initialized()
        self.released = threading.Event()  # ends the thread that started Ray (close)
        if self.started_here:
            self._connect(joined, workers)
        try:
            self._start(address, head, workers, device, gpu_tasks)
        except BaseException:
            if self.started_here:
                self._shutdown()
            raise

    def _start(
        self,
        address: str | None,
        head: tuple[str, int] | None,
        workers: int | None,
        device: str,
        gpu_tasks: int,
    ) -> None:
        """What the sweep needs of the cluster it joined: its device, the head to watch,
        its capacity, the remote functions and the progress relay."""
        ray = self.ray
        resources = ray.cluster_resources()
        self.device = cluster_device(device, float(resources.get("GPU", 0)))
        self.head = head or gcs_head(ray)
        self.watch = HeadWatch(self.head, self.address)
        cpus = int(resources.get("CPU", 1))
        self.capacity = 2 * (workers or cpus)
        # each deep task asks for 1/gpu_tasks of a GPU, tabular tasks for none
        self.gpu_capacity = math.floor(2 * gpu_tasks * float(resources.get("GPU", 0)))
        self.task: Callable[..., Any] = ray.remote(num_cpus=1, max_retries=TASK_RETRIES)(_compute)
        # a function of its own (not .options): Ray then ends a GPU task's worker after it,
        # so no process keeps a card's context for a task Ray gives another card
        self.gpu_task = ray.remote(num_cpus=1, num_gpus=1 / gpu_tasks, max_retries=TASK_RETRIES)(
            _compute
        )
        # the actor class is sent to the cluster once: sending it again to make a lost
        # relay anew is a call to the head that never returns once the head is gone
        self.relay_class = ray.remote(num_cpus=0)(_Relay)
        self.relay = self.relay_class.remote()
        self.pending: dict[Any, int] = {}
        self.plugins = Registrations()
        self.on_gpu: set[Any] = set()

    def _connect(self, address: str | None, workers: int | None) -> None:
        """``ray.init``, given :data:`CONNECT_SECONDS` to finish (Ray offers no timeout
        for it), in a thread that then holds on until :meth:`close`: on Linux a local
        Ray's services are bound to the *thread* that starts them (a parent-death signal,
        which fires when that thread ends), so a thread that ended after ``init`` would
        take the local cluster down with it, and the sweep with it, in silence."""
        options: dict[str, Any] = {
            "include_dashboard": False,
            "log_to_driver": False,
            "logging_level": logging.ERROR,
        }
        if address is None:  # a Ray of its own, even where another one runs on this machine
            options.update(num_cpus=workers, object_store_memory=LOCAL_OBJECT_STORE_BYTES)
        failure: list[BaseException] = []
        started = threading.Event()
        os.environ.setdefault("RAY_BACKEND_LOG_LEVEL", "fatal")  # the core's C++ logs

        def init_and_hold() -> None:
            try:
                self.ray.init(address=address or "local", **options)
            except BaseException as exc:  # handed to the caller
                failure.append(exc)
                return
            finally:
                started.set()
            self.released.wait()  # the local Ray's services live as long as this thread

        with _silenced_stderr():  # Ray's C++ core logs each retry of a bad address
            thread = threading.Thread(target=init_and_hold, name="ray-keeper", daemon=True)
            thread.start()
            started.wait(CONNECT_SECONDS)
        where = f"the Ray cluster at {address}" if address else "a local Ray"
        if not started.is_set():
            self.lost = True
            self.released.set()  # a Ray that starts late ends with its thread
            if address is None:
                raise BackendLost(
                    f"--backend: a local Ray did not start within {CONNECT_SECONDS:.0f} s; "
                    "nothing was computed"
                )
            raise BackendLost(
                f"--address: {where} accepted a connection but did not let this "
                f"sweep join within {CONNECT_SECONDS:.0f} s (is this machine one of its "
                "nodes? from elsewhere use ray://HEAD:10001); nothing was computed"
            )
        quiet_cluster_messages()
        if failure:
            exc = failure[0]
            if not isinstance(exc, (ConnectionError, RuntimeError, ValueError)):
                raise exc
            parameter = "address" if address else "backend"
            verb = "join" if address else "start"
            raise ConfigError(parameter, f"cannot {verb} {where}: {why(exc)}") from None

    def _shutdown(self) -> None:
        """Stop the Ray this backend started (its services first, then the thread that
        holds them)."""
        try:
            self.ray.shutdown()
        finally:
            self.released.set()

    def prepare(self, specs: Sequence[RunSpec]) -> None:
        """Compile the kernels of ``specs`` here first, so that Ray's workers on this
        machine load them from numba's cache rather than compile them each; the tasks
        carry the plug-ins registered here."""
        warm_up(specs)
        self.plugins = Registrations.current()

    def _on_gpu(self, task: Task) -> bool:
        return self.device != devices.DEFAULT_DEVICE and uses_device(task)

    def has_room(self, task: Task) -> bool:
        """Whether ``task`` may be sent now: a task for a GPU while fewer than two per
        share of a GPU (``gpu_tasks`` a GPU) wait or run, so that tabular tasks are not
        held behind them."""
        return not self._on_gpu(task) or len(self.on_gpu) < self.gpu_capacity

    def submit(self, tag: int, task: Task) -> None:
        if self.watch.lost is not None:
            self.lost = True
            raise BackendLost(self.watch.lost)
        on_gpu = self._on_gpu(task)
        try:
            if on_gpu:
                ref = self.gpu_task.remote(
                    tag, task, self.relay, __version__, self.device, self.plugins
                )
            else:
                ref = self.task.remote(
                    tag, task, self.relay, __version__, devices.DEFAULT_DEVICE, self.plugins
                )
        except Exception as exc:  # the cluster went away as the task was sent
            raise self._went_away(exc, "as a task was sent") from None
        if on_gpu:
            self.on_gpu.add(ref)
        self.pending[ref] = tag

    def poll(self, timeout: float) -> list[Finished]:
        if self.failure is not None:
            raise self.failure
        if self.watch.lost is not None:
            self.lost = True
            raise BackendLost(self.watch.lost)
        done: list[Any] = []
        if self.pending:
            done, _ = self.ray.wait(list(self.pending), num_returns=1, timeout=timeout)
            if done:  # take every other finished task too
                pending = list(self.pending)
                done, _ = self.ray.wait(pending, num_returns=len(pending), timeout=0)
        else:
            time.sleep(timeout)
        finished = []
        for ref in done:
            del self.pending[ref]
            self.on_gpu.discard(ref)
            try:
                finished.append(self.ray.get(ref, timeout=LOST_SECONDS))
            except self.ray.exceptions.RayError as exc:
                self.failure = self._failure(exc)
                break  # the runs finished so far are stored first
        if self.failure is None:  # a failure in hand ends the sweep before the relay is asked
            self._relay_progress()
        return finished

    def _failure(self, exc: BaseException) -> BaseException:
        """What a task's failure ends the sweep with (a run's own error comes back as its
        task's :class:`~.tasks.Failure`, not here): another version of cmarl-cd on a node,
        or plug-ins it cannot import, as one line; another error of the task as it is;
        and a task the cluster lost (its node died, after the retries) as
        :class:`BackendLost`."""
        cause = getattr(exc, "cause", None)
        if isinstance(exc, self.ray.exceptions.RayTaskError) and cause is not None:
            if str(cause).startswith((VERSION_MISMATCH, PLUGINS_MISSING)):
                return ConfigError("backend", str(cause))
            return cause
        self.lost = True
        first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        return BackendLost(
            f"--backend: the Ray cluster at {self.address} lost a task ({first}); the runs "
            "stored before are kept: run the same command again to resume"
        )

    def _went_away(self, exc: BaseException, when: str) -> BackendLost:
        """The one line that ends a sweep whose cluster went away ``when``."""
        self.lost = True
        first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        return BackendLost(
            f"--backend: the Ray cluster at {self.address} went away {when} ({first}); the "
            "runs stored before are kept: run the same command again to resume"
        )

    def _relay_progress(self) -> None:
        """Hand on the progress the relay collected; a relay lost with its node is made
        anew (the tasks' later reports go to the old one: the runner tops up each task's
        progress when its runs are stored)."""
        exceptions = self.ray.exceptions
        try:
            items = self.ray.get(self.relay.take.remote(), timeout=HEAD_CHECK_SECONDS)
        except exceptions.GetTimeoutError:
            return
        except exceptions.RayActorError:
            head_answers = self.head is None or answers(*self.head, HEAD_CHECK_SECONDS) is None
            if self.watch.lost is None and head_answers:
                try:
                    self.relay = self.relay_class.remote()  # needs the head
                except Exception as exc:  # the cluster went away meanwhile
                    raise self._went_away(exc, "as the progress relay was made anew") from None
            return
        for tag, amount, seconds in items:
            self.on_progress(tag, amount, seconds)

    def close(self, cancel: bool) -> None:
        self.watch.stop.set()
        if self.lost or self.watch.lost is not None:  # Ray would wait on the dead cluster
            self.released.set()  # a Ray this sweep started ends with its thread
            return
        if cancel:
            for ref in self.pending:
                self.ray.cancel(ref, force=True)
        self.pending.clear()
        if self.started_here:
            self._shutdown()
