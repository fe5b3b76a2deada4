"""Deep CMARL-CD's λ-returns bootstrapped from the record network (``return_lambda``): the
stored returns by hand for integer states and features, λ = 1 giving the Monte-Carlo
returns, the setting checked, and a run that learns from them end to end, the same by
seed."""

from __future__ import annotations

import numpy as np
import pytest

from cmarlcd import ConfigError
from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig
from cmarlcd.learners.deep.designs import IMITATION_DEEP_CMARLCD

pytest.importorskip("torch")

from types import SimpleNamespace

from cmarlcd.training.deep_kernels import EPISODES, FeatureData, IndexData, Weights
from cmarlcd.training.deep_replay import BOOTSTRAPPED, BootstrappedRing
from cmarlcd.training.deep_side import new_greedy_cache
from cmarlcd.training.degree_kernels import (
    features_lambda_store,
    index_lambda_store,
)

#: Rewards 1, 2, 4 at states 7, 8, 9; γ 0.5, λ 0.5; the record network's estimates 10 at
#: state 8 and 20 at state 9. Backwards: G_2 = 4; G_1 = 2 + 0.5 (0.5 · 20 + 0.5 · 4) = 8;
#: G_0 = 1 + 0.5 (0.5 · 10 + 0.5 · 8) = 5.5.
BY_HAND = [4.0, 8.0, 5.5]


def index_side(lam: float) -> tuple[IndexData, BootstrappedRing]:
    table = np.zeros(10, np.float32)
    table[8], table[9] = 10.0, 20.0
    weights = BOOTSTRAPPED.new(
        DeepCMARLCDConfig(update="imitation", return_lambda=lam), 1, np.array([3, 3]),
        SimpleNamespace(n_states=10), 0,
    )  # fmt: skip
    replay = BOOTSTRAPPED.view(weights, 0)
    replay.record_table[:] = table
    schedule = np.array(DeepCMARLCDConfig(gamma=0.5).schedule(100), np.float64)
    side = IndexData(
        np.array([3, 3]), np.zeros((10, 2, 3), np.float32), np.ones((10, 2, 3), np.bool_),
        np.zeros(10, np.bool_), np.array([7, 8, 9, 0]), np.array([[0, 1], [2, 2], [1, 0]]),
        np.array([1.0, 2.0, 4.0]), replay, np.zeros(4, np.int64), schedule, np.zeros((2, 3)),
    )  # fmt: skip
    return side, replay


def test_lambda_returns_of_integer_states_by_hand() -> None:
    side, replay = index_side(0.5)
    index_lambda_store(side, 3)
    assert replay.ring.size[0] == 3 and side.counters[EPISODES] == 1
    assert replay.ring.reward[:3].tolist() == BY_HAND
    assert replay.ring.state[:3].tolist() == [9, 8, 7]


def test_lambda_one_stores_the_monte_carlo_returns() -> None:
    """λ = 1: 1 + 0.5 · (2 + 0.5 · 4) = 3, 2 + 0.5 · 4 = 4, 4 (eq. 1), the estimates
    unread."""
    side, replay = index_side(1.0)
    index_lambda_store(side, 3)
    assert replay.ring.reward[:3].tolist() == [4.0, 4.0, 3.0]


def test_lambda_returns_of_features_by_hand() -> None:
    """One feature, the record network ReLU(x) (one hidden unit, weight 1) times 10 plus
    0: estimates 10 and 20 at features 1 and 2, the next visits' features."""
    spec = SimpleNamespace(n_states=0, own_dim=None, n_features=1, max_steps=3)
    config = DeepCMARLCDConfig(update="imitation", return_lambda=0.5, record_hidden=1)
    ring = BOOTSTRAPPED.new(config, 1, np.array([3]), spec, 1)
    w1, b1, w2, b2 = ring.record_weights[:4]
    w1[0, 0, 0], b1[0, 0], w2[0, 0, 0], b2[0, 0] = 1.0, 0.0, 10.0, 0.0
    replay = BOOTSTRAPPED.view(ring, 0)
    schedule = np.array(DeepCMARLCDConfig(gamma=0.5).schedule(100), np.float64)
    obs = np.array([[0.0], [1.0], [2.0], [0.0], [0.0]], np.float32)
    joints, rewards = np.array([[0], [2], [1]]), np.array([1.0, 2.0, 4.0])
    # the loop's own side type (a type of the tests' own would enter numba's on-disk
    # cache index, which a process without the tests could not read back)
    degrees = Weights(*(np.zeros((1, *shape), np.float32)
                        for shape in ((1, 4), (4,), (4, 3), (3,), (0, 4, 4), (0, 4))))  # fmt: skip
    side = FeatureData(
        np.array([3]), degrees, np.zeros(8, np.float32), obs, np.ones((4, 1, 3), np.bool_),
        joints, rewards, replay, np.zeros(8, np.int64), schedule, np.zeros((2, 3)),
        new_greedy_cache(SimpleNamespace(state_determines_features=False, max_steps=3), 1),
        np.zeros(1, np.int64),
    )  # fmt: skip
    features_lambda_store(side, 3)
    assert replay.ring.reward[:3].tolist() == BY_HAND
    assert replay.ring.state[:3, 0].tolist() == [2.0, 1.0, 0.0]


def test_the_setting_is_checked() -> None:
    with pytest.raises(ConfigError, match="return_lambda: must be in"):
        DeepCMARLCDConfig(update="imitation", return_lambda=1.5)
    with pytest.raises(ConfigError, match="keyed memory folds"):
        DeepCMARLCDConfig(return_lambda=0.9)
    assert DeepCMARLCDConfig(update="replayed", return_lambda=0.9).bootstraps
    assert not DeepCMARLCDConfig(update="imitation").bootstraps


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
