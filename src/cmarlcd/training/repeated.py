"""Runs on a repeated game: play until the learner has converged (Algorithm 1), or for a
budget of games while watching the greedy joint action (the learner comparison).

:func:`play_until_converged` and :func:`play_watching_greedy` are templates
(:mod:`cmarlcd.compiled`): ``game`` is bound to a game's kernels (a matrix game's,
:mod:`cmarlcd.games.matrix`) and ``learner`` to a repeated-game learner's
(:class:`cmarlcd.learners.tabular.protocol.RepeatedKernels`). :func:`fit` runs the first for a
learner object such as :class:`cmarlcd.learners.CMARLCD`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cmarlcd.compiled import Unbound, specialise
from cmarlcd.errors import require
from cmarlcd.games.matrix import KERNELS, MatrixGame

game = Unbound("game")
learner = Unbound("learner")


def play_until_converged(env, tables, params, counts, max_games, rng) -> tuple[int, bool]:
    """Template: play until ``learner.converged`` (asked only when a game changed the
    learner) or ``max_games`` games; returns ``(games_played, converged)``. The tables are
    updated in place, so a call continues from wherever the learner stands."""
    joint = np.zeros(counts.shape[0], dtype=np.int64)
    rewards = np.zeros(1)
    for played in range(max_games):
        learner.act(tables, params, counts, rng, joint)
        game.step(env, joint, rng, rewards)
        if learner.learn(tables, params, counts, joint, rewards[0]) and learner.converged(
            tables, params, counts
        ):
            return played + 1, True
    return max_games, False


def play_watching_greedy(
    env, tables, params, counts, max_games, env_rng, rng, greedy
) -> tuple[int, bool, int]:
    """Template: like :func:`play_until_converged`, with the game's draws from ``env_rng``
    and the greedy joint action watched: ``greedy`` holds it throughout. Returns
    ``(games_played, converged, settled)``, ``settled`` being the games played when the
    greedy joint action last changed (0 if it never did): from then on it stayed.

    For learners without a stopping rule (``converged`` always False) this plays
    ``max_games`` games."""
    n_agents = counts.shape[0]
    joint = np.zeros(n_agents, dtype=np.int64)
    candidate = np.zeros(n_agents, dtype=np.int64)
    rewards = np.zeros(1)
    learner.greedy(tables, counts, greedy)
    settled = 0
    for played in range(max_games):
        learner.act(tables, params, counts, rng, joint)
        game.step(env, joint, env_rng, rewards)
        if not learner.learn(tables, params, counts, joint, rewards[0]):
            continue
        learner.greedy(tables, counts, candidate)
        for i in range(n_agents):
            if candidate[i] != greedy[i]:
                greedy[:] = candidate
                settled = played + 1
                break
        if learner.converged(tables, params, counts):
            return played + 1, True, settled
    return max_games, False, settled


@dataclass(frozen=True)
class FitResult:
    """Outcome of :func:`fit`."""

    games: int
    """Games played in this call."""
    converged: bool
    """The learner converged (for CMARL-CD: every strategy pure) before the cap."""
    greedy_joint_action: tuple[int, ...]
    """Each agent's greedy action afterwards."""
    greedy_payoff: float
    """Payoff of the greedy joint action."""
    success: bool
    """Converged and the greedy joint action is optimal (the paper's success)."""


def fit(learner_object, game: MatrixGame, max_games: int | None = None) -> FitResult:
    """Play ``game`` with ``learner_object`` (e.g. :class:`cmarlcd.learners.CMARLCD`) until
    it converges or ``max_games`` games (default: its config's ``max_games``) are played,
    through the compiled loop, on the learner's own tables and random stream."""
    counts = learner_object.counts
    require(
        game.action_counts == tuple(counts.tolist()),
        "game",
        f"has action counts {game.action_counts}, the learners {tuple(counts.tolist())}",
    )
    config = learner_object.config
    cap = config.max_games if max_games is None else int(max_games)
    require(cap >= 1, "max_games", f"must be >= 1 (got {cap})")
    loop = specialise(play_until_converged, game=KERNELS, learner=config.kernels)
    games, converged = loop(
        game.new_env(),
        learner_object.tables,
        learner_object.params,
        counts,
        cap,
        learner_object.rng,
    )
    greedy = learner_object.greedy_joint_action()
    payoff = game.payoff(greedy)
    success = bool(converged) and payoff == game.max_payoff
    return FitResult(int(games), bool(converged), greedy, payoff, success)
