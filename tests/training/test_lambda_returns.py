"""Deep CMARL-CD's λ-returns bootstrapped from the record network (``return_lambda``): the
stored returns by hand for integer states and features, a cut episode's bootstrapped
from the state it was cut in (``truncation="bootstrap"``) and a terminated one's not, λ = 1
giving the Monte-Carlo returns, the settings checked, and a run that learns from them end
to end, the same by seed."""

from __future__ import annotations

import numpy as np
import pytest

from cmarlcd import ConfigError
from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig
from cmarlcd.learners.deep.designs import IMITATION_DEEP_CMARLCD

pytest.importorskip("torch")

from types import SimpleNamespace

from cmarlcd.training.deep_kernels import (
    ENDED_TERMINAL,
    EPISODES,
    FeatureData,
    IndexData,
    Weights,
)
from cmarlcd.training.deep_replay import BOOTSTRAPPED, BootstrappedRing
from cmarlcd.training.deep_side import new_greedy_cache
from cmarlcd.training.degree_kernels import (
    count_turn,
    features_lambda_store,
    index_lambda_store,
)

#: Rewards 1, 2, 4 at states 7, 8, 9; γ 0.5, λ 0.5; the record network's estimates 10 at
#: state 8 and 20 at state 9. Backwards: G_2 = 4; G_1 = 2 + 0.5 (0.5 · 20 + 0.5 · 4) = 8;
#: G_0 = 1 + 0.5 (0.5 · 10 + 0.5 · 8) = 5.5.
BY_HAND = [4.0, 8.0, 5.5]
#: The same episode cut in state 6, whose estimate is 40, with ``truncation="bootstrap"``:
#: G_2 = 4 + 0.5 · 40 = 24; G_1 = 2 + 0.5 (0.5 · 20 + 0.5 · 24) = 13;
#: G_0 = 1 + 0.5 (0.5 · 10 + 0.5 · 13) = 6.75.
CUT_BY_HAND = [24.0, 13.0, 6.75]


def schedule(truncation: str = "terminal") -> np.ndarray:
    """γ 0.5, and what a cut episode's λ-returns end in."""
    config = DeepCMARLCDConfig(
        update="imitation", return_lambda=0.5, gamma=0.5, truncation=truncation
    )
    return np.array(config.schedule(100), np.float64)


def index_side(lam: float, truncation: str = "terminal") -> tuple[IndexData, BootstrappedRing]:
    """States 7, 8, 9 visited, the episode ended in state 6 (estimate 40)."""
    table = np.zeros(10, np.float32)
    table[8], table[9], table[6] = 10.0, 20.0, 40.0
    weights = BOOTSTRAPPED.new(
        DeepCMARLCDConfig(update="imitation", return_lambda=lam), 1, np.array([3, 3]),
        SimpleNamespace(n_states=10), 0,
    )  # fmt: skip
    replay = BOOTSTRAPPED.view(weights, 0)
    replay.record_table[:] = table
    side = IndexData(
        np.array([3, 3]), np.zeros((10, 2, 3), np.float32), np.ones((10, 2, 3), np.bool_),
        np.zeros(10, np.bool_), np.array([7, 8, 9, 6]), np.array([[0, 1], [2, 2], [1, 0]]),
        np.array([1.0, 2.0, 4.0]), replay, np.zeros(8, np.int64), schedule(truncation),
        np.zeros((2, 3)),
    )  # fmt: skip
    return side, replay


def test_lambda_returns_of_integer_states_by_hand() -> None:
    side, replay = index_side(0.5)
    index_lambda_store(side, 3)
    assert replay.ring.size[0] == 3 and side.counters[EPISODES] == 1
    assert replay.ring.reward[:3].tolist() == BY_HAND
    assert replay.ring.state[:3].tolist() == [9, 8, 7]


@pytest.mark.parametrize("ended_terminal", [0, 1])
def test_a_cut_episode_bootstraps_from_the_state_it_was_cut_in(ended_terminal: int) -> None:
    """With ``truncation="bootstrap"`` an episode whose last turn did not end in a
    terminal state (the loop's observe keeps it) ends in the estimate of the state it was
    cut in: :data:`CUT_BY_HAND`; one that terminated ends in nothing: :data:`BY_HAND`."""
    side, replay = index_side(0.5, "bootstrap")
    side.counters[ENDED_TERMINAL] = ended_terminal
    index_lambda_store(side, 3)
    assert replay.ring.reward[:3].tolist() == (BY_HAND if ended_terminal else CUT_BY_HAND)
    assert replay.ring.terminal[:3].tolist() == [True, False, False]  # the episode's end


