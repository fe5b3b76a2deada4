"""What a backend computes: *tasks*, lists of batches of runs (a batch: runs of one config,
computed together when the experiment can batch them), and the functions that compute
them in whatever process a backend runs them, reporting progress through a callback,
with their deep learners on the sweep's device (:mod:`cmarlcd.devices`).

A task that raises does not lose what it finished: :func:`run_task` hands back the
outcomes of the runs done before, and a :class:`Failure` naming the runs that raised,
the error in one line and its traceback; the sweep stores the first and ends on the
second.

The leaf every backend imports (:mod:`~.local`, :mod:`~.worker`, :mod:`~.ray_cluster`).
"""

from __future__ import annotations

import pickle
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from cmarlcd import devices, provenance
from cmarlcd.experiments import get_experiment
from cmarlcd.policies.keeping import wanting
from cmarlcd.progress import Throttled, install_sink
from cmarlcd.run_logs import logging_runs, run_log_dir
from cmarlcd.runs import RunSpec

Outcome = tuple[RunSpec, dict[str, Any], float]
Task = list[list[RunSpec]]
ProgressCallback = Callable[[int, float, float], None]


@dataclass(frozen=True)
class Failure:
    """Why a task stopped before its last run: the runs being computed when it did (a
    batch computes its runs together), the error in one line (``Type: message``), the
    whole traceback, and the exception itself where it survives the trip between
    processes (``None`` where it cannot be pickled, or a worker process died)."""

    runs: tuple[RunSpec, ...]
    error: str
    details: str = ""
    interrupted: bool = False
    """A ``KeyboardInterrupt`` (Ctrl-C) rather than an error of the run."""
    exception: BaseException | None = None

    @classmethod
    def of(cls, runs: list[RunSpec], exc: BaseException, keep: bool = True) -> Failure:
        """The failure of ``runs`` that raised ``exc`` (``keep``: carry the exception
        itself where it pickles, for a caller in another process)."""
        lines = str(exc).strip().splitlines()
        error = type(exc).__name__ + (f": {lines[0]}" if lines else "")
        details = "".join(traceback.format_exception(exc))
        return cls(
            tuple(runs),
            error,
            details,
            isinstance(exc, KeyboardInterrupt),
            exc if keep and _pickles(exc) else None,
        )


Finished = tuple[int | None, list[Outcome], Failure | None]
"""A task's tag, the outcomes of its runs that finished, and why it stopped early (a
failure of no task in particular, a worker lost while it started, has no tag)."""


def _pickles(exc: BaseException) -> bool:
    try:
        pickle.loads(pickle.dumps(exc))
    except Exception:
        return False
    return True


#: The metrics' key a run's provenance travels under from its worker (never in metrics).
PROVENANCE = "_provenance"


def warm_up(specs: Sequence[RunSpec]) -> None:
    """Compile (or load from numba's cache) the kernels of the experiments of ``specs``
    in this process."""
    for name in sorted({spec.experiment for spec in specs}):
        get_experiment(name).warm_up()


def execute(spec: RunSpec) -> Outcome:
    """Compute one run (in whatever process calls it)."""
    start = time.perf_counter()
    experiment = get_experiment(spec.experiment)
    settings = experiment.settings_of(spec.config_json)
    with wanting(spec.keep_policy), logging_runs([run_log_dir(spec.log_dir, spec.name)]):
        metrics = experiment.run(settings, spec.seed_sequence())
    return spec, _with_device(experiment, settings, metrics), time.perf_counter() - start


def execute_batch(specs: list[RunSpec]) -> list[Outcome]:
    """Compute runs that share one config, together when the experiment can batch them."""
    experiment = get_experiment(specs[0].experiment)
    if len(specs) == 1 or experiment.run_batch is None:
        return [execute(spec) for spec in specs]
    start = time.perf_counter()
    settings = experiment.settings_of(specs[0].config_json)
    logs = [run_log_dir(spec.log_dir, spec.name) for spec in specs]
    with wanting(specs[0].keep_policy), logging_runs(logs):
        results = experiment.run_batch(settings, [s.seed_sequence() for s in specs])
    seconds = (time.perf_counter() - start) / len(specs)
    return [
        (spec, _with_device(experiment, settings, metrics), seconds)
        for spec, metrics in zip(specs, results, strict=True)
    ]


def _with_device(experiment: Any, settings: Any, metrics: dict[str, Any]) -> dict[str, Any]:
    """A deep run's metrics say which device computed it; every run's, under
    :data:`PROVENANCE` (taken out before the metrics are stored, and stored beside them),
    where it was computed (:mod:`cmarlcd.provenance`; torch's version where it is deep)."""
    info = dict(provenance.current())
    if not experiment.uses_device(settings):
        return {**metrics, PROVENANCE: {**info, "torch": None, "device": "cpu"}}
    device = devices.describe(devices.current())
    return {**metrics, "device": device, PROVENANCE: {**info, "device": device}}


def uses_device(task: Task) -> bool:
    """Whether a run of the task trains a deep learner (on the sweep's device)."""
    return any(
        get_experiment(spec.experiment).uses_device(
            get_experiment(spec.experiment).settings_of(spec.config_json)
        )
        for batch in task
        for spec in batch
    )


def run_task(
    task: Task, device: str = devices.DEFAULT_DEVICE, keep: bool = True
) -> tuple[list[Outcome], Failure | None]:
    """Every batch of a task, in turn, deep learners on ``device`` (a resolved name): the
    outcomes of the runs that finished, and the :class:`Failure` that stopped the task
    (``None`` when every run finished). A batch an experiment cannot batch is computed run
    by run, so a failure names the one run that raised."""
    outcomes: list[Outcome] = []
    with devices.running_on(device):
        for batch in task:
            together = len(batch) > 1 and get_experiment(batch[0].experiment).run_batch
            for runs in [batch] if together else [[spec] for spec in batch]:
                try:
                    outcomes += execute_batch(runs)
                except BaseException as exc:  # Ctrl-C included: it is a failure too
                    return outcomes, Failure.of(runs, exc, keep)
    return outcomes, None


def run_reporting(
    tag: int, task: Task, put: Callable[[Any], None], device: str = devices.DEFAULT_DEVICE
) -> Finished:
    """:func:`run_task`, sending ``(tag, amount, seconds)`` progress through ``put`` (at
    most every 0.1 s) and flushing what is left when the task ends."""
    sink = Throttled(lambda amount, seconds: put((tag, amount, seconds)))
    install_sink(sink)
    try:
        outcomes, failure = run_task(task, device)
    finally:
        sink.flush()
        install_sink(None)
    return tag, outcomes, failure
