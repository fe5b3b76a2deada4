"""Games of the compiled protocol under the learn-then-evaluate protocol (beyond the
paper): ``cmarl-cd train --game NAME:TASK``.

A *game family* turns the text after ``NAME:`` into the rules of one task, whose spec the
compiled loops play: Level-Based Foraging (``foraging:8x8-2p-2f-coop``,
:mod:`cmarlcd.games.foraging`) and MPE's simple_spread (``simple_spread:N=5``,
:mod:`cmarlcd.games.spread`). Each family is one experiment of the store (its name), run
under the protocol of :mod:`cmarlcd.experiments.episodic`: each learner trained for a
budget of episodes or environment steps, its greedy policy evaluated at evenly spaced
points of its learning (the curve) and at the end. A run's options name its task
(``task``, the task's full name), so runs of two tasks never share a key. An evaluation
episode *succeeds* when it terminates before the step cap (on LBF: every food
collected; simple_spread never terminates).

The deep learners read every agent's observation joined (the game's features); a
tabular learner plays only a task whose table of every state's joint action, which the
protocol evaluates, holds at most :data:`~cmarlcd.experiments.episodic.MAX_POLICY_ENTRIES`
entries (about the 1-food LBF tasks of grids up to 8x8 with 2 agents; no simple_spread
task, whose state is continuous).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from cmarlcd.errors import ConfigError, require
from cmarlcd.experiments.episodic import (
    MAX_POLICY_ENTRIES,
    EpisodicGame,
    EpisodicSweep,
    Options,
    experiment,
    is_deep,
    terminated_episodes,
)
from cmarlcd.games.foraging import Foraging
from cmarlcd.games.observations import own_observations
from cmarlcd.games.spread import SimpleSpread
from cmarlcd.games.time_left import with_time_left
from cmarlcd.learners.deep.config import OWN_OBSERVATION_LEARNERS
from cmarlcd.registry import LearnerConfig
from cmarlcd.runs import Experiment
from cmarlcd.training.tabular import EpisodeStats, evaluate_uniform

#: [choice] Episodes of the uniform random policy a report's floor is read from, at least
#: (more where the learners' evaluation has more): its return is noisy (a standard
#: deviation of about 0.5 an episode on the small LBF tasks), and it costs milliseconds.
FLOOR_EPISODES = 10_000


@dataclass(frozen=True)
class GameFamily:
    """The tasks of one compiled game, as ``--game NAME:TASK`` names them.

    Attributes:
        name: the name before ``:``, and the store's experiment of its runs.
        parse: the rules of the task the text after ``:`` names (they have ``.name``,
            the task's full name, and ``.spec()``).
        warm_up: [choice] the task the family's kernels are compiled on before a sweep
            (every task shares them).
        tabular_fits: whether a tabular learner can play a task's rules.
        example: a task, for messages.
        success: what an episode that terminates has done, for reports (None: the game
            never terminates, and reports show no success).
    """

    name: str
    parse: Callable[[str], Any]
    warm_up: Any
    tabular_fits: Callable[[Any], bool]
    example: str
    success: str | None = None

    @functools.cached_property
    def game(self) -> EpisodicGame:
        """The family as one game of the protocol (its warm-up task), whose options pick
        a task."""
        return EpisodicGame(
            experiment=self.name,
            spec=self.warm_up.spec(),
            success=terminated_episodes,
            policy_states=0,
            variant=_task_game,
        )

    @functools.cached_property
    def experiment(self) -> Experiment:
        return experiment(self.game)

    def rules_of(self, options: Options) -> Any:
        """The rules of the task ``options`` name."""
        given = dict(options)
        unknown = sorted(set(given) - {"task", "inputs", "time_left"})
        require(not unknown, unknown[0] if unknown else "game", f"is no option of {self.name}")
        return self.parse(str(given.get("task", self.warm_up.name)))

    @staticmethod
    def options(rules: Any, inputs: str = "observations", time_left: bool = False) -> Options:
        """The options of a task's runs: its full name, always, what the learners read
        where it is not every observation joined, and the time left where they read it
        (so the runs of before either option keep their keys in a store)."""
        require(inputs in GAME_INPUTS, "inputs", f"must be one of {', '.join(GAME_INPUTS)}")
        return (
            (("inputs", inputs),) * (inputs != GAME_INPUTS[0])
            + (("task", rules.name),)
            + (("time_left", "true"),) * time_left
        )

    def spec_of(self, options: Options) -> Any:
        """The game the options name: the task's, each agent's observation followed by
        the time left where ``time_left`` says so, and laid out for each agent's own
        network where ``inputs`` says so."""
        rules, given = self.rules_of(options), dict(options)
        spec, width = rules.spec(), rules.observation_size
        if reads_time_left(options):
            spec, width = with_time_left(spec, width), width + 1
        if given.get("inputs", GAME_INPUTS[0]) == "own-observations":
            return own_observations(spec, width)
        return spec


def reads_time_left(options: Options) -> bool:
    """Whether a task's runs read the time left after each agent's observation
    (:meth:`GameFamily.options` with ``time_left``)."""
    return dict(options).get("time_left") == "true"


#: [choice] What the deep learners read of a compiled game: every agent's observation
#: joined (``observations``, the default), or ``own-observations``: VDN's and QMIX's
#: agents each their own, QMIX's mixer the joined ones (decentralised execution, as
#: EPyMARL and BenchMARL run them; :func:`cmarlcd.games.observations.own_observations`).
GAME_INPUTS = ("observations", "own-observations")


@functools.lru_cache(maxsize=64)
def _task_game(game: EpisodicGame, options: Options) -> EpisodicGame:
    spec = FAMILIES[game.experiment].spec_of(options)
    return EpisodicGame(game.experiment, spec, terminated_episodes, 0)


def foraging_tabular_fits(rules: Foraging) -> bool:
    """Whether a tabular learner can play an LBF task (see the module docstring)."""
    return rules.indexed and rules.n_states * rules.players <= MAX_POLICY_ENTRIES


FORAGING = GameFamily(
    "foraging",
    Foraging.from_name,
    Foraging(size=5, players=2, foods=1),
    foraging_tabular_fits,
    "foraging:8x8-2p-2f-coop",
    "all food",
)
SIMPLE_SPREAD = GameFamily(
    "simple_spread",
    SimpleSpread.from_name,
    SimpleSpread(),
    lambda rules: False,
    "simple_spread:N=3",
)
#: The families ``--game`` plays, by name.
FAMILIES = {family.name: family for family in (FORAGING, SIMPLE_SPREAD)}


def parse_game(text: str) -> tuple[GameFamily, Any]:
    """``foraging:8x8-2p-2f-coop,penalty=0.1`` -> (the family, that task's rules);
    ``simple_spread`` alone is mpe2's default task."""
    name, sep, task = text.partition(":")
    family = FAMILIES.get(name.strip())
    if family is None:
        raise ConfigError(
            "game",
            f"unknown game {name.strip()!r} (games: {', '.join(FAMILIES)}; e.g. "
            f"{FORAGING.example} or {SIMPLE_SPREAD.example})",
        )
    if family is FORAGING:
        require(
            bool(sep and task.strip()), "game", f"foraging: name the task after ':' (got {text!r})"
        )
    return family, family.parse(task.strip())


@dataclass(frozen=True)
class GameSweep(EpisodicSweep):
    """Learners x runs on one task of a family (``game``: the family's, ``options``: its
    :meth:`GameFamily.options`)."""

    game: EpisodicGame = FORAGING.game
    learners: tuple[LearnerConfig, ...] = ()
    episodes: tuple[int, ...] = (10_000,)
    runs: int = 3
    eval_episodes: int = 100

    def __post_init__(self) -> None:
        super().__post_init__()
        family, rules = self.family, self.rules
        if dict(self.options).get("inputs") == "own-observations":
            others = [c.name for c in self.learners if c.name not in OWN_OBSERVATION_LEARNERS]
            require(
                not others,
                "inputs",
                f"own-observations is read by {', '.join(OWN_OBSERVATION_LEARNERS)} only "
                f"(not {', '.join(others)})",
            )
        tabular = [c.name for c in self.learners if not is_deep(c)]
        if tabular and not family.tabular_fits(rules):
            spec = rules.spec()
            why = (
                "has no state index"
                if spec.n_states == 1
                else f"has {spec.n_states:,} states x {spec.n_agents} agents, more than "
                f"{MAX_POLICY_ENTRIES:,} entries"
            )
            smaller = ", or a smaller task (e.g. 5x5-2p-1f)" if family is FORAGING else ""
            deep_iql = " (deep IQL is deep-iql; iql is the table)" if "iql" in tabular else ""
            raise ConfigError(
                "algorithms",
                f"{', '.join(tabular)}: tabular learners need a table of every state; "
                f"{family.name} {rules.name} {why}: choose deep learners{deep_iql}{smaller}",
            )

    @property
    def family(self) -> GameFamily:
        return FAMILIES[self.game.experiment]

    @property
    def rules(self) -> Any:
        return self.family.rules_of(self.options)


def uniform_floor(rules: Any, episodes: int, seed: int) -> EpisodeStats:
    """``episodes`` episodes of the uniform random policy on a task: the floor of a
    learning curve (compiled, millions of steps a second; drawn from ``seed`` alone)."""
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(0x10BF,)))
    return evaluate_uniform(rules.spec(), episodes, rng)
