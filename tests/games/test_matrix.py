"""Invariants of the repeated games (Section IV-C)."""

from __future__ import annotations

import json
from itertools import product

import numpy as np
import pytest

from cmarlcd.errors import ConfigError
from cmarlcd.games import matrix
from cmarlcd.games.matrix import (
    case2_optimum_count,
    climbing_game,
    from_payoffs,
    load_payoffs,
    penalty_game,
    random_case1,
    random_case2,
)


@pytest.mark.parametrize(("n", "m"), [(2, 2), (3, 4), (5, 3), (7, 5)])
def test_case1_has_m_optima_whose_components_are_permutations(n: int, m: int) -> None:
    game = random_case1(n, m, np.random.default_rng(n * 10 + m))
    optima = np.array(game.optimal_joint_actions)
    assert game.payoffs.shape == (m,) * n
    assert optima.shape == (m, n)
    for agent in range(n):  # each agent's components across the optima: a permutation
        assert sorted(optima[:, agent]) == list(range(m))
    assert game.max_payoff == matrix.OPTIMAL_PAYOFF
    others = game.payoffs[game.payoffs != matrix.OPTIMAL_PAYOFF]
    assert others.size == m**n - m
    assert others.min() >= 0.0 and others.max() < matrix.SUBOPTIMAL_SCALE


# round(0.1 * m^n) by hand, halves rounded up: 8.1 -> 8, 24.3 -> 24, 72.9 -> 73,
# 25.6 -> 26, 62.5 -> 63, 312.5 -> 313, 1638.4 -> 1638.
CASE2_COUNTS = {(4, 3): 8, (5, 3): 24, (6, 3): 73, (4, 4): 26, (4, 5): 63, (5, 5): 313}
CASE2_COUNTS[(7, 4)] = 1638


@pytest.mark.parametrize(("n", "m"), sorted(CASE2_COUNTS))
def test_case2_has_round_tenth_of_joint_actions_optimal(n: int, m: int) -> None:
    assert case2_optimum_count(n, m) == CASE2_COUNTS[(n, m)]
    game = random_case2(n, m, np.random.default_rng(0))
    assert len(game.optimal_joint_actions) == CASE2_COUNTS[(n, m)]
    assert (game.payoffs[game.payoffs < 1.0] < matrix.SUBOPTIMAL_SCALE).all()


def test_case2_optima_are_spread_uniformly() -> None:
    """Across many draws every joint action is optimal about 10 % of the time."""
    hits = np.zeros((3,) * 4)
    for seed in range(400):
        hits += random_case2(4, 3, np.random.default_rng(seed)).payoffs == 1.0
    rate = hits / 400
    assert abs(rate.mean() - 8 / 81) < 1e-12  # exactly 8 optima each time
    assert rate.min() > 0.04 and rate.max() < 0.18  # no joint action is favoured


def test_generators_are_deterministic_by_seed() -> None:
    a = random_case1(4, 3, np.random.default_rng(7)).payoffs
    b = random_case1(4, 3, np.random.default_rng(7)).payoffs
    c = random_case1(4, 3, np.random.default_rng(8)).payoffs
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def test_flat_index_strides_address_the_tensor() -> None:
    game = from_payoffs(np.arange(2 * 3 * 4, dtype=float).reshape(2, 3, 4))
    for joint in product(range(2), range(3), range(4)):
        assert game.flat_payoffs[np.dot(joint, game.strides)] == game.payoff(joint)


def test_classic_games_have_their_known_optima() -> None:
    assert climbing_game().optimal_joint_actions == [(0, 0)]
    assert climbing_game().max_payoff == 11
    penalty = penalty_game(-50)
    assert penalty.optimal_joint_actions == [(0, 0), (2, 2)]
    assert penalty.payoff((0, 2)) == penalty.payoff((2, 0)) == -50


def test_payoffs_are_read_only_copies() -> None:
    source = np.ones((2, 2))
    game = from_payoffs(source)
    source[0, 0] = 5
    assert game.payoff((0, 0)) == 1
    with pytest.raises(ValueError):
        game.payoffs[0, 0] = 3


@pytest.mark.parametrize(
    ("payoffs", "fragment"),
    [
        ([1.0, 2.0], "one axis per agent"),
        ([[1.0, 2.0]], "at least 2 actions"),
        ([[1.0, np.nan], [0.0, 1.0]], "finite"),
        ([[1.0, np.inf], [0.0, 1.0]], "finite"),
        ([[1.0, 2.0], [3.0]], "rectangular numeric"),
        ([["a", "b"], ["c", "d"]], "rectangular numeric"),
    ],
)
def test_bad_payoffs_are_rejected(payoffs: object, fragment: str) -> None:
    with pytest.raises(ConfigError, match=fragment) as info:
        from_payoffs(payoffs)
    assert info.value.parameter == "payoffs"


def test_bad_sizes_and_penalty_are_rejected() -> None:
    rng = np.random.default_rng(0)
    with pytest.raises(ConfigError, match="agents"):
        random_case1(1, 3, rng)
    with pytest.raises(ConfigError, match="actions"):
        random_case2(3, 1, rng)
    with pytest.raises(ConfigError, match="k"):
        penalty_game(5.0)


def test_load_payoffs_reads_npy_json_and_csv(tmp_path) -> None:
    tensor = np.arange(8.0).reshape(2, 2, 2)
    np.save(tmp_path / "g.npy", tensor)
    (tmp_path / "g.json").write_text(json.dumps(tensor.tolist()))
    (tmp_path / "g.csv").write_text("1,2\n3,4\n")
    assert np.array_equal(load_payoffs(tmp_path / "g.npy").payoffs, tensor)
    assert np.array_equal(load_payoffs(tmp_path / "g.json").payoffs, tensor)
    assert load_payoffs(tmp_path / "g.csv").payoffs.tolist() == [[1, 2], [3, 4]]


def test_load_payoffs_rejects_bad_files(tmp_path) -> None:
    (tmp_path / "broken.json").write_text("[[1, 2], [3,")
    (tmp_path / "g.xlsx").write_text("")
    for name, fragment in [
        ("broken.json", "cannot read"),
        ("g.xlsx", "unsupported"),
        ("missing.npy", "no such file"),
    ]:
        with pytest.raises(ConfigError, match=fragment):
            load_payoffs(tmp_path / name)


def test_a_matrix_game_is_a_one_step_parallel_env() -> None:
    from cmarlcd.games.matrix import MatrixGameEnv

    env = MatrixGameEnv(climbing_game(), render_mode="ansi")
    observations, infos = env.reset(seed=0)
    assert observations == {"agent_0": 0, "agent_1": 0}
    assert infos["agent_1"]["action_mask"].tolist() == [1, 1, 1]
    _, rewards, terminations, truncations, _ = env.step({"agent_0": 0, "agent_1": 1})
    assert rewards == {"agent_0": -30.0, "agent_1": -30.0}  # the climbing game's (0, 1)
    assert all(terminations.values()) and not any(truncations.values()) and env.agents == []
    text = env.render()
    assert "[-30]" in text and text.count("[") == 1  # the played cell, marked once
    three = MatrixGameEnv(from_payoffs(np.arange(8.0).reshape(2, 2, 2)), render_mode="ansi")
    three.reset(seed=0)
    three.step({"agent_0": 1, "agent_1": 1, "agent_2": 0})
    assert "played (1, 1, 0) -> 6" in three.render()
