"""Every learner and game by name, in one place (the command line and the experiments
look them up here). Adding a learner is one file plus one line below; adding a game is
one package plus one line.

Learners are registered by their default config (the paper's DSN settings): the config
names its learner and carries its compiled functions (or, for the deep learners, its
network settings), and any other setting is ``dataclasses.replace(default, ...)``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import asdict, fields, replace
from typing import Any

from cmarlcd.errors import require
from cmarlcd.games import battlefield, sensor_network
from cmarlcd.games.matrix import climbing_game, penalty_game
from cmarlcd.games.spec import GameSpec
from cmarlcd.learners.automata import AutomatonConfig
from cmarlcd.learners.coordination import RepeatedConfig, StochasticConfig
from cmarlcd.learners.deep_config import DeepConfig
from cmarlcd.learners.distributed_q import DistributedQConfig, DistributedQStochasticConfig
from cmarlcd.learners.fmq import FMQConfig
from cmarlcd.learners.hysteretic import HystereticConfig, HystereticStochasticConfig
from cmarlcd.learners.joint_action import CentralQConfig, JointActionConfig
from cmarlcd.learners.lenient import LenientConfig, LenientStochasticConfig
from cmarlcd.learners.q_learning import IQLConfig, IQLStochasticConfig
from cmarlcd.learners.tabular import TabularConfig

LearnerConfig = TabularConfig | DeepConfig

#: Learners for stochastic games, by name: the paper's (with its DSN settings) and the
#: classic independent learners (with their papers' settings).
LEARNERS: dict[str, LearnerConfig] = {
    config.name: config
    for config in (
        StochasticConfig(),
        AutomatonConfig(),
        DeepConfig(mixer="vdn"),
        DeepConfig(mixer="qmix"),
        IQLStochasticConfig(),
        DistributedQStochasticConfig(),
        HystereticStochasticConfig(),
        LenientStochasticConfig(),
    )
}

#: The learners of the paper's DSN tables (the others are compared beyond the paper).
PAPER_LEARNERS = ("cmarl-cd", "la-oca", "vdn", "qmix")

RepeatedLearnerConfig = (
    RepeatedConfig
    | IQLConfig
    | DistributedQConfig
    | HystereticConfig
    | FMQConfig
    | LenientConfig
    | JointActionConfig
    | CentralQConfig
)

#: Learners for repeated games, by name, with their papers' settings: CMARL-CD
#: (Algorithm 1) and the classic learners it is compared with (``cmarl-cd compare``).
REPEATED_LEARNERS: dict[str, RepeatedLearnerConfig] = {
    config.name: config
    for config in (
        RepeatedConfig(),
        IQLConfig(),
        DistributedQConfig(),
        HystereticConfig(),
        FMQConfig(),
        LenientConfig(),
        JointActionConfig(),
        CentralQConfig(),
    )
}

#: Games by name: each a function returning its spec.
GAMES: dict[str, Callable[[], GameSpec]] = {
    "dsn": lambda: sensor_network.SPEC,
    "climbing": lambda: climbing_game().spec(),
    "penalty": lambda: penalty_game().spec(),
    "battlefield": lambda: battlefield.SPEC,
}


def learner_names() -> str:
    return ", ".join(LEARNERS)


def require_learner(name: str, parameter: str = "algorithms") -> LearnerConfig:
    """The default config of learner ``name``, or a one-line error listing the known ones."""
    require(name in LEARNERS, parameter, f"unknown {name!r}; available: {learner_names()}")
    return LEARNERS[name]


def learner_config(name: str, settings: Mapping[str, Any]) -> LearnerConfig:
    """Learner ``name`` with ``settings`` (a stored config's learner fields; the
    others keep the learner's defaults)."""
    return replace(require_learner(name), **settings)


def is_paper_setting(config: LearnerConfig) -> bool:
    """True when ``config`` holds the paper's settings of its learner."""
    default = LEARNERS.get(config.name)
    return default is not None and asdict(default) == asdict(config)


def display_name(name: str) -> str:
    """A learner's name in tables and figures (``"cmarl-cd"`` -> ``"CMARL-CD"``)."""
    config = LEARNERS.get(name)
    return config.display_name if config is not None else name.upper()


def needs_torch(name: str) -> bool:
    """Whether learner ``name`` needs the ``[deep]`` extra (PyTorch)."""
    return isinstance(LEARNERS.get(name), DeepConfig)


def repeated_learner_names() -> str:
    return ", ".join(REPEATED_LEARNERS)


def repeated_learner(name: str, settings: Mapping[str, Any] | None = None) -> RepeatedLearnerConfig:
    """Repeated-game learner ``name`` with those of ``settings`` that are its fields (the
    others keep its defaults), or a one-line error listing the known ones."""
    require(
        name in REPEATED_LEARNERS,
        "learners",
        f"unknown {name!r}; available: {repeated_learner_names()}",
    )
    default = REPEATED_LEARNERS[name]
    own = {f.name for f in fields(default)}
    return replace(default, **{k: v for k, v in (settings or {}).items() if k in own})
