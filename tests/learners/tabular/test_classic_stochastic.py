"""The classic independent learners in stochastic games: each step rule against a
hand-computed update, and each learner on a trivial one-state game through the compiled
training loop."""

from __future__ import annotations

import numpy as np
import pytest

from cmarlcd.games.matrix import from_payoffs
from cmarlcd.learners.tabular.distributed_q import DistributedQStochasticConfig
from cmarlcd.learners.tabular.hysteretic import HystereticStochasticConfig
from cmarlcd.learners.tabular.lenient import LenientStochasticConfig
from cmarlcd.learners.tabular.protocol import full_legal, init_tables
from cmarlcd.learners.tabular.q_learning import IQLStochasticConfig
from cmarlcd.training.tabular import TabularRun

COUNTS = np.array([2, 2], dtype=np.int64)


def tables_of(config, n_states: int = 3):
    return init_tables(config, n_states, COUNTS)


def one_step(config, tables, reward: float, terminal: bool = False) -> None:
    """Step 0 of an episode: state 0, joint action (1, 0), ``reward``, then state 1."""
    states = np.array([0], dtype=np.int64)
    joints = np.array([[1, 0]], dtype=np.int64)
    rewards = np.array([reward])
    config.kernels.observe(tables, config.params(), states, joints, rewards, 0, 1, terminal)


def test_iql_steps_towards_the_discounted_best_next_value() -> None:
    config = IQLStochasticConfig(alpha=0.5, gamma=0.9)
    tables = tables_of(config)
    tables.values[1] = [[2.0, 5.0], [1.0, 0.0]]
    one_step(config, tables, reward=1.0)
    # agent 0: target 1 + 0.9 · 5 = 5.5, Q = 0 + 0.5 · 5.5; agent 1: 1 + 0.9 · 1 = 1.9
    assert tables.values[0, 0].tolist() == pytest.approx([0.0, 2.75])
    assert tables.values[0, 1].tolist() == pytest.approx([0.95, 0.0])
    one_step(config, tables, reward=-1.0, terminal=True)  # no bootstrap at the end
    assert tables.values[0, 0, 1] == pytest.approx(2.75 + 0.5 * (-1.0 - 2.75))


def test_hysteretic_stochastic_uses_alpha_up_and_beta_down() -> None:
    config = HystereticStochasticConfig(alpha=0.5, beta=0.1, gamma=0.9)
    tables = tables_of(config)
    tables.values[1] = [[2.0, 5.0], [1.0, 0.0]]
    tables.values[0] = [[0.0, 4.0], [3.0, 0.0]]
    one_step(config, tables, reward=1.0)
    # agent 0: δ = 5.5 - 4 = 1.5 >= 0; agent 1: δ = 1.9 - 3 = -1.1 < 0
    assert tables.values[0, 0, 1] == pytest.approx(4.0 + 0.5 * 1.5)
    assert tables.values[0, 1, 0] == pytest.approx(3.0 - 0.1 * 1.1)


def test_distributed_q_stochastic_is_optimistic_and_waits_for_a_finite_target() -> None:
    config = DistributedQStochasticConfig(gamma=0.9)
    tables = tables_of(config)
    tables.values[1, 0] = [2.0, 5.0]  # agent 1 has seen nothing at state 1 yet: -inf
    one_step(config, tables, reward=1.0)
    assert tables.values[0, 0, 1] == pytest.approx(5.5) and tables.policy[0, 0] == 1
    assert tables.values[0, 1, 0] == -np.inf and tables.policy[0, 1] == -1
    one_step(config, tables, reward=0.0)  # a lower target never lowers q
    assert tables.values[0, 0, 1] == pytest.approx(5.5)


def test_lenient_stochastic_forgives_while_hot_and_diffuses_temperature() -> None:
    config = LenientStochasticConfig(alpha=0.5, decay=0.5, gamma=0.9, diffusion=0.1)
    tables = tables_of(config)
    tables.values[0] = [[0.0, 4.0], [3.0, 0.0]]
    tables.temperatures[1] = [[10.0, 20.0], [30.0, 50.0]]
    tables.draws[0] = [0.0, 0.999]  # agent 0 updates; agent 1's bad news is forgiven
    one_step(config, tables, reward=1.0)
    # agent 0: target 1 + 0.9 · max(0, 0) = 1, δ = -3 < 0 but the draw 0 is under
    # 1 - exp(-1/50): Q = 4 + 0.5 · (1 - 4) = 2.5
    assert tables.values[0, 0, 1] == pytest.approx(2.5)
    assert tables.values[0, 1, 0] == 3.0  # forgiven
    # T(0, a) <- 0.5 · (0.9 · 50 + 0.1 · mean T(1, ·)): means 15 (agent 0), 40 (agent 1)
    assert tables.temperatures[0, 0, 1] == pytest.approx(0.5 * (45.0 + 1.5))
    assert tables.temperatures[0, 1, 0] == pytest.approx(0.5 * (45.0 + 4.0))
    assert tables.temperatures[0, 0, 0] == 50.0  # not played: unchanged


@pytest.mark.parametrize(
    "config",
    [
        IQLStochasticConfig(),
        DistributedQStochasticConfig(),
        HystereticStochasticConfig(),
        LenientStochasticConfig(),
    ],
    ids=lambda c: c.name,
)
def test_every_stochastic_learner_learns_a_trivial_one_state_game(config) -> None:
    """A repeated game is a one-step episodic game: the loop of the DSN plays it too."""
    game = from_payoffs([[1.0, 0.0], [0.0, 0.0]])
    for seed in range(5):
        rngs = np.random.default_rng(seed).spawn(2)
        run = TabularRun(game.spec(), config, *rngs)
        run.train(3_000)
        assert tuple(run.greedy_policy()[0]) == (0, 0)


def test_greedy_execution_keeps_to_the_legal_actions() -> None:
    config = IQLStochasticConfig()
    tables = tables_of(config)
    legal = full_legal(COUNTS)
    legal[0, 0] = False
    config.kernels.init_state(tables, config.params(), 2, legal, COUNTS)
    tables.values[2, 0] = [9.0, 1.0]  # the illegal action has the larger value
    joint = np.zeros(2, dtype=np.int64)
    config.kernels.greedy(tables, 2, COUNTS, joint)
    assert joint[0] == 1
