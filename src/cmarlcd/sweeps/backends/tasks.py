"""What a backend computes: *tasks*, lists of batches of runs (a batch: runs of one config,
computed together when the experiment can batch them), and the functions that compute
them in whatever process a backend runs them, reporting progress through a callback,
with their deep learners on the sweep's device (:mod:`cmarlcd.devices`).

The leaf every backend imports (:mod:`~.local`, :mod:`~.ray_cluster`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from cmarlcd import devices
from cmarlcd.experiments import get_experiment
from cmarlcd.progress import Throttled, install_sink
from cmarlcd.runs import RunSpec

Outcome = tuple[RunSpec, dict[str, Any], float]
Finished = tuple[int, list[Outcome]]
Task = list[list[RunSpec]]
ProgressCallback = Callable[[int, float, float], None]


def execute(spec: RunSpec) -> Outcome:
    """Compute one run (in whatever process calls it)."""
    start = time.perf_counter()
    experiment = get_experiment(spec.experiment)
    settings = experiment.settings_of(spec.config_json)
    metrics = experiment.run(settings, spec.seed_sequence())
    return spec, _with_device(experiment, settings, metrics), time.perf_counter() - start


def execute_batch(specs: list[RunSpec]) -> list[Outcome]:
    """Compute runs that share one config, together when the experiment can batch them."""
    experiment = get_experiment(specs[0].experiment)
    if len(specs) == 1 or experiment.run_batch is None:
        return [execute(spec) for spec in specs]
    start = time.perf_counter()
    settings = experiment.settings_of(specs[0].config_json)
    results = experiment.run_batch(settings, [s.seed_sequence() for s in specs])
    seconds = (time.perf_counter() - start) / len(specs)
    return [
        (spec, _with_device(experiment, settings, metrics), seconds)
        for spec, metrics in zip(specs, results, strict=True)
    ]


def _with_device(experiment: Any, settings: Any, metrics: dict[str, Any]) -> dict[str, Any]:
    """A deep run's metrics say which device computed it."""
    if not experiment.uses_device(settings):
        return metrics
    return {**metrics, "device": devices.describe(devices.current())}


def uses_device(task: Task) -> bool:
    """Whether a run of the task trains a deep learner (on the sweep's device)."""
    return any(
        get_experiment(spec.experiment).uses_device(
            get_experiment(spec.experiment).settings_of(spec.config_json)
        )
        for batch in task
        for spec in batch
    )


def execute_task(task: Task, device: str = devices.DEFAULT_DEVICE) -> list[Outcome]:
    """Every batch of a task, in turn, deep learners on ``device`` (a resolved name)."""
    with devices.running_on(device):
        return [outcome for batch in task for outcome in execute_batch(batch)]


def execute_reporting(
    tag: int, task: Task, put: Callable[[Any], None], device: str = devices.DEFAULT_DEVICE
) -> list[Outcome]:
    """:func:`execute_task`, sending ``(tag, amount, seconds)`` progress through ``put``
    (at most every 0.1 s) and flushing what is left when the task ends."""
    sink = Throttled(lambda amount, seconds: put((tag, amount, seconds)))
    install_sink(sink)
    try:
        return execute_task(task, device)
    finally:
        sink.flush()
        install_sink(None)
