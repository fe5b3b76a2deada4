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

Ray is imported only here, and this module only when the backend is chosen.
"""

from __future__ import annotations

import contextlib
import importlib.util
import logging
import os
import sys
import time
from collections.abc import Callable, Iterator
from typing import Any

from cmarlcd import __version__
from cmarlcd.backends import Finished, ProgressCallback, Task, execute_reporting
from cmarlcd.errors import ConfigError, require

#: How many times Ray reruns a task whose worker process or node died.
TASK_RETRIES = 3
#: [choice] Memory for Ray's object store when this sweep starts a local Ray: results are
#: small (a few kB a run), so the smallest store Ray accepts is plenty.
LOCAL_OBJECT_STORE_BYTES = 80 * 1024**2


def ray_module() -> Any:
    """``ray``, or a one-line error saying how to install it."""
    require(
        importlib.util.find_spec("ray") is not None,
        "backend",
        "ray needs Ray: pip install 'cmarl-cd[ray]'",
    )
    import ray

    return ray


def _compute(tag: int, task: Task, relay: Any, version: str) -> Finished:
    """One task: its outcomes, its progress sent to ``relay`` on the way."""
    if version != __version__:
        raise RuntimeError(
            f"this Ray node runs cmarl-cd {__version__}, the sweep {version}: install "
            "the same version on every node"
        )
    os.environ["OMP_NUM_THREADS"] = "1"
    try:
        import torch

        torch.set_num_threads(1)
    except ImportError:
        pass
    return tag, execute_reporting(tag, task, lambda item: relay.add.remote(*item))


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


class RayBackend:
    """Tasks on a Ray cluster: the one at ``address``, or a local one of ``workers``
    CPUs."""

    #: [choice] A Ray task costs milliseconds to schedule and return: short runs go in
    #: tasks of about a second (estimated), long ones (a deep seed batch) alone.
    task_seconds = 1.0

    def __init__(
        self, workers: int | None, on_progress: ProgressCallback, address: str | None = None
    ) -> None:
        self.ray = ray = ray_module()
        self.on_progress = on_progress
        self.started_here = not ray.is_initialized()
        if self.started_here:
            self._connect(address, workers)
        cpus = int(ray.cluster_resources().get("CPU", 1))
        self.capacity = 2 * (workers or cpus)
        self.task: Callable[..., Any] = ray.remote(num_cpus=1, max_retries=TASK_RETRIES)(_compute)
        self.relay = ray.remote(num_cpus=0)(_Relay).remote()
        self.pending: dict[Any, int] = {}

    def _connect(self, address: str | None, workers: int | None) -> None:
        options: dict[str, Any] = {
            "include_dashboard": False,
            "log_to_driver": False,
            "logging_level": logging.ERROR,
        }
        if address is None:
            options.update(num_cpus=workers, object_store_memory=LOCAL_OBJECT_STORE_BYTES)
        try:
            with _silenced_stderr():  # Ray's C++ core logs each retry of a bad address
                self.ray.init(address=address, **options)
        except (ConnectionError, RuntimeError, ValueError) as exc:
            where = f"the Ray cluster at {address}" if address else "a local Ray"
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            parameter = "address" if address else "backend"
            raise ConfigError(parameter, f"cannot start {where}: {first}") from None

    def submit(self, tag: int, task: Task) -> None:
        ref = self.task.remote(tag, task, self.relay, __version__)
        self.pending[ref] = tag

    def poll(self, timeout: float) -> list[Finished]:
        done: list[Any] = []
        if self.pending:
            done, _ = self.ray.wait(list(self.pending), num_returns=1, timeout=timeout)
            if done:  # take every other finished task too
                pending = list(self.pending)
                done, _ = self.ray.wait(pending, num_returns=len(pending), timeout=0)
        else:
            time.sleep(timeout)
        for tag, amount, seconds in self.ray.get(self.relay.take.remote()):
            self.on_progress(tag, amount, seconds)
        finished = []
        for ref in done:
            del self.pending[ref]
            finished.append(self.ray.get(ref))
        return finished

    def close(self, cancel: bool) -> None:
        if cancel:
            for ref in self.pending:
                self.ray.cancel(ref, force=True)
        self.pending.clear()
        if self.started_here:
            self.ray.shutdown()
