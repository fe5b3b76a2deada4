"""Every learner and game by name, in one place (the command line and the experiments
look them up here). Adding a learner is one file plus one entry below; adding a game is
one package plus one line.

A learner is registered once (:class:`Learner`): its name, its kind (tabular or deep),
its form for stochastic games and its form for repeated games (each a frozen config of
its paper's settings, or None where it has none), and its settings on games where they
differ (``presets``: the battlefield's, Section V-B). A config names its learner and
carries its compiled functions (or, for the deep learners, its network settings); any
other setting is ``dataclasses.replace(default, ...)``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any

from cmarlcd.errors import require
from cmarlcd.games import battlefield, sensor_network
from cmarlcd.games.matrix import climbing_game, penalty_game
from cmarlcd.games.spec import GameSpec
from cmarlcd.learners.automata import AutomatonConfig
from cmarlcd.learners.coordination import BATTLEFIELD_CMARLCD, RepeatedConfig, StochasticConfig
from cmarlcd.learners.deep_config import BATTLEFIELD_DEEP, DeepConfig
from cmarlcd.learners.distributed_q import DistributedQConfig, DistributedQStochasticConfig
from cmarlcd.learners.fmq import FMQConfig
from cmarlcd.learners.hysteretic import HystereticConfig, HystereticStochasticConfig
from cmarlcd.learners.joint_action import CentralQConfig, JointActionConfig
from cmarlcd.learners.lenient import LenientConfig, LenientStochasticConfig
from cmarlcd.learners.q_learning import IQLConfig, IQLStochasticConfig
from cmarlcd.learners.tabular import TabularConfig

LearnerConfig = TabularConfig | DeepConfig

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

#: The kinds of learner: a table per state (compiled kernels), or networks (``[deep]``).
TABULAR, DEEP = "tabular", "deep"
#: The game whose learners have settings of their own (Section V-B).
BATTLEFIELD = "battlefield"


@dataclass(frozen=True)
class Learner:
    """One learner: its name, its kind, and the forms it takes."""

    name: str
    kind: str
    stochastic: LearnerConfig | None = None
    """Its form for stochastic games (the DSN's settings for the paper's learners)."""
    repeated: RepeatedLearnerConfig | None = None
    """Its form for repeated games (``cmarl-cd repeated``, ``compare``)."""
    presets: Mapping[str, LearnerConfig] = field(default_factory=dict)
    """Its settings on a game, by game name, where it plays that game with settings of
    its own (the battlefield's)."""

    @property
    def display_name(self) -> str:
        config = self.stochastic if self.stochastic is not None else self.repeated
        return config.display_name if config is not None else self.name.upper()

    @property
    def needs_torch(self) -> bool:
        """Whether it needs the ``[deep]`` extra (PyTorch)."""
        return self.kind == DEEP


def _tabular(stochastic: Any = None, repeated: Any = None, **presets: Any) -> Learner:
    name = (stochastic or repeated).name
    return Learner(name, TABULAR, stochastic, repeated, presets)


def _deep(mixer: str) -> Learner:
    battle = DeepConfig(mixer=mixer, **BATTLEFIELD_DEEP)
    return Learner(mixer, DEEP, DeepConfig(mixer=mixer), None, {BATTLEFIELD: battle})


#: Every learner, in the order tables list them: the paper's four, then the classic
#: coordination learners (with their papers' settings).
REGISTRY: dict[str, Learner] = {
    learner.name: learner
    for learner in (
        _tabular(StochasticConfig(), RepeatedConfig(), battlefield=BATTLEFIELD_CMARLCD),
        _tabular(AutomatonConfig(), battlefield=AutomatonConfig()),
        _deep("vdn"),
        _deep("qmix"),
        _tabular(IQLStochasticConfig(), IQLConfig()),
        _tabular(DistributedQStochasticConfig(), DistributedQConfig()),
        _tabular(HystereticStochasticConfig(), HystereticConfig()),
        _tabular(repeated=FMQConfig()),
        _tabular(LenientStochasticConfig(), LenientConfig()),
        _tabular(repeated=JointActionConfig()),
        _tabular(repeated=CentralQConfig()),
    )
}

#: Learners for stochastic games, by name, with their DSN settings.
LEARNERS: dict[str, LearnerConfig] = {
    name: learner.stochastic for name, learner in REGISTRY.items() if learner.stochastic
}

#: Learners for repeated games, by name, with their papers' settings: CMARL-CD
#: (Algorithm 1) and the classic learners it is compared with (``cmarl-cd compare``).
REPEATED_LEARNERS: dict[str, RepeatedLearnerConfig] = {
    name: learner.repeated for name, learner in REGISTRY.items() if learner.repeated
}

#: The learners of the paper's DSN tables (the others are compared beyond the paper).
PAPER_LEARNERS = ("cmarl-cd", "la-oca", "vdn", "qmix")


def learners_on(game: str) -> dict[str, LearnerConfig]:
    """The learners with settings of their own on ``game``, with those settings."""
    return {
        name: learner.presets[game] for name, learner in REGISTRY.items() if game in learner.presets
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
    learner = REGISTRY.get(name)
    return learner.display_name if learner is not None else name.upper()


def needs_torch(name: str) -> bool:
    """Whether learner ``name`` needs the ``[deep]`` extra (PyTorch)."""
    learner = REGISTRY.get(name)
    return learner is not None and learner.needs_torch


def kind_of(config: Any) -> str:
    """A learner config's kind: :data:`TABULAR` or :data:`DEEP`."""
    return DEEP if isinstance(config, DeepConfig) else TABULAR


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
