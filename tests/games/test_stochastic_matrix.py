"""Invariants of the stochastic climbing games (Kapetanakis & Kudenko 2002) and of the
compiled draw of a stochastic payoff."""

from __future__ import annotations

import numpy as np
import pytest

from cmarlcd.errors import ConfigError
from cmarlcd.games.matrix import climbing_game
from cmarlcd.games.matrix.stochastic import (
    StochasticMatrixGame,
    fully_stochastic_climbing_game,
    partially_stochastic_climbing_game,
)

STOCHASTIC_CLIMBING = [partially_stochastic_climbing_game, fully_stochastic_climbing_game]


@pytest.mark.parametrize("make", STOCHASTIC_CLIMBING)
def test_expected_payoffs_are_the_climbing_games(make) -> None:
    """Both games are built so that their expectations equal the climbing game's."""
    game = make()
    assert np.array_equal(game.expected_payoffs, climbing_game().payoffs)
    assert game.optimal_joint_actions == [(0, 0)]
    assert game.max_payoff == 11.0 and game.is_optimal((0, 0)) and not game.is_optimal((1, 1))


def test_the_lucky_draw_pays_more_than_the_optimum() -> None:
    """(1, 1) can pay 14, more than (0, 0) ever pays: what fools a max-reward learner."""
    for make in STOCHASTIC_CLIMBING:
        game = make()
        assert game.outcomes[1, 1].max() == 14.0
        assert game.outcomes[0, 0].max() < 14.0


@pytest.mark.parametrize("make", STOCHASTIC_CLIMBING)
def test_compiled_draws_follow_the_probabilities(make) -> None:
    game = make()
    spec = game.spec()
    env, rng, rewards = game.new_env(), np.random.default_rng(3), np.zeros(1)
    for joint in [(0, 0), (1, 1), (0, 1), (2, 2)]:
        draws = []
        for _ in range(4_000):
            spec.kernels.step(env, np.array(joint, dtype=np.int64), rng, rewards)
            draws.append(rewards[0])
        values = set(game.outcomes[joint].tolist())
        assert set(draws) <= values
        # mean within 5 standard errors of the expectation (payoffs differ by <= 70)
        assert abs(np.mean(draws) - game.payoff(joint)) < 5 * 35 / np.sqrt(4_000)


def test_partially_stochastic_is_deterministic_off_the_middle_cell() -> None:
    game = partially_stochastic_climbing_game()
    spec, env, rng, rewards = game.spec(), game.new_env(), np.random.default_rng(0), np.zeros(1)
    for joint in [(0, 0), (0, 1), (2, 2)]:
        spec.kernels.step(env, np.array(joint, dtype=np.int64), rng, rewards)
        assert rewards[0] == climbing_game().payoff(joint)


@pytest.mark.parametrize(
    ("outcomes", "probabilities", "parameter"),
    [
        (np.zeros((2, 2, 2)), np.full((2, 2, 2), 0.4), "probabilities"),  # sums to 0.8
        (np.zeros((2, 2, 2)), np.full((2, 2, 3), 1 / 3), "probabilities"),  # shape
        (np.full((2, 2, 1), np.nan), np.ones((2, 2, 1)), "outcomes"),
        (np.zeros((2, 2)), np.ones((2, 2)), "outcomes"),  # no outcome axis
        (np.zeros((2, 2, 2)), np.array([[[1.5, -0.5]] * 2] * 2), "probabilities"),
    ],
)
def test_bad_games_are_rejected(outcomes, probabilities, parameter) -> None:
    with pytest.raises(ConfigError) as err:
        StochasticMatrixGame(outcomes, probabilities)
    assert err.value.parameter == parameter
