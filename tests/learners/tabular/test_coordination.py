"""CMARL-CD: repeated games (Algorithm 1, eqs. 2-5) and stochastic games (Algorithm 2,
eqs. 14-17)."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

from cmarlcd import CMARLCD, ConfigError, RepeatedConfig, fit
from cmarlcd.games.matrix import climbing_game, from_payoffs, penalty_game, random_case1
from cmarlcd.learners import policy
from cmarlcd.learners.tabular.coordination import CMARLCDStochastic, StochasticConfig, is_pure


def softmax(values: list[float], temperature: float) -> list[float]:
    weights = [math.exp(v / temperature) for v in values]
    return [w / sum(weights) for w in weights]


def test_update_matches_a_hand_computed_example() -> None:
    """Two agents with 3 actions, T = 1, δ = 0.04, all degrees 0 (eqs. 2-5)."""
    learner = CMARLCD([3, 3], RepeatedConfig(temperature=1.0, delta=0.04), seed=0)
    assert learner.update((0, 2), 5.0)  # first game: 5 >= -inf, I = 1
    assert learner.degrees[0].tolist() == pytest.approx([0.04, -0.04, -0.04])
    assert learner.degrees[1].tolist() == pytest.approx([-0.04, -0.04, 0.04])
    # p = e^0.04 / (e^0.04 + 2 e^-0.04) = 1.040811 / 2.962389 = 0.351342
    assert learner.strategy(0)[0] == pytest.approx(0.351342, abs=1e-6)
    assert learner.strategy(1).tolist() == pytest.approx([0.324329, 0.324329, 0.351342], abs=1e-6)
    assert not learner.update((1, 1), 4.0)  # 4 < r_max = 5: I = 0, nothing moves
    assert learner.degrees[0].tolist() == pytest.approx([0.04, -0.04, -0.04])
    assert learner.update((1, 2), 5.0)  # a tie counts (eq. 4: r >= r_max)
    assert learner.degrees[0].tolist() == pytest.approx([0.0, 0.0, -0.08])
    assert learner.degrees[1].tolist() == pytest.approx([-0.08, -0.08, 0.08])
    assert learner.max_reward == 5.0


def test_temperature_scales_the_softmax() -> None:
    learner = CMARLCD([2, 2], RepeatedConfig(temperature=0.5, delta=0.25), seed=0)
    learner.update((0, 1), 1.0)  # c_0 = (0.25, -0.25): p = softmax((0.5, -0.5))
    assert learner.strategy(0).tolist() == pytest.approx(softmax([0.5, -0.5], 1.0))
    assert learner.strategy(0)[0] == pytest.approx(1 / (1 + math.exp(-1)))


def test_sample_action_is_an_inverse_cdf() -> None:
    p = np.array([0.25, 0.5, 0.25])
    draws = {u: policy.sample_action(p, 3, u) for u in (0.0, 0.2, 0.25, 0.6, 0.74, 0.75, 0.99)}
    assert draws == {0.0: 0, 0.2: 0, 0.25: 1, 0.6: 1, 0.74: 1, 0.75: 2, 0.99: 2}


def test_stopping_rule_and_greedy_ties() -> None:
    p = np.array([[0.9995, 0.0005, 0.0], [0.5, 0.5, 0.0]])
    counts = np.array([2, 2])
    assert not is_pure(p, counts, 0.999)
    p[1] = [0.0004, 0.9996, 0.0]
    assert is_pure(p, counts, 0.999)
    degrees = np.array([[1.0, 1.0, 9.0], [0.0, 2.0, 2.0]])  # padding (9.0) is ignored
    legal = np.array([[True, True, False], [True, True, False]])
    greedy = [policy.greedy_action(degrees[i], legal[i], counts[i]) for i in range(2)]
    assert greedy == [0, 1]
    legal[1, 1] = False  # an illegal action is never greedy
    assert policy.greedy_action(degrees[1], legal[1], counts[1]) == 0


def reference_fit(payoffs: np.ndarray, rng: np.random.Generator, delta: float, max_games: int):
    """Algorithm 1 in plain Python, written from the paper, consuming the same stream:
    one U[0, 1) per agent per game, actions drawn by inverse CDF."""
    degrees = [[0.0] * k for k in payoffs.shape]
    strategies = [softmax(c, 1.0) for c in degrees]
    r_max = -math.inf
    for game in range(1, max_games + 1):
        joint = []
        for p in strategies:
            u, acc, action = rng.random(), 0.0, len(p) - 1
            for a in range(len(p) - 1):
                acc += p[a]
                if u < acc:
                    action = a
                    break
            joint.append(action)
        reward = payoffs[tuple(joint)]
        if reward >= r_max:
            r_max = reward
            for i, chosen in enumerate(joint):
                degrees[i] = [
                    c + delta if a == chosen else c - delta for a, c in enumerate(degrees[i])
                ]
                strategies[i] = softmax(degrees[i], 1.0)
            if all(max(p) > 0.999 for p in strategies):
                return game, degrees
    return max_games, degrees


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_compiled_loop_equals_a_plain_python_algorithm_1(seed: int) -> None:
    game = random_case1(3, 3, np.random.default_rng(seed))
    stream = np.random.default_rng(100 + seed)
    expected_games, expected = reference_fit(game.payoffs, stream, 0.04, 10**6)
    learner = CMARLCD(game.action_counts, seed=np.random.default_rng(100 + seed))
    result = fit(learner, game)
    assert result.games == expected_games
    assert np.allclose(learner.degrees, expected, atol=1e-12, rtol=0)


SCRIPT = """
import json, numpy as np
from cmarlcd import CMARLCD, fit
from cmarlcd.games.matrix import random_case1
game = random_case1(4, 3, np.random.default_rng(3))
learner = CMARLCD(game.action_counts, seed=11)
r = fit(learner, game)
print(json.dumps({"games": r.games, "degrees": learner.degrees.tolist()}))
"""


def test_compiled_kernels_equal_the_same_code_interpreted() -> None:
    """NUMBA_DISABLE_JIT runs the very same functions as plain Python."""
    runs = {}
    for jit_off in ("0", "1"):
        env = {**os.environ, "NUMBA_DISABLE_JIT": jit_off}
        out = subprocess.run(
            [sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, check=True
        )
        runs[jit_off] = json.loads(out.stdout)
    assert runs["0"]["games"] == runs["1"]["games"]
    assert np.allclose(runs["0"]["degrees"], runs["1"]["degrees"], atol=1e-12, rtol=0)


def test_act_update_loop_equals_fit() -> None:
    game = random_case1(3, 4, np.random.default_rng(5))
    stepwise = CMARLCD(game.action_counts, seed=9)
    games = 0
    while not stepwise.is_pure():
        joint = stepwise.act()
        stepwise.update(joint, game.payoff(joint))
        games += 1
    fitted = CMARLCD(game.action_counts, seed=9)
    assert fit(fitted, game).games == games
    assert np.array_equal(fitted.degrees, stepwise.degrees)


def test_same_seed_same_result_and_different_seed_differs() -> None:
    game = random_case1(4, 4, np.random.default_rng(0))
    first = fit(CMARLCD(game.action_counts, seed=1), game)
    again = fit(CMARLCD(game.action_counts, seed=1), game)
    other = fit(CMARLCD(game.action_counts, seed=2), game)
    assert first == again
    assert other.games != first.games


@pytest.mark.parametrize("game", [climbing_game(), penalty_game(-10.0), penalty_game(-100.0)])
def test_converges_to_an_optimum_of_classic_games(game) -> None:
    for seed in range(20):
        result = fit(CMARLCD(game.action_counts, seed=seed), game)
        assert result.converged and result.success, (game.name, seed, result)


def test_agents_with_different_action_counts() -> None:
    rng = np.random.default_rng(4)
    successes = 0
    for seed in range(20):
        payoffs = 0.9 * rng.random((2, 3, 5))
        payoffs[1, 2, 4] = 1.0
        game = from_payoffs(payoffs)
        learner = CMARLCD(game.action_counts, seed=seed)
        result = fit(learner, game)
        assert result.converged
        assert learner.strategies[0, 2:].tolist() == [0.0, 0.0, 0.0]  # padding stays empty
        successes += result.success
    assert successes >= 19  # 30 joint actions: the optimum is met long before convergence


def test_cap_ends_an_unconverged_run_as_failure() -> None:
    game = random_case1(6, 5, np.random.default_rng(0))
    result = fit(CMARLCD(game.action_counts, seed=0), game, max_games=50)
    assert result.games == 50 and not result.converged and not result.success


@pytest.mark.parametrize(
    ("kwargs", "parameter"),
    [
        ({"temperature": 0.0}, "temperature"),
        ({"temperature": -1.0}, "temperature"),
        ({"temperature": float("nan")}, "temperature"),
        ({"delta": 0.0}, "delta"),
        ({"delta": 1.0}, "delta"),
        ({"purity_threshold": 1.0}, "purity_threshold"),
        ({"max_games": 0}, "max_games"),
    ],
)
def test_bad_config_names_the_parameter(kwargs: dict, parameter: str) -> None:
    with pytest.raises(ConfigError) as info:
        RepeatedConfig(**kwargs)
    assert info.value.parameter == parameter


def test_bad_learner_input_is_rejected() -> None:
    with pytest.raises(ConfigError, match="agents"):
        CMARLCD([3])
    with pytest.raises(ConfigError, match="actions"):
        CMARLCD([3, 1])
    learner = CMARLCD([2, 2], seed=0)
    with pytest.raises(ConfigError, match="joint_action"):
        learner.update((0, 2), 1.0)
    with pytest.raises(ConfigError, match="joint_action"):
        learner.update((0,), 1.0)
    with pytest.raises(ConfigError, match="reward"):
        learner.update((0, 1), float("nan"))
    with pytest.raises(ConfigError, match="game"):
        fit(learner, climbing_game())


# ------------------------------------------------- Algorithm 2: stochastic games


def episode(learner, steps) -> None:
    for state, joint, reward in steps:
        learner.observe(state, joint, reward)
    learner.end_episode()


def test_new_record_resets_and_takes_the_large_step() -> None:
    """DSN settings: c_init 1.5, δ_reset 0.5, δ 0.05, clip [0.5, 3.0], γ 0.9."""
    learner = CMARLCDStochastic([2, 3], n_states=3, seed=0)
    # one episode s0 -(1, 2), r=1-> s1 -(0, 0), r=2-> end. Backwards:
    # s1: G = 2 > -inf, record: reset to 1.5, chosen +0.5, others -0.5
    # s0: G = 1 + 0.9 * 2 = 2.8 > -inf, record as well
    episode(learner, [(0, (1, 2), 1.0), (1, (0, 0), 2.0)])
    values = learner.tables.degrees
    assert values[1, 0, :2].tolist() == [2.0, 1.0]
    assert values[1, 1].tolist() == [2.0, 1.0, 1.0]
    assert values[0, 0, :2].tolist() == [1.0, 2.0]
    assert values[0, 1].tolist() == [1.0, 1.0, 2.0]
    assert learner.max_return(0) == pytest.approx(2.8) and learner.max_return(1) == 2.0
    # eq. (17): p = softmax(c / T)
    assert learner.tables.probs[1, 1].tolist() == pytest.approx(softmax([2.0, 1.0, 1.0], 1.0))


def test_tie_takes_the_small_step_and_below_changes_nothing() -> None:
    learner = CMARLCDStochastic([3], n_states=1, seed=0)
    episode(learner, [(0, (0,), 5.0)])  # record: [2.0, 1.0, 1.0]
    episode(learner, [(0, (1,), 5.0)])  # tie: action 1 +0.05, others -0.05
    assert learner.tables.degrees[0, 0].tolist() == pytest.approx([1.95, 1.05, 0.95])
    episode(learner, [(0, (2,), 4.0)])  # below the record: nothing moves
    assert learner.tables.degrees[0, 0].tolist() == pytest.approx([1.95, 1.05, 0.95])
    episode(learner, [(0, (2,), 5.0 + 1e-12)])  # within the 1e-9 tolerance: a tie
    assert learner.tables.degrees[0, 0].tolist() == pytest.approx([1.9, 1.0, 1.0])
    episode(learner, [(0, (2,), 5.0 - 1e-12)])  # a hair below, within it: a tie too
    assert learner.tables.degrees[0, 0].tolist() == pytest.approx([1.85, 0.95, 1.05])
    assert learner.max_return(0) == 5.0


def test_degrees_are_clipped_to_c_min_c_max() -> None:
    learner = CMARLCDStochastic([2], StochasticConfig(delta=0.4), n_states=1, seed=0)
    episode(learner, [(0, (0,), 1.0)])  # record: [2.0, 1.0]
    for _ in range(5):  # ties: +0.4 / -0.4 until the clips hold
        episode(learner, [(0, (0,), 1.0)])
    assert learner.tables.degrees[0, 0].tolist() == [3.0, 0.5]


def test_every_visit_backward_order() -> None:
    """A state visited twice: the later visit (processed first) sets the record."""
    learner = CMARLCDStochastic([2], n_states=2, seed=0)
    # s0 -(0), r=0-> s1 -(1), r=0-> s0 -(1), r=10-> end
    # backwards: t=2 s0 G=10 record (action 1); t=1 s1 G=9 record; t=0 s0 G=8.1 < 10: nothing
    episode(learner, [(0, (0,), 0.0), (1, (1,), 0.0), (0, (1,), 10.0)])
    assert learner.tables.degrees[0, 0].tolist() == [1.0, 2.0]
    assert learner.max_return(0) == 10.0 and learner.max_return(1) == pytest.approx(9.0)


def test_greedy_breaks_ties_by_lowest_index() -> None:
    learner = CMARLCDStochastic([3, 3], n_states=1, seed=0)
    assert learner.greedy(0) == (0, 0)  # all degrees equal c_init


@pytest.mark.parametrize(
    ("kwargs", "parameter"),
    [
        ({"c_min": 2.0, "c_max": 1.0}, "c_max"),
        ({"c_min": 0.0}, "c_min"),
        ({"c_init": 5.0}, "c_init"),
        ({"gamma": -0.1}, "gamma"),
        ({"gamma": 1.5}, "gamma"),
        ({"delta": 0.0}, "delta"),
        ({"temperature": -1.0}, "temperature"),
    ],
)
def test_bad_stochastic_config(kwargs: dict, parameter: str) -> None:
    with pytest.raises(ConfigError) as info:
        StochasticConfig(**kwargs)
    assert info.value.parameter == parameter