def test_a_cut_episode_ends_in_nothing_by_default() -> None:
    side, replay = index_side(0.5)
    index_lambda_store(side, 3)  # cut (ENDED_TERMINAL 0), truncation "terminal"
    assert replay.ring.reward[:3].tolist() == BY_HAND


def test_the_loops_observe_keeps_whether_a_turn_ended_in_a_terminal_state() -> None:
    side, _ = index_side(0.5)
    count_turn(side, 0, 8, True)
    assert side.counters[ENDED_TERMINAL] == 1
    count_turn(side, 1, 9, False)
    assert side.counters[ENDED_TERMINAL] == 0


def test_lambda_one_stores_the_monte_carlo_returns() -> None:
    """λ = 1: 1 + 0.5 · (2 + 0.5 · 4) = 3, 2 + 0.5 · 4 = 4, 4 (eq. 1), the estimates
    unread."""
    side, replay = index_side(1.0)
    index_lambda_store(side, 3)
    assert replay.ring.reward[:3].tolist() == [4.0, 4.0, 3.0]


@pytest.mark.parametrize("truncation", ["terminal", "bootstrap"])
def test_lambda_returns_of_features_by_hand(truncation: str) -> None:
    """One feature, the record network ReLU(x) (one hidden unit, weight 1) times 10 plus
    0: estimates 10 and 20 at features 1 and 2, the next visits' features, and 40 at
    feature 4, the state the episode was cut in."""
    spec = SimpleNamespace(n_states=0, own_dim=None, n_features=1, max_steps=3)
    config = DeepCMARLCDConfig(update="imitation", return_lambda=0.5, record_hidden=1)
    ring = BOOTSTRAPPED.new(config, 1, np.array([3]), spec, 1)
    w1, b1, w2, b2 = ring.record_weights[:4]
    w1[0, 0, 0], b1[0, 0], w2[0, 0, 0], b2[0, 0] = 1.0, 0.0, 10.0, 0.0
    replay = BOOTSTRAPPED.view(ring, 0)
    obs = np.array([[0.0], [1.0], [2.0], [4.0], [0.0]], np.float32)
    joints, rewards = np.array([[0], [2], [1]]), np.array([1.0, 2.0, 4.0])
    # the loop's own side type (a type of the tests' own would enter numba's on-disk
    # cache index, which a process without the tests could not read back)
    degrees = Weights(*(np.zeros((1, *shape), np.float32)
                        for shape in ((1, 4), (4,), (4, 3), (3,), (0, 4, 4), (0, 4))))  # fmt: skip
    side = FeatureData(
        np.array([3]), degrees, np.zeros(8, np.float32), obs, np.ones((4, 1, 3), np.bool_),
        joints, rewards, replay, np.zeros(8, np.int64), schedule(truncation), np.zeros((2, 3)),
        new_greedy_cache(SimpleNamespace(state_determines_features=False, max_steps=3), 1),
        np.zeros(1, np.int64),
    )  # fmt: skip
    features_lambda_store(side, 3)
    assert replay.ring.reward[:3].tolist() == (
        CUT_BY_HAND if truncation == "bootstrap" else BY_HAND
    )
    assert replay.ring.state[:3, 0].tolist() == [2.0, 1.0, 0.0]


def test_the_setting_is_checked() -> None:
    with pytest.raises(ConfigError, match="return_lambda: must be in"):
        DeepCMARLCDConfig(update="imitation", return_lambda=1.5)
    with pytest.raises(ConfigError, match="keyed memory folds"):
        DeepCMARLCDConfig(return_lambda=0.9)
    assert DeepCMARLCDConfig(update="replayed", return_lambda=0.9).bootstraps
    assert not DeepCMARLCDConfig(update="imitation").bootstraps
    with pytest.raises(ConfigError, match="truncation: 'bootstrap' is for λ-returns"):
        DeepCMARLCDConfig(truncation="bootstrap")  # the keyed memory: Monte-Carlo returns
    with pytest.raises(ConfigError, match="truncation: 'bootstrap' is for λ-returns"):
        DeepCMARLCDConfig(
            update="imitation", return_lambda=0.9, refresh_returns=True, truncation="bootstrap"
        )
    with pytest.raises(ConfigError, match="truncation: must be one of"):
        DeepCMARLCDConfig(update="imitation", return_lambda=0.9, truncation="cut")


