"""Deep learners on their own observations in the compiled loop (``GameSpec.own_dim``,
``games/observations.py``): the features laid out as ``[s, o_1, ..., o_n]``, each
agent's network reading its own, and the compiled greedy action the networks' own."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from cmarlcd.errors import ConfigError  # noqa: E402
from cmarlcd.games.foraging import Foraging  # noqa: E402
from cmarlcd.games.observations import own_observations  # noqa: E402
from cmarlcd.games.spread import SimpleSpread  # noqa: E402
from cmarlcd.learners.deep.config import DeepConfig  # noqa: E402
from cmarlcd.training import deep_kernels  # noqa: E402
from cmarlcd.training.deep import DeepBatch  # noqa: E402

SMALL = dict(buffer_size=400, batch_size=16, train_every=25, target_every=100)
RULES = SimpleSpread(N=3)
SPEC = own_observations(RULES.spec(), RULES.observation_size)


def test_the_features_are_the_observations_twice() -> None:
    base = RULES.spec()
    env, rng = base.new_env(), np.random.default_rng(0)
    base.kernels.reset(env, rng)
    joined = np.zeros(base.n_features, np.float32)
    both = np.zeros(SPEC.n_features, np.float32)
    base.kernels.features(env, 0, joined)
    SPEC.kernels.features(env, 0, both)
    assert SPEC.own_dim == RULES.observation_size and SPEC.n_features == 2 * base.n_features
    assert np.array_equal(both, np.concatenate([joined, joined]))


def test_a_game_whose_features_are_not_observations_is_refused() -> None:
    with pytest.raises(ConfigError):
        own_observations(RULES.spec(), RULES.observation_size + 1)


@pytest.mark.parametrize("mixer", ["vdn", "qmix"])
def test_each_agent_acts_on_its_own_observation_as_its_network_does(mixer) -> None:
    batch = DeepBatch(SPEC, DeepConfig(mixer=mixer, **SMALL), [np.random.SeedSequence(1)], 30)
    batch.train([30], lambda *_: None)
    model, side = batch.model, batch.group.views[0].data
    assert model.agents.own_dim == RULES.observation_size
    assert side.weights.w1.shape[1] == RULES.observation_size
    assert side.starts.tolist() == [SPEC.n_features - (3 - i) * SPEC.own_dim for i in range(3)]
    rng = np.random.default_rng(3)
    features = rng.normal(size=(100, SPEC.n_features)).astype(np.float32)
    legal = np.ones((100, 3, 5), dtype=np.bool_)
    expected = model.greedy(torch.from_numpy(features)[None], torch.from_numpy(legal)[None])
    hidden = np.zeros(model.agents.first.weight.shape[-1], np.float32)
    for n in range(100):
        for i in range(3):
            action = deep_kernels.greedy_agent_at(
                side.weights, i, features[n], int(side.starts[i]), legal[n, i], 5, hidden
            )
            assert action == int(expected[0, n, i])
    # an agent's action does not move when another agent's own observation does
    changed = features.copy()
    changed[:, side.starts[1] : side.starts[1] + SPEC.own_dim] += 5.0
    again = model.greedy(torch.from_numpy(changed)[None], torch.from_numpy(legal)[None])
    assert torch.equal(again[0, :, 0], expected[0, :, 0])


def test_lbf_with_own_observations_learns_in_the_compiled_loop() -> None:
    rules = Foraging(5, 2, 1)
    spec = own_observations(rules.spec(), rules.observation_size)
    batch = DeepBatch(spec, DeepConfig(**SMALL), [np.random.SeedSequence(k) for k in range(2)], 40)
    points = []
    batch.train([20, 40], lambda k, point, policy: points.append((k, point)))
    assert sorted(points) == [(0, 20), (0, 40), (1, 20), (1, 40)]
    assert all(play.episodes == 40 for play in batch.plays)


def test_deep_cmarl_cd_s_compiled_degrees_read_each_agent_s_own_observation() -> None:
    """Deep CMARL-CD on own observations (the degree networks; the record network and the
    memory read the whole input): the compiled loop's degrees of each agent, read from its
    own observation, are the model's to float32 rounding, and an agent's degrees do not
    move when another agent's observation does."""
    from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig
    from cmarlcd.training.degree_kernels import agent_degrees

    config = DeepCMARLCDConfig(buffer_size=400, batch_size=16)
    batch = DeepBatch(SPEC, config, [np.random.SeedSequence(1)], 30)
    batch.train([30], lambda *_: None)
    view = batch.group.views[0]
    model, side = view.model, view.data
    assert model.agents.own_dim == RULES.observation_size and model.fused is not None
    assert side.weights.w1.shape[1] == RULES.observation_size
    assert side.starts.tolist() == [SPEC.n_features - (3 - i) * SPEC.own_dim for i in range(3)]
    features = np.random.default_rng(3).normal(size=(50, SPEC.n_features)).astype(np.float32)
    with torch.no_grad():
        degrees = model.agents(torch.from_numpy(features)[None])[0].numpy()
    out = np.zeros(5)
    for n in range(50):
        for i in range(3):
            agent_degrees(side.weights, i, features[n], side.starts[i], 5, side.hidden, out)
            assert out == pytest.approx(degrees[n, i], abs=1e-5)
    changed = features.copy()
    changed[:, side.starts[1] : side.starts[1] + SPEC.own_dim] += 5.0
    with torch.no_grad():
        again = model.agents(torch.from_numpy(changed)[None])[0]
    assert torch.equal(again[:, 0], model.agents(torch.from_numpy(features)[None])[0][:, 0])
    assert not torch.equal(again[:, 1], model.agents(torch.from_numpy(features)[None])[0][:, 1])


def test_deep_cmarl_cd_s_object_api_reads_own_observations() -> None:
    from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig
    from cmarlcd.learners.deep.degree_agent import DegreeAgent

    agent = DegreeAgent([3, 3], DeepCMARLCDConfig(), 10, state_dim=7, own_dim=2, seed=0)
    state = np.arange(7, dtype=np.float32)
    other = state.copy()
    other[5:] += 4.0  # agent 1's own observation, the last two features
    assert np.array_equal(agent.degrees(state)[0], agent.degrees(other)[0])
    assert not np.array_equal(agent.degrees(state)[1], agent.degrees(other)[1])
    with pytest.raises(ConfigError, match="own_dim"):
        DegreeAgent([3, 3], DeepCMARLCDConfig(), 10, state_dim=4, own_dim=2, seed=0)
