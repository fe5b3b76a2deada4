"""The paper's experimental protocols, and the registry the runner finds them in.

* :mod:`~.repeated` -- Section IV-C, Tables 1-2;
* :mod:`~.episodic` -- learn then evaluate greedily, for any one-team game;
* :mod:`~.sensor_network` -- Section V-A on the DSN, Tables 3-7 and Fig. 4;
* :mod:`~.tournament` -- Section V-B, the blood battlefield tournament, Figs. 6-7;
* :mod:`~.theorem` -- Section IV-B, the numerical check of Theorem 1;
* :mod:`~.compare` -- beyond the paper: CMARL-CD against the classic independent learners;
* :mod:`~.scaling` -- beyond the paper: learners against the size of the sensor network;
* :mod:`~.environment` -- beyond the paper: any learner on any PettingZoo ``ParallelEnv``;
* :mod:`~.games` -- beyond the paper: any learner on Level-Based Foraging or MPE's
  simple_spread, compiled.
"""

from __future__ import annotations

from typing import Any

from cmarlcd.experiments import (
    compare,
    environment,
    games,
    repeated,
    scaling,
    sensor_network,
    theorem,
    tournament,
)
from cmarlcd.plugins import note
from cmarlcd.runs import Experiment, RunRecord, RunSpec

_REGISTRY: dict[str, Experiment] = {}


def register(experiment: Experiment) -> Experiment:
    """Make ``experiment`` runnable by name. Called at the top level of a module, it
    registers it in the sweep's worker processes too, which import that module
    (:mod:`cmarlcd.plugins`)."""
    _REGISTRY[experiment.name] = experiment
    note("experiment", experiment.name)
    return experiment


def get_experiment(name: str) -> Experiment:
    """The registered experiment ``name``."""
    return _REGISTRY[name]


def settings_of(run: RunSpec | RunRecord) -> Any:
    """The typed settings of a run to compute or a stored run (each experiment's
    :class:`~cmarlcd.runs.Settings`)."""
    key = run.key
    return get_experiment(key.experiment).settings_of(key.config)


for _experiment in (
    repeated.REPEATED,
    sensor_network.DSN,
    tournament.TOURNAMENT,
    theorem.THEOREM1,
    compare.COMPARE,
    scaling.SCALING,
    environment.TRAIN,
    *(family.experiment for family in games.FAMILIES.values()),
):
    register(_experiment)

__all__ = [
    "compare",
    "environment",
    "games",
    "get_experiment",
    "register",
    "repeated",
    "scaling",
    "sensor_network",
    "settings_of",
    "theorem",
    "tournament",
]
