"""A learner's fixed greedy strategy at one moment of its learning, as the evaluation of a
one-team game plays it.

Where the learner's strategy is a table over the game's states (the tabular learners,
and a deep learner reading one-hot state indices), the table is taken and played by a
fixed policy side (:func:`cmarlcd.training.tabular.evaluate`), so it can also be stored
(Fig. 4). Where a deep learner reads state features, a table of every state would grow
with the state count: its own side plays its greedy kernel instead, on a game of its own
(:meth:`cmarlcd.training.loop.Play.evaluate`), between two of its learning turns.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cmarlcd.games.spec import GameSpec
from cmarlcd.training.loop import Play
from cmarlcd.training.tabular import EpisodeStats, evaluate


@dataclass(frozen=True)
class GreedyPolicy:
    """A fixed greedy joint strategy on ``spec``: a ``table`` of every state's joint
    action, ``(n_states, n_agents)``, or else the ``play`` whose side plays it."""

    spec: GameSpec
    table: np.ndarray | None = None
    play: Play | None = None

    def __post_init__(self) -> None:
        if (self.table is None) == (self.play is None):
            raise ValueError("a greedy policy is a table or a play, one of the two")

    def evaluate(self, episodes: int, rng: np.random.Generator) -> EpisodeStats:
        """``episodes`` greedy episodes, the game's randomness drawn from ``rng``."""
        if self.table is not None:
            return evaluate(self.spec, self.table, episodes, rng)
        assert self.play is not None
        outcome = self.play.evaluate(episodes, rng)
        return EpisodeStats(outcome.returns[:, 0].copy(), outcome.lengths, outcome.terminated)
