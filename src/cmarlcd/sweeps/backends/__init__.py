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
- :class:`ProcessBackend`: local worker processes, started from a fork server that has
  the package and the sweep's kernels loaded (never forked from the sweep's threads). A
  worker whose parent dies (``kill -9``, an out-of-memory kill) exits at once rather
  than holding the store open; a worker that raises or dies ends the sweep with one
  line; Ctrl-C stops the workers.
- :class:`~.ray_cluster.RayBackend`: tasks on a Ray cluster (the ``[ray]`` extra),
  imported only when chosen.
"""

from __future__ import annotations

import importlib.util
from collections.abc import Sequence
from typing import Protocol

from cmarlcd.devices import DEFAULT_DEVICE, GPU_TASKS, resolve
from cmarlcd.errors import require
from cmarlcd.runs import RunSpec
from cmarlcd.sweeps.backends.local import InlineBackend, ProcessBackend, default_workers
from cmarlcd.sweeps.backends.tasks import Finished, ProgressCallback, Task

__all__ = ["BACKENDS", "Backend", "check_backend", "default_workers", "make_backend"]

#: The backends ``--backend`` accepts.
BACKENDS = ("process", "ray")


def check_backend(backend: str, address: str | None) -> None:
    """A known backend, an address only for Ray, and Ray installed when chosen (checked
    without importing it)."""
    require(
        backend in BACKENDS, "backend", f"must be one of {', '.join(BACKENDS)} (got {backend!r})"
    )
    require(address is None or backend == "ray", "address", "needs --backend ray")
    require(address is None or address.strip() != "", "address", "must not be empty")
    if address not in (None, "auto"):
        from cmarlcd.sweeps.backends.ray_cluster import head_of  # (imports no Ray)

        head_of(address)  # HOST:PORT or ray://HOST:PORT
    if backend == "ray":
        require(
            importlib.util.find_spec("ray") is not None,
            "backend",
            "ray needs Ray: pip install 'cmarl-cd[ray]'",
        )


class Backend(Protocol):
    """Computes tagged batches of runs."""

    capacity: int
    """How many tasks it should hold at once (queued or running)."""
    task_seconds: float
    """Short batches are packed into tasks of about this many estimated seconds."""

    def prepare(self, specs: Sequence[RunSpec]) -> None:
        """Ready the kernels of ``specs``' experiments where the runs will compute."""

    def submit(self, tag: int, task: Task) -> None:
        """Start computing ``task``."""

    def poll(self, timeout: float) -> list[Finished]:
        """The tasks finished since the last call, waiting up to ``timeout`` seconds for
        one: each task's runs that finished, and why it stopped early, if it did."""

    def close(self, cancel: bool) -> None:
        """Release the workers; ``cancel`` drops batches not finished."""


def make_backend(
    name: str,
    workers: int,
    on_progress: ProgressCallback,
    address: str | None = None,
    device: str = DEFAULT_DEVICE,
    gpu_tasks: int = GPU_TASKS,
) -> Backend:
    """The backend called ``name`` (``process``: in-process when ``workers`` is 1), its
    deep learners on ``device`` (``cpu``, ``cuda``, ``cuda:N``, ``auto``: resolved here
    for local workers, on each node for Ray), ``gpu_tasks`` of them sharing a GPU."""
    if name == "ray":
        from cmarlcd.sweeps.backends.ray_cluster import RayBackend

        return RayBackend(workers, on_progress, address, device, gpu_tasks)
    local = resolve(device)
    if workers == 1:
        return InlineBackend(on_progress, local)
    return ProcessBackend(workers, on_progress, local, gpu_tasks)
