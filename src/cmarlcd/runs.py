"""What a run is: its identity and seeds (:class:`RunSpec`, :class:`RunKey`), what a
stored one holds (:class:`RunRecord`), and how an experiment computes runs
(:class:`Experiment`). A leaf under the experiments, the sweeps and the reports: it imports
nothing of the package.

A *run* is (experiment, algorithm, config, root seed, run index). Its random streams come
from :meth:`RunSpec.seed_sequence`, a :class:`numpy.random.SeedSequence` built from the
root seed, a digest of the experiment and config, and the run index, so a run's result
never depends on which worker ran it, how many workers there were, or which other runs
were in the same sweep. The algorithm name is deliberately left out of the seed:
algorithms compared under the same config see the same random games (common random
numbers).
"""

from __future__ import annotations

import functools
import hashlib
import json
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field, fields
from typing import Any, Self

import numpy as np


def canonical_json(config: Mapping[str, Any]) -> str:
    """The canonical text of a config: sorted keys, no whitespace."""
    return json.dumps(dict(config), sort_keys=True, separators=(",", ":"))


#: Field metadata naming the version a setting was added in (:func:`added_setting`).
ADDED_IN = "added_in"
#: Field metadata: the value of an added setting that keeps the behaviour from before it.
BEFORE = "before"
_AS_DEFAULT = object()


def added_setting(default: Any, version: str, before: Any = _AS_DEFAULT) -> Any:
    """A dataclass field for a setting added in ``version``, after runs were stored.

    ``before`` is the value that keeps the behaviour from before the setting existed
    (default: ``default``). At that value the setting is left out of a run's identity
    (:func:`identity`), and a stored identity without it reads as that value
    (:func:`as_stored`), so that stores made before it still resume and every run keeps
    its seeds and numbers. A ``default`` other than ``before`` changes what new runs do:
    they carry the setting in their identity, so they are new runs, not the stored ones.
    """
    kept = default if before is _AS_DEFAULT else before
    return field(default=default, metadata={ADDED_IN: version, BEFORE: kept})


def identity(config: Any) -> dict[str, Any]:
    """A settings dataclass as a run's identity: every field (nested ones as
    :func:`dataclasses.asdict` writes them) but the settings added since runs were
    stored (:func:`added_setting`) that hold their value from before."""
    values = asdict(config)
    for spec in fields(config):
        if ADDED_IN in spec.metadata and getattr(config, spec.name) == spec.metadata[BEFORE]:
            del values[spec.name]
    return values


def as_stored(kind: type, values: Mapping[str, Any]) -> dict[str, Any]:
    """The fields ``values`` of a stored identity of a ``kind`` dataclass, with each added
    setting it leaves out (:func:`identity`) at its value from before."""
    left_out = {
        spec.name: spec.metadata[BEFORE]
        for spec in fields(kind)
        if ADDED_IN in spec.metadata and spec.name not in values
    }
    return {**left_out, **values}


@dataclass(frozen=True)
class RunKey:
    """The identity of one run in the store."""

    experiment: str
    algorithm: str
    config: str
    root_seed: int
    run_index: int

    def values(self) -> tuple[str, str, str, int, int]:
        return (self.experiment, self.algorithm, self.config, self.root_seed, self.run_index)


@dataclass(frozen=True)
class RunRecord:
    """A stored run: its key, its metrics, how long it took and the package version that
    computed it."""

    key: RunKey
    metrics: dict[str, Any]
    wall_seconds: float
    version: str = ""
    finished_at: float = 0.0
    """When it was stored, in seconds since the epoch (0: not read from a store)."""

    @property
    def config(self) -> dict[str, Any]:
        return json.loads(self.key.config)


class Settings:
    """Base of an experiment's typed settings of one run (a frozen dataclass).

    Settings travel through sweeps, the runner, the backends and the reports as these
    objects; only the store sees them as a dict, :meth:`to_config`, whose canonical JSON
    is the run's identity. :meth:`from_config` reads a stored dict back, and
    ``from_config(c).to_config() == c`` for every config the package stores (tested), so
    a store written by an earlier version resumes. The defaults suit a flat dataclass
    of JSON values; a settings type with nested parts overrides both.
    """

    def to_config(self) -> dict[str, Any]:
        """The settings as the store keeps them."""
        return asdict(self)  # type: ignore[call-overload]

    @classmethod
    def from_config(cls, config: Mapping[str, Any]) -> Self:
        """Settings from a stored config."""
        return cls(**as_stored(cls, config))

    def stream(self) -> dict[str, Any] | None:
        """The part of the config that seeds the run's random streams (None: all of it),
        so that settings outside it (e.g. evaluation budgets) leave the streams as
        they are."""
        return None