def test_a_run_on_lambda_returns_is_the_same_by_seed() -> None:
    """End to end on LBF's features: the loop copies the record network after its
    steps and stores λ-returns; two runs of one seed learn the same weights."""
    from dataclasses import replace

    from cmarlcd.experiments import games
    from cmarlcd.training.deep import DeepBatch

    spec = games.parse_game("foraging:5x5-2p-1f")[1].spec()
    config = replace(IMITATION_DEEP_CMARLCD, return_lambda=0.8, batch_size=64, buffer_size=2000)

    def weights() -> list:
        run = DeepBatch(spec, config, [np.random.SeedSequence(3)], 60)
        run.train([], lambda *args: None)
        copy, record = run.group.ring.record_weights, run.group.model.record_weights()
        assert np.array_equal(copy.w1, record[0].detach().numpy())  # refreshed after steps
        assert np.abs(copy.w1).sum() > 0
        return [p.detach().clone() for p in run.group.model.parameters()]

    first, second = weights(), weights()
    assert all((a == b).all() for a, b in zip(first, second, strict=True))


def test_the_object_api_stores_the_same_lambda_returns() -> None:
    """``DegreeAgent`` (any PettingZoo environment): the same episode and estimates as
    :data:`BY_HAND` (the record network set to 10 at state 8 and 20 at state 9)."""
    import torch

    from cmarlcd.learners.deep.degree_agent import DegreeAgent

    config = DeepCMARLCDConfig(update="imitation", return_lambda=0.5, gamma=0.5, batch_size=8)
    agent = DegreeAgent([3, 3], config, 10, n_states=10, seed=0)
    with torch.no_grad():
        record = agent.model.record
        record.first.weight.zero_(), record.second.weight.zero_()
        record.first.bias.fill_(1.0)  # a hidden unit of 1 reads the second layer's row
        record.first.weight[0, 8, 0], record.first.weight[0, 9, 0] = 9.0, 19.0
        record.second.bias.zero_()
        record.second.weight[0, 0, 0] = 1.0  # R(s) = hidden unit 0: 10 at 8, 20 at 9
    for state, joint, reward in ((7, (0, 1), 1.0), (8, (2, 2), 2.0), (9, (1, 0), 4.0)):
        agent.observe(state, joint, reward)
    agent.end_episode()
    assert agent.ring.reward[0, :3].tolist() == BY_HAND


@pytest.mark.parametrize("terminated", [False, True])
def test_the_object_api_bootstraps_a_cut_episode(terminated: bool) -> None:
    """The same episode ended in state 6 (estimate 40): cut (``terminated`` false),
    :data:`CUT_BY_HAND`; terminated, :data:`BY_HAND`."""
    import torch

    from cmarlcd.learners.deep.degree_agent import DegreeAgent

    config = DeepCMARLCDConfig(
        update="imitation", return_lambda=0.5, gamma=0.5, batch_size=8, truncation="bootstrap"
    )
    agent = DegreeAgent([3, 3], config, 10, n_states=10, seed=0)
    with torch.no_grad():
        record = agent.model.record
        record.first.weight.zero_(), record.second.weight.zero_()
        record.first.bias.fill_(1.0)
        record.first.weight[0, 8, 0], record.first.weight[0, 9, 0] = 9.0, 19.0
        record.first.weight[0, 6, 0] = 39.0
        record.second.bias.zero_()
        record.second.weight[0, 0, 0] = 1.0  # R(s) = hidden unit 0: 10, 20, 40 at 8, 9, 6
    for state, joint, reward in ((7, (0, 1), 1.0), (8, (2, 2), 2.0), (9, (1, 0), 4.0)):
        agent.observe(state, joint, reward)
    agent.end_episode(final_state=6, terminated=terminated)
    assert agent.ring.reward[0, :3].tolist() == (BY_HAND if terminated else CUT_BY_HAND)


@pytest.mark.parametrize("truncation", ["terminal", "bootstrap"])
def test_the_loop_bootstraps_simple_spreads_cut_episodes(truncation: str) -> None:
    """simple_spread cuts every episode at 25 steps: the last visit of each stores its
    reward alone with ``"terminal"``, and its reward plus γ times an estimate (not 0 once
    the networks have moved) with ``"bootstrap"``."""
    from dataclasses import replace

    from cmarlcd.experiments import games
    from cmarlcd.learners.deep.designs import SHARES_RANGE_DEEP_CMARLCD
    from cmarlcd.training.deep import DeepBatch

    spec = games.parse_game("simple_spread")[1].spec()
    config = replace(
        SHARES_RANGE_DEEP_CMARLCD, truncation=truncation, batch_size=32, buffer_size=2_000
    )
    run = DeepBatch(spec, config, [np.random.SeedSequence(5)], 40)
    run.train([], lambda *args: None)
    ring, step_reward = run.group.ring.ring, run.group.ring.step_reward[0]
    last = np.flatnonzero(ring.terminal[0, : ring.size[0]])
    assert last.size == 40  # every episode's last visit
    gap = ring.reward[0, last] - step_reward[last]
    if truncation == "terminal":
        assert np.array_equal(ring.reward[0, last], step_reward[last])
    else:
        assert np.all(gap[-10:] != 0)  # γ R(s_T), the networks trained by then
