"""The classic independent learners (Claus & Boutilier 1998, Lauer & Riedmiller 2000,
Matignon et al. 2007, Kapetanakis & Kudenko 2002, Panait et al. 2006 / Wei & Luke 2016):
each rule against a hand-computed update, each learner on a trivial game, and the
literature's known results on the climbing and penalty games."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cmarlcd.compiled import specialise
from cmarlcd.errors import ConfigError
from cmarlcd.games.matrix import climbing_game, from_payoffs, penalty_game
from cmarlcd.games.matrix.stochastic import (
    fully_stochastic_climbing_game,
    partially_stochastic_climbing_game,
)
from cmarlcd.learners.tabular.distributed_q import DistributedQConfig
from cmarlcd.learners.tabular.fmq import FMQConfig
from cmarlcd.learners.tabular.hysteretic import HystereticConfig
from cmarlcd.learners.tabular.independent import RepeatedLearner, kk_temperature
from cmarlcd.learners.tabular.joint_action import CentralQConfig, JointActionConfig
from cmarlcd.learners.tabular.lenient import LenientConfig
from cmarlcd.learners.tabular.q_learning import IQLConfig
from cmarlcd.registry import REPEATED_LEARNERS
from cmarlcd.training.repeated import play_watching_greedy


def play(config, game, games: int, seed: int) -> tuple[int, ...]:
    """The greedy joint action after ``games`` games (the compiled loop)."""
    spec = game.spec()
    counts = spec.action_counts.copy()
    greedy = np.zeros(counts.shape[0], dtype=np.int64)
    loop = specialise(play_watching_greedy, game=spec.kernels, learner=config.kernels)
    env_rng, rng = np.random.default_rng(seed).spawn(2)
    tables = config.new_tables(counts)
    loop(game.new_env(), tables, config.params(), counts, games, env_rng, rng, greedy)
    return tuple(int(a) for a in greedy)


def optimal_share(config, game, games: int, runs: int) -> float:
    return sum(game.is_optimal(play(config, game, games, seed)) for seed in range(runs)) / runs


# ------------------------------------------------------------ hand-computed updates


def test_iql_moves_each_agents_value_a_fraction_alpha_towards_the_reward() -> None:
    learner = RepeatedLearner(IQLConfig(alpha=0.5), [3, 3], seed=0)
    learner.update((0, 2), reward=-30.0)  # Q_0(0) = 0 + 0.5 (-30 - 0) = -15
    learner.update((0, 1), reward=10.0)  # Q_0(0) = -15 + 0.5 (10 + 15) = -2.5
    values = learner.tables.values
    assert values[0].tolist() == [-2.5, 0.0, 0.0]
    assert values[1].tolist() == [0.0, 5.0, -15.0]
    assert learner.tables.plays[0] == 2


def test_hysteretic_learns_good_news_at_alpha_and_bad_news_at_beta() -> None:
    learner = RepeatedLearner(HystereticConfig(alpha=0.5, beta=0.1), [2, 2], seed=0)
    learner.update((0, 0), reward=10.0)  # δ = 10 ≥ 0: 0 + 0.5 · 10 = 5
    learner.update((0, 1), reward=-10.0)  # agent 0: δ = -15 < 0: 5 - 0.1 · 15 = 3.5
    assert learner.tables.values[0].tolist() == pytest.approx([3.5, 0.0])
    assert learner.tables.values[1].tolist() == pytest.approx([5.0, -1.0])


def test_distributed_q_keeps_the_best_reward_and_moves_its_policy_only_on_a_new_best() -> None:
    learner = RepeatedLearner(DistributedQConfig(), [3, 3], seed=0)
    assert learner.update((1, 1), 7.0)  # first rewards: both policies set
    assert learner.greedy_joint_action() == (1, 1)
    assert not learner.update((1, 2), 6.0)  # agent 0: 6 < q(1) = 7, nothing
    assert learner.update((0, 0), 11.0)  # a new best for both
    assert learner.greedy_joint_action() == (0, 0)
    assert not learner.update((0, 1), -30.0)  # a worse reward never lowers q
    q = learner.tables.values
    assert q[0].tolist() == [11.0, 7.0, -np.inf]
    assert q[1].tolist() == [11.0, 7.0, 6.0]
    assert not learner.update((2, 1), 11.0)  # equal to the best: no new policy
    assert learner.greedy_joint_action() == (0, 0)


def test_fmq_adds_the_weighted_frequency_of_the_max_reward_to_q() -> None:
    learner = RepeatedLearner(FMQConfig(alpha=0.5, weight=10.0), [2, 2], seed=0)
    learner.update((0, 0), 10.0)  # Q = 5, maxR = 10 seen 1 of 1: EV = 5 + 10 · 1 · 10 = 105
    assert learner.tables.values[0, 0] == pytest.approx(105.0)
    learner.update((0, 1), 2.0)  # Q = 3.5, maxR 10 seen 1 of 2: EV = 3.5 + 10 · 0.5 · 10
    assert learner.tables.values[0, 0] == pytest.approx(53.5)
    learner.update((0, 1), 12.0)  # a new max restarts its count: seen 1 of 3 plays
    assert learner.tables.values[0, 0] == pytest.approx(7.75 + 10 * (1 / 3) * 12)
    # agent 1's action 1: Q = 0 -> 1 -> 6.5, maxR 12 seen 1 of 2 plays
    assert learner.tables.values[1, 1] == pytest.approx(6.5 + 10 * 0.5 * 12)


def test_kk_temperature_schedule() -> None:
    assert kk_temperature(0, 500.0, 0.006) == 501.0
    assert kk_temperature(1000, 500.0, 0.006) == pytest.approx(500 * math.exp(-6) + 1)


def test_lenient_ignores_bad_news_while_hot_and_cools_each_played_action() -> None:
    config = LenientConfig(alpha=0.5, decay=0.5, max_temperature=4.0)
    learner = RepeatedLearner(config, [2, 2], seed=0)
    # the lenience draws are taken when acting: set them by hand
    learner.tables.draws[:] = [0.99, 0.0]
    learner.update((0, 0), -8.0)
    # agent 0: δ = -8 < 0, draw 0.99 >= 1 - exp(-1/4) ≈ 0.221: forgiven, Q stays 0
    # agent 1: draw 0.0 < 0.221: updated, Q = 0 + 0.5 · (-8) = -4
    assert learner.tables.values[:, 0].tolist() == [0.0, -4.0]
    assert learner.tables.temperatures[:, 0].tolist() == [2.0, 2.0]  # 4 · 0.5
    learner.tables.draws[:] = [0.99, 0.99]
    learner.update((0, 0), 6.0)  # good news is always learned: 0 + 3, -4 + 5
    assert learner.tables.values[:, 0].tolist() == [3.0, 1.0]


def test_lenience_forgives_a_decrease_with_probability_exp_of_minus_one_over_theta_t() -> None:
    """P(forgive) = exp(-1 / (θ T)): at T = 2, θ = 2 it is e^-0.25 = 0.7788, so a draw
    of 0.3 (>= 1 - 0.7788) forgives; at θ = 1 it is e^-0.5 = 0.6065 and 0.3 does not."""
    from cmarlcd.learners.tabular.lenient import is_lenient

    assert is_lenient(-1.0, 2.0, 2.0, 0.3) and not is_lenient(-1.0, 2.0, 1.0, 0.3)
    assert is_lenient(-1.0, 2.0, 2.0, 1 - math.exp(-0.25))  # the boundary draw forgives
    assert not is_lenient(+1.0, 2.0, 2.0, 0.99)  # good news is never ignored


def test_lenient_acts_greedily_once_cool() -> None:
    config = LenientConfig(max_temperature=1.0, min_temperature=2.0)
    learner = RepeatedLearner(config, [3, 3], seed=0)
    learner.tables.values[0] = [0.0, 1.0, 0.0]
    learner.tables.values[1] = [0.0, 0.0, 2.0]
    assert {learner.act() for _ in range(20)} == {(1, 2)}


def test_jal_expected_values_against_the_empirical_frequencies() -> None:
    learner = RepeatedLearner(JointActionConfig(alpha=1.0), [2, 2], seed=0)
    learner.update((0, 0), 10.0)  # Q(0,0) = 10; counts (from 1): agent 0 [2,1], agent 1 [2,1]
    learner.update((1, 1), 4.0)  # Q(1,1) = 4; counts [2,2], [2,2]
    learner.update((0, 1), 1.0)  # Q(0,1) = 1; counts agent 0 [3,2], agent 1 [2,3]
    ev = learner.tables.values
    # agent 0: EV(0) = Q(0,0) Pr_1(0) + Q(0,1) Pr_1(1) = 10 · 2/5 + 1 · 3/5 = 4.6
    #          EV(1) = Q(1,0) 2/5 + Q(1,1) 3/5 = 0 + 2.4
    assert ev[0].tolist() == pytest.approx([4.6, 2.4])
    # agent 1: EV(0) = Q(0,0) Pr_0(0) + Q(1,0) Pr_0(1) = 10 · 3/5 = 6; EV(1) = 3/5 + 4 · 2/5
    assert ev[1].tolist() == pytest.approx([6.0, 2.2])
    assert learner.greedy_joint_action() == (0, 0)


def test_jal_refuses_a_large_joint_action_space() -> None:
    with pytest.raises(ConfigError, match="at most 1,024 joint actions"):
        RepeatedLearner(JointActionConfig(), [4] * 6)


@pytest.mark.parametrize(
    ("make", "parameter"),
    [
        (lambda: IQLConfig(alpha=0.0), "alpha"),
        (lambda: HystereticConfig(alpha=0.1, beta=0.2), "beta"),
        (lambda: DistributedQConfig(epsilon=1.5), "epsilon"),
        (lambda: FMQConfig(weight=-1.0), "weight"),
        (lambda: LenientConfig(decay=0.0), "decay"),
        (lambda: JointActionConfig(decay=float("nan")), "decay"),
    ],
)
def test_bad_settings_are_rejected(make, parameter) -> None:
    with pytest.raises(ConfigError) as err:
        make()
    assert err.value.parameter == parameter


# ------------------------------------------------------- games and known results


@pytest.mark.parametrize("name", sorted(REPEATED_LEARNERS))
def test_every_learner_finds_the_optimum_of_a_trivial_game(name: str) -> None:
    """One joint action pays 1, every other 0 (the penalty-free coordination game)."""
    game = from_payoffs([[1.0, 0.0], [0.0, 0.0]])
    assert optimal_share(REPEATED_LEARNERS[name], game, 5_000, runs=10) == 1.0


@pytest.mark.parametrize("k", [0, -10, -50, -100])
def test_distributed_q_solves_the_deterministic_penalty_games(k: int) -> None:
    """Lauer & Riedmiller (2000): optimal in deterministic cooperative games."""
    assert optimal_share(DistributedQConfig(), penalty_game(k), 5_000, runs=20) == 1.0


def test_distributed_q_solves_the_climbing_game() -> None:
    assert optimal_share(DistributedQConfig(), climbing_game(), 5_000, runs=20) == 1.0


def test_distributed_qs_optimism_is_fooled_by_stochastic_payoffs() -> None:
    """(1, 1) sometimes pays 14 > 12: distributed Q learns the lucky draw."""
    for game in (partially_stochastic_climbing_game(), fully_stochastic_climbing_game()):
        assert optimal_share(DistributedQConfig(), game, 5_000, runs=20) <= 0.1


def test_fmq_solves_the_climbing_games_but_not_the_fully_stochastic_one() -> None:
    """Kapetanakis & Kudenko (2002): FMQ on the climbing and partially stochastic
    climbing games; its max-reward frequency is misled when every payoff is random."""
    assert optimal_share(FMQConfig(), climbing_game(), 5_000, runs=20) >= 0.9
    assert optimal_share(FMQConfig(), partially_stochastic_climbing_game(), 5_000, runs=20) >= 0.9
    assert optimal_share(FMQConfig(), fully_stochastic_climbing_game(), 5_000, runs=20) <= 0.5


def test_independent_learners_miss_the_climbing_games_optimum() -> None:
    """Claus & Boutilier (1998): independent learners end on a suboptimal equilibrium of
    the climbing game (the -30 penalties around the optimum drag its value down)."""
    assert optimal_share(IQLConfig(), climbing_game(), 5_000, runs=20) <= 0.3


def test_central_q_learns_the_joint_action_played_and_acts_as_one() -> None:
    learner = RepeatedLearner(CentralQConfig(alpha=0.5), [2, 3], seed=0)
    learner.update((1, 2), reward=8.0)  # flat index 1 · 3 + 2 = 5: Q = 0 + 0.5 · 8
    learner.update((0, 1), reward=-2.0)  # flat index 1: Q = -1
    assert learner.tables.values.tolist() == [0.0, -1.0, 0.0, 0.0, 0.0, 4.0]
    assert learner.greedy_joint_action() == (1, 2)
    learner.tables.plays[0] = 100_000  # cold: T = 1; e^-30 of the mass elsewhere
    learner.tables.values[5] = 30.0
    assert {learner.act() for _ in range(20)} == {(1, 2)}


def test_central_q_is_the_coordinated_reference_even_with_random_payoffs() -> None:
    """Averaging over the joint action, it learns expected payoffs: optimal on every
    climbing game, where every independent learner here fails somewhere."""
    for game in (
        climbing_game(),
        partially_stochastic_climbing_game(),
        fully_stochastic_climbing_game(),
    ):
        assert optimal_share(CentralQConfig(), game, 5_000, runs=20) >= 0.9