@functools.lru_cache(maxsize=8192)
def parse_settings(kind: type[Settings], config_json: str) -> Settings:
    """``kind`` read from a stored config's canonical JSON (cached: settings are
    immutable, and a sweep asks for each config's many times)."""
    return kind.from_config(json.loads(config_json))


RunFunction = Callable[[Any, np.random.SeedSequence], dict[str, Any]]
BatchFunction = Callable[[Any, list[np.random.SeedSequence]], list[dict[str, Any]]]


def _nothing() -> None:
    """No warm-up."""


def _unit_cost(settings: Any) -> float:
    return 1.0


def _not_batchable(settings: Any) -> bool:
    return False


def _no_work_reported(settings: Any) -> float | None:
    return None


def _no_device(settings: Any) -> bool:
    return False


def _keeps_no_policy(settings: Any) -> bool:
    return False


@dataclass(frozen=True)
class Experiment:
    """What the runner needs to know about an experiment.

    Every function takes the run's typed settings (an instance of ``settings``).

    Attributes:
        name: the store's experiment name.
        settings: the type of its runs' settings (:class:`Settings`).
        run: computes one run's metrics from its settings and seed sequence.
        warm_up: compiles the kernels once in the parent before workers fork.
        cost: the estimated seconds of one run of a config on one core (rough, fitted to
            measured runs, benchmarks/fit_costs.py; a run that reports progress says what
            each unit costs, :func:`cmarlcd.progress.unit_cost`, so that its reports add
            up to this): expensive batches start first, and a sweep of several
            experiments weighs their progress by it for one overall ETA.
        run_batch: optional; computes several runs of one settings together (e.g. seeds
            stacked in one model). It must give each run the metrics ``run`` would.
        batchable: whether runs of a config may share one ``run_batch`` call.
        work: the progress units (e.g. episodes) one run of a config reports with
            :func:`cmarlcd.progress.report_progress`, or None when it reports none (the
            runner then counts the run itself as one unit).
        work_unit: what ``work`` counts, for progress displays.
        uses_device: whether a run of a config trains a deep learner, which computes on
            the sweep's device (:mod:`cmarlcd.devices`); such a run records the device in
            its metrics, and on Ray its task asks for a share of a GPU (``1 / gpu_tasks``)
            when the device is one.
        keeps_policies: whether a run of a config can hand its final greedy policy back
            (:mod:`cmarlcd.policies`; ``--save-policies``).
    """

    name: str
    settings: type[Settings]
    run: RunFunction
    warm_up: Callable[[], None] = _nothing
    cost: Callable[[Any], float] = _unit_cost
    run_batch: BatchFunction | None = None
    batchable: Callable[[Any], bool] = _not_batchable
    work: Callable[[Any], float | None] = _no_work_reported
    work_unit: str = "runs"
    uses_device: Callable[[Any], bool] = _no_device
    keeps_policies: Callable[[Any], bool] = _keeps_no_policy

    def settings_of(self, config_json: str) -> Any:
        """The typed settings of a run of this experiment, from its stored config."""
        return parse_settings(self.settings, config_json)


def run_name(
    experiment: str, algorithm: str, config_json: str, root_seed: int, run_index: int
) -> str:
    """A run's identity as a file name (:attr:`RunSpec.name`)."""
    digest = hashlib.sha256(config_json.encode()).hexdigest()[:8]
    return f"{experiment}-{algorithm}-seed{root_seed}-run{run_index}-{digest}"


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
    keep_policy: bool = field(default=False, compare=False)
    """Whether the run hands its final greedy policy back to be kept (``--save-policies``;
    not part of its identity)."""
    log_dir: str | None = field(default=None, compare=False)
    """Where the run writes its live curves as it computes (``--log-dir``, in a folder of
    its :attr:`name`; :mod:`cmarlcd.run_logs`), or None; not part of its identity."""

    @classmethod
    def make(
        cls, experiment: str, algorithm: str, settings: Settings, root_seed: int, index: int
    ) -> RunSpec:
        """Run ``index`` of ``settings``, seeded by their :meth:`Settings.stream`."""
        config_json = canonical_json(settings.to_config())
        stream = settings.stream()
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

    @property
    def name(self) -> str:
        """``train-vdn-seed0-run2-1a2b3c4d``: the run's identity as a file name, its
        config's digest last (a kept policy's, a live log's folder)."""
        return run_name(self.experiment, self.algorithm, self.config_json, self.root_seed,
                        self.run_index)  # fmt: skip

    def seed_sequence(self) -> np.random.SeedSequence:
        """The run's root of randomness: (root seed; digest of experiment+stream, index)."""
        stream = self.stream_json or self.config_json
        digest = hashlib.sha256(f"{self.experiment}\n{stream}".encode()).digest()
        words = [int.from_bytes(digest[i : i + 4], "little") for i in range(0, 16, 4)]
        return np.random.SeedSequence(self.root_seed, spawn_key=(*words, self.run_index))
