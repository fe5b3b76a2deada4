"""Every learner and game by name, in one place (the command line and the experiments
look them up here). Adding a learner is one file plus one entry below; adding a game is
one package plus one entry.

A learner is registered once (:class:`Learner`): its name, its kind (tabular or deep),
its form for stochastic games and its form for repeated games (each a frozen config of
its paper's settings, or None where it has none), and its settings on games where they
differ (``presets``: the battlefield's, Section V-B). A config names its learner and
carries its compiled functions (or, for the deep learners, its network settings); any
other setting is ``dataclasses.replace(default, ...)``.

A game is registered once too (:class:`Game`): its name and, for each way the project
plays it, how to make it: ``spec`` (a stochastic game of the compiled protocol, played by
the training loop) and ``make`` (a repeated game of one run of ``cmarl-cd compare``,
fixed or drawn at random at one of its ``sizes``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field, fields, replace
from itertools import product
from typing import Any

import numpy as np

from cmarlcd.errors import require
from cmarlcd.games import battlefield, sensor_network
from cmarlcd.games.matrix import MatrixGame, climbing_game, penalty_game, random_game
from cmarlcd.games.matrix.stochastic import (
    StochasticMatrixGame,
    fully_stochastic_climbing_game,
    partially_stochastic_climbing_game,
)
from cmarlcd.games.spec import GameSpec
from cmarlcd.learners.deep.config import BATTLEFIELD_DEEP, DeepConfig, DeepLearnerConfig
from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig
from cmarlcd.learners.deep.designs import BATTLEFIELD_DEEP_CMARLCD, REPEATED_DEEP_CMARLCD
from cmarlcd.learners.tabular.automata import AutomatonConfig
from cmarlcd.learners.tabular.coordination import (
    BATTLEFIELD_CMARLCD,
    RepeatedConfig,
    StochasticConfig,
)
from cmarlcd.learners.tabular.distributed_q import DistributedQConfig, DistributedQStochasticConfig
from cmarlcd.learners.tabular.fmq import FMQConfig
from cmarlcd.learners.tabular.hysteretic import HystereticConfig, HystereticStochasticConfig
from cmarlcd.learners.tabular.joint_action import CentralQConfig, JointActionConfig
from cmarlcd.learners.tabular.lenient import LenientConfig, LenientStochasticConfig
from cmarlcd.learners.tabular.protocol import TabularConfig
from cmarlcd.learners.tabular.q_learning import IQLConfig, IQLStochasticConfig
from cmarlcd.paper import TABLE_ACTIONS, TABLE_AGENTS
from cmarlcd.plugins import note
from cmarlcd.runs import as_stored

LearnerConfig = TabularConfig | DeepConfig | DeepCMARLCDConfig

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
#: The preset of a deep learner on one-step (repeated) games: it plays ``compare`` there.
ONE_STEP = "one-step"


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


def _deep(mixer: str, battlefield: bool = True) -> Learner:
    """A learner of :class:`DeepConfig` (with the battlefield's settings where it plays
    the paper's tournament)."""
    config = DeepConfig(mixer=mixer)
    presets = {BATTLEFIELD: DeepConfig(mixer=mixer, **BATTLEFIELD_DEEP)} if battlefield else {}
    return Learner(config.name, DEEP, config, None, presets)


#: Every learner, in the order tables list them: the paper's four, then the classic
#: coordination learners (with their papers' settings).
REGISTRY: dict[str, Learner] = {
    learner.name: learner
    for learner in (
        _tabular(StochasticConfig(), RepeatedConfig(), battlefield=BATTLEFIELD_CMARLCD),
        _tabular(AutomatonConfig(), battlefield=AutomatonConfig()),
        _deep("vdn"),
        _deep("qmix"),
        Learner(
            DeepCMARLCDConfig.name,
            DEEP,
            DeepCMARLCDConfig(),
            None,
            {BATTLEFIELD: BATTLEFIELD_DEEP_CMARLCD, ONE_STEP: REPEATED_DEEP_CMARLCD},
        ),
        _tabular(IQLStochasticConfig(), IQLConfig()),
        _tabular(DistributedQStochasticConfig(), DistributedQConfig()),
        _tabular(HystereticStochasticConfig(), HystereticConfig()),
        _tabular(repeated=FMQConfig()),
        _tabular(LenientStochasticConfig(), LenientConfig()),
        _tabular(repeated=JointActionConfig()),
        _tabular(repeated=CentralQConfig()),
        # the deep forms of independent learning (beyond the paper: not in its tournament)
        _deep("independent", battlefield=False),
        _deep("hysteretic", battlefield=False),
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


RepeatedGame = MatrixGame | StochasticMatrixGame
Size = tuple[int, int]


@dataclass(frozen=True)
class Game:
    """One game: its name, what it is, and how each way of playing it makes it.

    Attributes:
        name: its name on the command line and in the store.
        title: what it is, in words (figures, JSON).
        short: its column header in tables.
        spec: the game as a stochastic game of the compiled protocol (None when the
            project plays it only as a repeated game).
        make: the repeated game of one run of ``compare``, from its size (None for a
            fixed game) and a generator (None when it is not a column of the comparison).
        sizes: the (agents, actions) of its random games; empty for a fixed game.
    """

    name: str
    title: str
    short: str
    spec: Callable[[], GameSpec] | None = None
    make: Callable[[Size | None, np.random.Generator], RepeatedGame] | None = None
    sizes: tuple[Size, ...] = ()

    def joint_actions(self, size: Size | None) -> int:
        """Joint actions of its repeated game (at ``size`` for a random one)."""
        if size is None:
            assert self.make is not None
            return math.prod(self.make(None, np.random.default_rng(0)).action_counts)
        agents, actions = size
        return actions**agents


def _fixed(name: str, title: str, short: str, make: Callable[[], RepeatedGame], spec=None) -> Game:
    return Game(name, title, short, spec, lambda size, rng: make())


def _penalty(k: int) -> Game:
    name = f"penalty{k}" if k else "penalty-0"
    return _fixed(name, f"penalty k={k}", f"k={k}", lambda: penalty_game(k))


def _random(case: int) -> Game:
    sizes = tuple(product(TABLE_AGENTS[case], TABLE_ACTIONS[case]))

    def make(size: Size | None, rng: np.random.Generator) -> RepeatedGame:
        assert size is not None, "a random game is drawn at a size"
        return random_game(case, *size, rng)

    return Game(
        f"case{case}", f"case {case} (Table {case} sizes)", f"case{case}", None, make, sizes
    )


#: Every game by name: the stochastic games first, then the comparison's columns in
#: their order.
GAMES: dict[str, Game] = {
    game.name: game
    for game in (
        Game("dsn", "distributed sensor network", "DSN", lambda: sensor_network.SPEC),
        Game("battlefield", "blood battlefield", "battlefield", lambda: battlefield.SPEC),
        Game("penalty", "penalty k=-10", "penalty", lambda: penalty_game().spec()),
        _fixed("climbing", "climbing", "climb", climbing_game, lambda: climbing_game().spec()),
        *(_penalty(k) for k in (0, -10, -50, -100)),
        _fixed(
            "climbing-ps",
            "climbing, partially stochastic",
            "PS",
            partially_stochastic_climbing_game,
        ),
        _fixed("climbing-fs", "climbing, fully stochastic", "FS", fully_stochastic_climbing_game),
        _random(1),
        _random(2),
    )
}


def register_learner(learner: Learner) -> Learner:
    """Make ``learner`` known by name (the command line, the experiments, the reports),
    in its stochastic-game and repeated-game forms. Called at the top level of a module,
    it registers the learner in the sweep's worker processes too (:mod:`cmarlcd.plugins`)."""
    REGISTRY[learner.name] = learner
    for forms, form in ((LEARNERS, learner.stochastic), (REPEATED_LEARNERS, learner.repeated)):
        if form is not None:
            forms[learner.name] = form
        else:
            forms.pop(learner.name, None)
    note("learner", learner.name)
    return learner


def register_game(game: Game) -> Game:
    """Make ``game`` known by name. Called at the top level of a module, it registers the
    game in the sweep's worker processes too (:mod:`cmarlcd.plugins`)."""
    GAMES[game.name] = game
    note("game", game.name)
    return game


def stochastic_games() -> dict[str, Callable[[], GameSpec]]:
    """The games played as stochastic games, by name: each a function making its spec."""
    return {name: game.spec for name, game in GAMES.items() if game.spec is not None}


def repeated_games() -> dict[str, Game]:
    """The games ``compare`` plays as repeated games, in column order."""
    return {name: game for name, game in GAMES.items() if game.make is not None}


def learner_names() -> str:
    return ", ".join(LEARNERS)


def require_learner(name: str, parameter: str = "algorithms") -> LearnerConfig:
    """The default config of learner ``name``, or a one-line error listing the known ones."""
    require(name in LEARNERS, parameter, f"unknown {name!r}; available: {learner_names()}")
    return LEARNERS[name]


def learner_config(name: str, settings: Mapping[str, Any]) -> LearnerConfig:
    """Learner ``name`` with ``settings`` (a stored config's learner fields; the
    settings added since it was stored at their value from before, the others at the
    learner's defaults)."""
    default = require_learner(name)
    return replace(default, **as_stored(type(default), settings))


def is_paper_setting(config: LearnerConfig) -> bool:
    """True when ``config`` holds the paper's settings of its learner."""
    default = LEARNERS.get(config.name)
    return default is not None and asdict(default) == asdict(config)


def reference_settings(config: Any) -> Any | None:
    """What a learner config's settings are told apart from: the learner's settings in
    the tables (its DSN settings, or its paper's settings on repeated games), else its
    class's defaults."""
    for known in (LEARNERS, REPEATED_LEARNERS):
        candidate = known.get(config.name)
        if type(candidate) is type(config):
            return candidate
    try:
        return type(config)()
    except TypeError:
        return None


def changed_settings(
    config: Any, reference: Any | None = None, ignore: tuple[str, ...] = ()
) -> dict[str, Any]:
    """The settings of ``config`` that differ from ``reference`` (default:
    :func:`reference_settings`), as ``--set`` writes them (nested ones dotted), leaving
    out ``ignore``; everything when there is nothing to compare with."""
    reference = reference_settings(config) if reference is None else reference
    ours = _flat(asdict(config))
    theirs = _flat(asdict(reference)) if type(reference) is type(config) else {}
    return {k: v for k, v in ours.items() if k not in ignore and theirs.get(k, _NONE) != v}


def variant_label(config: Any, reference: Any | None = None, ignore: tuple[str, ...] = ()) -> str:
    """How tables and figures name a learner with its settings: ``"CMARL-CD"`` for the
    reference settings, ``"CMARL-CD (delta=0.08)"`` where they differ, so that runs of
    two settings never share a row (fields as :func:`changed_settings` finds them)."""
    changed = changed_settings(config, reference, ignore)
    words = ", ".join(f"{k}={_setting_text(v)}" for k, v in sorted(changed.items()))
    return display_name(config.name) + (f" ({words})" if words else "")


_NONE = object()  # a setting the reference does not have


def _flat(values: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    flat: dict[str, Any] = {}
    for key, value in values.items():
        if isinstance(value, Mapping):
            flat.update(_flat(value, f"{prefix}{key}."))
        else:
            flat[f"{prefix}{key}"] = tuple(value) if isinstance(value, list) else value
    return flat


def _setting_text(value: Any) -> str:
    if isinstance(value, tuple):
        return "x".join(map(_setting_text, value))
    return repr(value) if isinstance(value, str) else str(value)


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
    return DEEP if isinstance(config, DeepLearnerConfig) else TABULAR


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


def comparable_learners() -> dict[str, Any]:
    """The learners ``compare`` plays, by name: the repeated-game learners, then the deep
    learners with settings of their own on one-step games."""
    return {**REPEATED_LEARNERS, **learners_on(ONE_STEP)}


def comparable_learner(name: str, settings: Mapping[str, Any] | None = None) -> Any:
    """Learner ``name`` as ``compare`` plays it, with those of ``settings`` that are its
    fields, or a one-line error listing the known ones."""
    known = comparable_learners()
    require(name in known, "learners", f"unknown {name!r}; available: {', '.join(known)}")
    default = known[name]
    if settings is None:
        return default
    own = {f.name for f in fields(default)}
    stored = {k: v for k, v in settings.items() if k in own}
    return replace(default, **as_stored(type(default), stored))
