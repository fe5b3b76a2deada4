"""A tabular learner on a cooperative game of one team: learning, and greedy evaluation.

Both go through the one loop of :mod:`cmarlcd.training.loop`, with the learner as the
game's only side (:class:`cmarlcd.training.tabular_side.TabularSide`) while learning,
and its greedy policy, taken at a checkpoint, as a fixed policy
(:class:`cmarlcd.training.policy_side.PolicySide`) while evaluating. With the same seeds
they consume the random streams exactly as the generic ``ParallelEnv`` loop of
:mod:`cmarlcd.training.episodes` does (the environment's generator for starts and
transitions, the learner's for actions), so both learn the same tables.

A state's legal-action masks are read from the game on its first visit and handed to the
learner's ``init_state``; a game's masks must therefore depend on the state index alone.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cmarlcd.games.spec import GameSpec
from cmarlcd.learners.tabular.protocol import TabularConfig
from cmarlcd.training.loop import Play
from cmarlcd.training.policy_side import PolicySide, UniformSide
from cmarlcd.training.tabular_side import TabularSide


@dataclass(frozen=True)
class EpisodeStats:
    """Undiscounted return and length of each episode played, and whether it terminated
    (rather than reaching the step cap)."""

    returns: np.ndarray
    lengths: np.ndarray
    terminated: np.ndarray


def evaluate(spec: GameSpec, policy: np.ndarray, episodes: int, rng) -> EpisodeStats:
    """Play ``episodes`` episodes of ``spec`` with the fixed greedy ``policy`` (one joint
    action per state index), the game's randomness drawn from ``rng``."""
    spec.require_one_team("evaluate")
    outcome = Play(spec, [PolicySide(spec, 0, policy)], rng, [rng]).evaluate(episodes, rng)
    return EpisodeStats(outcome.returns[:, 0].copy(), outcome.lengths, outcome.terminated)


def evaluate_uniform(spec: GameSpec, episodes: int, rng) -> EpisodeStats:
    """Play ``episodes`` episodes of ``spec`` with every agent's uniform legal action (the
    random policy, the floor of a learning curve), all drawn from ``rng``."""
    spec.require_one_team("evaluate")
    outcome = Play(spec, [UniformSide(spec, 0)], rng, [rng]).evaluate(episodes, rng)
    return EpisodeStats(outcome.returns[:, 0].copy(), outcome.lengths, outcome.terminated)


class TabularRun:
    """One tabular learner training on one game: its tables, first visits and streams.

    ``train`` continues where the last call stopped, so a run can stop at checkpoints to
    evaluate its greedy policy and go on with the same streams.
    """

    def __init__(
        self,
        spec: GameSpec,
        config: TabularConfig,
        env_rng: np.random.Generator,
        agent_rng: np.random.Generator,
    ) -> None:
        spec.require_one_team("TabularRun")
        self.spec, self.config = spec, config
        self.side = TabularSide(spec, 0, config)
        self.play = Play(spec, [self.side], env_rng, [agent_rng])

    @property
    def tables(self) -> tuple:
        """The learner's tables, one row per state index."""
        return self.side.state_tables()

    @property
    def counts(self) -> np.ndarray:
        return self.side.data.counts

    @property
    def seen(self) -> np.ndarray:
        """``seen[s]``: the learner has visited state ``s``."""
        return self.side.seen

    def train(self, episodes: int) -> int:
        """Learn for ``episodes`` more episodes; returns the environment steps taken."""
        before = self.play.turns
        self.play.learn_until(self.play.episodes + int(episodes))
        return self.play.turns - before

    @property
    def turns(self) -> int:
        """Environment steps learnt so far."""
        return self.play.turns

    def train_until_steps(self, steps: int) -> int:
        """Learn until ``steps`` environment steps in all, to the end of the episode in
        play; returns the episodes taken."""
        before = self.play.episodes
        self.play.learn_turns_until(int(steps))
        return self.play.episodes - before

    def greedy_policy(self) -> np.ndarray:
        """The greedy joint action of every state index: (n_states, n_agents)."""
        return self.side.greedy_policy()
