"""Two teams, two learners: matches of any two-team game (learning, then greedy
evaluation), played by the one loop of :mod:`cmarlcd.training.loop`.

Each side of a match is driven by its own learner (any pairing, self-play included) from
its own side's state and its own reward. Both learn during the learning stage
(:meth:`Match.learn`) and play their fixed greedy strategies in the evaluation stage
(:meth:`Match.evaluate`), whose episodes are counted as wins of either side or ties
(:func:`tally`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from cmarlcd.errors import require
from cmarlcd.games.spec import GameSpec
from cmarlcd.progress import report_progress
from cmarlcd.training.loop import CHUNK_EPISODES, Outcome, Play, PlayBatch
from cmarlcd.training.protocol import Side
from cmarlcd.training.sides import new_side, new_sides
from cmarlcd.training.tabular_side import UNSEEN_MODES


@dataclass(frozen=True)
class MatchResult:
    """An evaluation stage: episodes won by each side, tied, and their turns."""

    episodes: int
    wins: tuple[int, int]
    ties: int
    win_turns: tuple[int, int]
    """Total turns of each side's won episodes."""
    turns: int

    def win_rate(self, side: int) -> float:
        return self.wins[side] / self.episodes

    def win_steps(self, side: int) -> float:
        """Average turns of the side's won episodes (NaN when it won none)."""
        return self.win_turns[side] / self.wins[side] if self.wins[side] else float("nan")


def tally(outcome: Outcome) -> MatchResult:
    """Count the episodes of an evaluation. [choice] A side won an episode that
    terminated with its return above the other's; an episode cut at the turn cap or with
    equal returns is a tie. On the battlefield this is exactly its rule: a winner has
    destroyed all six opponents and returns at least 6 x 2 + 10 = 22, the loser at most
    5 x 2 - 10 = 0, and a mutual wipe-out gives both sides 12."""
    first, second = outcome.returns[:, 0], outcome.returns[:, 1]
    won = (outcome.terminated & (first > second), outcome.terminated & (second > first))
    wins = tuple(int(w.sum()) for w in won)
    return MatchResult(
        episodes=int(outcome.lengths.size),
        wins=(wins[0], wins[1]),
        ties=int(outcome.lengths.size - wins[0] - wins[1]),
        win_turns=(int(outcome.lengths[won[0]].sum()), int(outcome.lengths[won[1]].sum())),
        turns=int(outcome.lengths.sum()),
    )


class Match(Play):
    """Two learners, one per side of a two-team game, with their own streams.

    Args:
        spec: a game of two teams.
        configs: each side's learner config (tabular or deep).
        env_rng: the game's randomness, while learning.
        agent_rngs: each side's randomness (actions; a deep side also spawns its own
            parameter and replay streams from it).
        learn_episodes: the learning stage's length, known in advance because a deep
            side's ε is annealed over it (eq. 18).
        sides: the sides, when made elsewhere (:class:`MatchBatch`); by default each
            config's side on its own.
        unseen: what a tabular side plays at evaluation in a state it never visited,
            ``"lowest"`` (default) or ``"random"``
            (:func:`cmarlcd.training.tabular_side.tabular_greedy`).
    """

    def __init__(
        self,
        spec: GameSpec,
        configs: Sequence[Any],
        env_rng: np.random.Generator,
        agent_rngs: Sequence[np.random.Generator],
        learn_episodes: int,
        sides: Sequence[Side] | None = None,
        unseen: str = UNSEEN_MODES[0],
    ) -> None:
        require(
            spec.n_teams == 2, "game", f"a match needs two teams; {spec.name} has {spec.n_teams}"
        )
        require(learn_episodes >= 1, "learn_episodes", f"must be >= 1 (got {learn_episodes})")
        self.configs, self.learn_episodes = tuple(configs), int(learn_episodes)
        if sides is None:
            pairs = zip(configs, agent_rngs, strict=True)
            sides = [
                new_side(spec, team, config, rng, self.learn_episodes, unseen)
                for team, (config, rng) in enumerate(pairs)
            ]
        super().__init__(spec, sides, env_rng, agent_rngs)

    def learn(self, episodes: int | None = None) -> None:
        """Both sides learn for ``episodes`` more episodes (default: the rest of the
        learning stage), progress reported as episodes finish."""
        target = self.learn_episodes if episodes is None else self.episodes + int(episodes)
        require(
            target <= self.learn_episodes,
            "episodes",
            f"the learning stage has {self.learn_episodes} episodes",
        )
        while self.episodes < target:
            before = self.episodes
            self.advance(min(target, before + CHUNK_EPISODES))
            self.require_alone()
            report_progress(float(self.episodes - before))

    def evaluate(self, episodes: int, rng: np.random.Generator) -> MatchResult:  # type: ignore[override]
        """Both sides' greedy strategies for ``episodes`` episodes (see
        :meth:`cmarlcd.training.loop.Play.evaluate`), counted as wins and ties."""
        result = tally(super().evaluate(episodes, rng))
        report_progress(float(episodes))
        return result


class MatchBatch(PlayBatch):
    """Matches of one pairing (e.g. the rounds of a tournament) learning together, so
    that each deep learner's sides train as one stacked model (see
    :class:`cmarlcd.training.loop.PlayBatch`); each match is evaluated with the
    strategies it finished learning with.

    Args:
        spec: a game of two teams.
        configs: the pairing: the learner config of each of its two positions.
        positions: for each match, the positions that play side 0 and side 1
            (``(0, 1)`` or ``(1, 0)``: rounds may swap sides).
        env_rngs: each match's game stream, as for :class:`Match`.
        agent_rngs: each match's streams of its two sides, as for :class:`Match`.
        learn_episodes: each match's learning stage.
        unseen: what the tabular sides play in states they never visited (see
            :class:`Match`).
    """

    def __init__(
        self,
        spec: GameSpec,
        configs: Sequence[Any],
        positions: Sequence[tuple[int, int]],
        env_rngs: Sequence[np.random.Generator],
        agent_rngs: Sequence[Sequence[np.random.Generator]],
        learn_episodes: int,
        unseen: str = UNSEEN_MODES[0],
    ) -> None:
        sides, groups = new_sides(spec, configs, positions, agent_rngs, learn_episodes, unseen)
        self.matches = [
            Match(spec, [configs[p] for p in order], env_rng, rngs, learn_episodes, sides=pair)
            for order, env_rng, rngs, pair in zip(
                positions, env_rngs, agent_rngs, sides, strict=True
            )
        ]
        super().__init__(self.matches, groups, learn_episodes)
