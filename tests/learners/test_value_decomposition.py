"""VDN and QMIX (SPEC §4): mixers, masks, the ε schedule, learning a matrix game."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from cmarlcd import ConfigError  # noqa: E402
from cmarlcd.learners.deep_config import DeepConfig, epsilon  # noqa: E402
from cmarlcd.learners.value_decomposition import (  # noqa: E402
    QMixer,
    ValueDecomposition,
    VDNMixer,
)


def seeds(count: int) -> list[np.random.SeedSequence]:
    return [np.random.SeedSequence(k) for k in range(count)]


def test_vdn_sums_the_agent_values() -> None:
    q = torch.randn(2, 5, 3)
    assert torch.allclose(VDNMixer()(q, torch.zeros(2, 5, dtype=torch.int64)), q.sum(-1))


@pytest.mark.parametrize("integer_states", [True, False])
def test_qmix_is_monotone_in_every_agent_value(integer_states: bool) -> None:
    gens = [[torch.Generator().manual_seed(k + 10 * b) for k in range(4)] for b in range(2)]
    mixer = QMixer(seeds=2, n_agents=3, in_dim=6, hidden=8, generators=gens)
    q = torch.randn(2, 50, 3, requires_grad=True)
    state = torch.randint(0, 6, (2, 50)) if integer_states else torch.randn(2, 50, 6)
    mixer(q, state).sum().backward()
    assert (q.grad >= 0).all() and (q.grad > 0).any()


def test_one_hot_lookup_equals_the_dense_product() -> None:
    gens = [[torch.Generator().manual_seed(k) for k in range(4)]]
    mixer = QMixer(seeds=1, n_agents=3, in_dim=6, hidden=8, generators=gens)
    q, state = torch.randn(1, 20, 3), torch.randint(0, 6, (1, 20))
    one_hot = torch.nn.functional.one_hot(state, 6).float()
    assert torch.allclose(mixer(q, state), mixer(q, one_hot), atol=1e-6)


def test_eq_18_epsilon_schedule() -> None:
    cfg = DeepConfig()
    # L = 100: annealed over 0.8 L = 80 episodes from 1.0 to 0.0, then 0.01
    assert epsilon(1, 100, cfg) == pytest.approx(1 - 1 / 80)
    assert epsilon(40, 100, cfg) == pytest.approx(0.5)
    assert epsilon(80, 100, cfg) == pytest.approx(0.0)
    assert epsilon(81, 100, cfg) == 0.01 and epsilon(100, 100, cfg) == 0.01


def test_illegal_actions_are_never_greedy_nor_bootstrapped() -> None:
    model = ValueDecomposition([3, 2], 1, DeepConfig(gamma=1.0), seeds(1))
    with torch.no_grad():  # make action 2 of agent 0 by far the best
        model.agents.second.bias[0, 2] = 100.0
        model.target_agents.second.bias[0, 2] = 100.0
    state = torch.zeros(1, 1, dtype=torch.int64)
    legal = torch.tensor([[[True, True, False], [True, True, False]]])
    assert model.greedy(state)[0, 0, 0] == 2
    assert model.greedy(state, legal)[0, 0, 0] != 2
    # padded action 2 of agent 1 (it has 2 actions) is never chosen either
    with torch.no_grad():
        model.agents.second.bias[1, 2] = 100.0
    assert model.greedy(state)[0, 0, 1] != 2
    # TD target: bootstrapped from the best *legal* target value
    next_q = model._masked(model.target_agents(state), legal)
    assert next_q.max(dim=-1).values.max() < 50


def test_vdn_finds_the_optimum_of_a_cooperative_matrix_game() -> None:
    """One state, two agents, payoff [[10, 0, 0], [0, 2, 0], [0, 0, 5]], uniform play."""
    payoff = torch.tensor([[10.0, 0, 0], [0, 2, 0], [0, 0, 5]])
    model = ValueDecomposition([3, 3], 1, DeepConfig(lr=0.01), seeds(1))
    gen = torch.Generator().manual_seed(0)
    for _ in range(300):
        actions = torch.randint(0, 3, (1, 64, 2), generator=gen)
        model.td_step(
            {
                "state": torch.zeros(1, 64, dtype=torch.int64),
                "actions": actions,
                "reward": payoff[actions[..., 0], actions[..., 1]],
                "next_state": torch.zeros(1, 64, dtype=torch.int64),
                "next_legal": torch.ones(1, dtype=torch.bool),
                "terminal": torch.ones(1, 64, dtype=torch.bool),
            }
        )
    assert model.greedy(torch.zeros(1, 1, dtype=torch.int64))[0, 0].tolist() == [0, 0]


def test_batched_seeds_have_independent_parameters() -> None:
    alone = ValueDecomposition([2, 3], 4, DeepConfig(mixer="qmix"), seeds(3)[2:])
    batch = ValueDecomposition([2, 3], 4, DeepConfig(mixer="qmix"), seeds(3))
    for (name, a), (_, b) in zip(alone.named_parameters(), batch.named_parameters(), strict=True):
        width = a.shape[0]
        assert torch.equal(a, b[-width:]), name


@pytest.mark.parametrize(
    ("kwargs", "parameter"),
    [
        ({"mixer": "sum"}, "mixer"),
        ({"batch_size": 0}, "batch_size"),
        ({"gamma": 0.0}, "gamma"),
        ({"buffer_size": 10, "batch_size": 20}, "batch_size"),
        ({"lr": 0.0}, "lr"),
    ],
)
def test_bad_deep_config(kwargs: dict, parameter: str) -> None:
    with pytest.raises(ConfigError) as info:
        DeepConfig(**kwargs)
    assert info.value.parameter == parameter


@pytest.mark.parametrize("mixer", ["vdn", "qmix"])
def test_integer_state_fast_path_trains_like_the_one_hot_product(mixer: str) -> None:
    """Integer states take table lookups, QMIX's embedding bag and a cached target table;
    one-hot feature vectors take the plain dense products. Same seeds, same batches:
    the same losses and parameters, also across a target copy."""
    n_states, cfg = 5, DeepConfig(mixer=mixer, hidden=6, mixer_hidden=4, gamma=0.9)
    fast = ValueDecomposition([2, 3, 2], n_states, cfg, seeds(2))
    dense = ValueDecomposition([2, 3, 2], n_states, cfg, seeds(2))
    gen = torch.Generator().manual_seed(1)

    def one_hot(state: torch.Tensor) -> torch.Tensor:
        return torch.nn.functional.one_hot(state, n_states).float()

    for step in range(4):
        state = torch.randint(0, n_states, (2, 30), generator=gen)
        batch = {
            "state": state,
            "actions": torch.randint(0, 2, (2, 30, 3), generator=gen),
            "reward": torch.randn(2, 30, generator=gen),
            "next_state": torch.randint(0, n_states, (2, 30), generator=gen),
            "terminal": torch.rand(2, 30, generator=gen) < 0.2,
        }
        dense_batch = batch | {"state": one_hot(state), "next_state": one_hot(batch["next_state"])}
        assert fast.td_step(batch) == pytest.approx(dense.td_step(dense_batch), rel=1e-5)
        if step == 1:
            fast.sync_target(), dense.sync_target()
    for (name, a), (_, b) in zip(fast.named_parameters(), dense.named_parameters(), strict=True):
        assert torch.allclose(a, b, atol=1e-5), name
