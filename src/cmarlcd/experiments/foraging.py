"""Level-Based Foraging under the learn-then-evaluate protocol (beyond the paper):
``cmarl-cd train --game foraging:TASK``.

Any task of :class:`~cmarlcd.games.foraging.Foraging` under the protocol of
:mod:`cmarlcd.experiments.episodic`: each learner trained for L episodes, its greedy
policy evaluated at evenly spaced points of its learning (the curve) and at the end. An
evaluation episode *succeeds* when it collects every food (it terminates before the step
cap; the return is then 1 less the penalties). A run's options name its task
(``task``, the task's full name), so runs of two tasks never share a key.

The deep learners read every agent's observation joined (the game's features); a tabular
learner plays only a task whose table of every state's joint action, which the protocol
evaluates, holds at most :data:`~cmarlcd.experiments.episodic.MAX_POLICY_ENTRIES`
entries (about the 1-food tasks of grids up to 8x8 with 2 agents).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

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
from cmarlcd.registry import LearnerConfig
from cmarlcd.training.tabular import EpisodeStats, evaluate_uniform

EXPERIMENT = "foraging"
#: [choice] Episodes of the uniform random policy a report's floor is read from, at least
#: (more where the learners' evaluation has more): its return is noisy (a standard
#: deviation of about 0.5 an episode on the small tasks), and it costs milliseconds.
FLOOR_EPISODES = 10_000
#: [choice] The task the experiment's kernels are compiled on before a sweep (every task
#: shares them; this one's state table is small enough for the tabular learners).
WARM_UP_TASK = Foraging(size=5, players=2, foods=1)


@functools.lru_cache(maxsize=64)
def task_game(game: EpisodicGame, options: Options) -> EpisodicGame:
    """The game of the task the options name (``task``)."""
    given = dict(options)
    unknown = sorted(set(given) - {"task"})
    require(not unknown, unknown[0] if unknown else "game", "is no option of foraging")
    rules = Foraging.from_name(str(given.get("task", WARM_UP_TASK.name)))
    return EpisodicGame(game.experiment, rules.spec(), terminated_episodes, 0)


FORAGING_GAME = EpisodicGame(
    experiment=EXPERIMENT,
    spec=WARM_UP_TASK.spec(),
    success=terminated_episodes,
    policy_states=0,
    variant=task_game,
)
FORAGING = experiment(FORAGING_GAME)


def task_options(rules: Foraging) -> Options:
    """The options of a task's runs: its name, always (even the warm-up task's)."""
    return (("task", rules.name),)


def tabular_fits(rules: Foraging) -> bool:
    """Whether a tabular learner can play ``rules`` (see the module docstring)."""
    return rules.indexed and rules.n_states * rules.players <= MAX_POLICY_ENTRIES


@dataclass(frozen=True)
class ForagingSweep(EpisodicSweep):
    """Learners x runs on one foraging task (``options``: :func:`task_options`)."""

    game: EpisodicGame = FORAGING_GAME
    learners: tuple[LearnerConfig, ...] = ()
    episodes: tuple[int, ...] = (10_000,)
    runs: int = 3
    eval_episodes: int = 100

    def __post_init__(self) -> None:
        super().__post_init__()
        rules = self.rules
        tabular = [c.name for c in self.learners if not is_deep(c)]
        if tabular and not tabular_fits(rules):
            raise ConfigError(
                "algorithms",
                f"{', '.join(tabular)} need a table of every state; foraging {rules.name} "
                f"has {rules.state_count:,} states x {rules.players} agents, more than "
                f"{MAX_POLICY_ENTRIES:,} entries: choose deep learners, or a smaller task "
                "(e.g. 5x5-2p-1f)",
            )

    @property
    def rules(self) -> Foraging:
        return Foraging.from_name(str(dict(self.options).get("task", WARM_UP_TASK.name)))


def uniform_floor(rules: Foraging, episodes: int, seed: int) -> EpisodeStats:
    """``episodes`` episodes of the uniform random policy on ``rules``: the floor of a
    learning curve (compiled, a few million steps a second; drawn from ``seed`` alone)."""
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(0x10BF,)))
    return evaluate_uniform(rules.spec(), episodes, rng)
