"""What a run is: its identity and seeds (:class:`RunSpec`), and how an experiment
computes runs (:class:`Experiment`).

A *run* is (experiment, algorithm, config, root seed, run index). Its random streams come
from :meth:`RunSpec.seed_sequence`, a :class:`numpy.random.SeedSequence` built from the
root seed, a digest of the experiment and config, and the run index, so a run's result
never depends on which worker ran it, how many workers there were, or which other runs
were in the same sweep. The algorithm name is deliberately left out of the seed:
algorithms compared under the same config see the same random games (common random
numbers).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from cmarlcd.store import RunKey, canonical_json

RunFunction = Callable[[dict[str, Any], np.random.SeedSequence], dict[str, Any]]
BatchFunction = Callable[[dict[str, Any], list[np.random.SeedSequence]], list[dict[str, Any]]]


def _nothing() -> None:
    """No warm-up."""


def _unit_cost(config: Mapping[str, Any]) -> float:
    return 1.0


def _not_batchable(config: Mapping[str, Any]) -> bool:
    return False


def _no_work_reported(config: Mapping[str, Any]) -> float | None:
    return None


@dataclass(frozen=True)
class Experiment:
    """What the runner needs to know about an experiment.

    Attributes:
        name: the store's experiment name.
        run: computes one run's metrics from its config and seed sequence.
        warm_up: compiles the kernels once in the parent before workers fork.
        cost: the estimated seconds of one run of a config on one core (rough, fitted to
            measured runs, benchmarks/fit_costs.py; a run that reports progress says what
            each unit costs, :func:`cmarlcd.progress.unit_cost`, so that its reports add
            up to this): expensive batches start first, and a sweep of several
            experiments weighs their progress by it for one overall ETA.
        run_batch: optional; computes several runs of one config together (e.g. seeds
            stacked in one model). It must give each run the metrics ``run`` would.
        batchable: whether runs of a config may share one ``run_batch`` call.
        work: the progress units (e.g. episodes) one run of a config reports with
            :func:`cmarlcd.progress.report_progress`, or None when it reports none (the
            runner then counts the run itself as one unit).
        work_unit: what ``work`` counts, for progress displays.
    """

    name: str
    run: RunFunction
    warm_up: Callable[[], None] = _nothing
    cost: Callable[[Mapping[str, Any]], float] = _unit_cost
    run_batch: BatchFunction | None = None
    batchable: Callable[[Mapping[str, Any]], bool] = _not_batchable
    work: Callable[[Mapping[str, Any]], float | None] = _no_work_reported
    work_unit: str = "runs"


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
        return json.loads(self.config_json)

    def seed_sequence(self) -> np.random.SeedSequence:
        """The run's root of randomness: (root seed; digest of experiment+stream, index)."""
        stream = self.stream_json or self.config_json
        digest = hashlib.sha256(f"{self.experiment}\n{stream}".encode()).digest()
        words = [int.from_bytes(digest[i : i + 4], "little") for i in range(0, 16, 4)]
        return np.random.SeedSequence(self.root_seed, spawn_key=(*words, self.run_index))
