"""VDN and QMIX: mixers, masks, the ε schedule, learning a matrix game."""

from __future__ import annotations

import math

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from cmarlcd import ConfigError  # noqa: E402
from cmarlcd.learners.deep.config import DeepConfig, epsilon  # noqa: E402
from cmarlcd.learners.deep.value_decomposition import (  # noqa: E402
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


def test_the_loops_table_copy_is_the_tables_bit_for_bit() -> None:
    """What the compiled loop acts from after each gradient step (:meth:`copy_tables`, in
    scratch kept between calls) is :meth:`tables` exactly, also once the weights have
    changed since the scratch was made."""
    config = DeepConfig(mixer="vdn", hidden=9)
    model = ValueDecomposition([3, 4, 2], 7, config, seeds(3))
    agents = model.agents
    out = np.full((3, 7, 3, 4), np.nan, np.float32)
    noise = torch.Generator().manual_seed(1)
    for _ in range(3):
        agents.copy_tables(out)
        with torch.no_grad():
            expected = agents.tables().numpy()
            for p in agents.parameters():
                p.add_(torch.randn(p.shape, generator=noise))
        assert np.array_equal(out, expected)
        assert (out != agents.tables().detach().numpy()).any()  # the next call must redo it


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
        ({"gamma": -0.1}, "gamma"),
        ({"buffer_size": 10, "batch_size": 20}, "batch_size"),
        ({"lr": 0.0}, "lr"),
        ({"step": "manual"}, "step"),
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


# ----------------------------------------------------- hand-computed oracles

#: Q-values (state, agent, action) of the online and the target networks in the TD test.
ONLINE = [[[1.0, 2.0], [0.5, -1.0]], [[0.0, 3.0], [2.0, 1.0]], [[4.0, 0.0], [0.0, 0.0]]]
TARGET = [[[10.0, 20.0], [1.0, 1.0]], [[5.0, 7.0], [2.0, 8.0]], [[3.0, 9.0], [6.0, 4.0]]]


def set_q_tables(agents, q: list) -> None:
    """Make the agent networks compute ``q[s][i][a]`` exactly: the first layer copies the
    one-hot state through (hidden = n_states, ReLU of 0/1), the second holds the table."""
    table = torch.tensor(q).permute(1, 0, 2)  # (agent, state, action)
    with torch.no_grad():
        agents.first.weight.copy_(torch.eye(len(q)).expand_as(agents.first.weight))
        agents.first.bias.zero_()
        agents.second.weight.copy_(table)
        agents.second.bias.zero_()


def td_model(step: str = "autograd") -> ValueDecomposition:
    """The oracle's model, its update switched off (learning rate 0 for the fused step,
    whose Adam is its own; no optimiser step for autograd) so the gradients stay."""
    config = DeepConfig(hidden=3, gamma=0.5, step=step)
    model = ValueDecomposition([2, 2], 3, config, seeds(1))
    set_q_tables(model.agents, ONLINE)
    set_q_tables(model.target_agents, TARGET)
    model.optimizer.step = lambda: None
    if model.fused is not None:
        model.fused.rates[:] = 0.0
    return model


def second_layer_grad(model: ValueDecomposition) -> torch.Tensor:
    """The gradient of the agents' second-layer weights of the last step, either way."""
    if model.fused is not None:
        return torch.from_numpy(model.fused.agent_grads[2])
    return model.agents.second.weight.grad


def td_batch(next_legal: bool) -> dict:
    """Three transitions: (s=0, a=(1,0), r=1, s'=1); (s=1, a=(1,1), r=2, terminal);
    (s=2, a=(0,0), r=0, s'=2 where agent 0 may not play action 1)."""
    legal = torch.ones(1, 3, 2, 2, dtype=torch.bool)
    legal[0, 2, 0, 1] = False
    batch = {
        "state": torch.tensor([[0, 1, 2]]),
        "actions": torch.tensor([[[1, 0], [1, 1], [0, 0]]]),
        "reward": torch.tensor([[1.0, 2.0, 0.0]]),
        "next_state": torch.tensor([[1, 2, 2]]),
        "terminal": torch.tensor([[False, True, False]]),
    }
    if next_legal:
        batch["next_legal"] = legal
    return batch


@pytest.mark.parametrize("step", ["autograd", "fused"])
@pytest.mark.parametrize("masks", ["in the batch", "per state"])
def test_one_td_step_against_a_hand_computed_batch(masks: str, step: str) -> None:
    """Targets r + γ Σ_i max_{a legal} Q_i^target(s', a), r alone at a terminal state:
      1. Q_tot = 2 + 0.5 = 2.5; target 1 + 0.5 (7 + 8) = 8.5          -> error -6
      2. Q_tot = 3 + 1 = 4;     target 2 (terminal)                  -> error  2
      3. Q_tot = 4 + 0 = 4;     target 0 + 0.5 (3 + 6) = 4.5 (9 is illegal) -> error -0.5
    loss = (36 + 4 + 0.25) / 3; dloss/dQ_i(s, a) = 2 · error / 3 at each played (s, a)."""
    model = td_model(step)
    if masks == "per state":
        legal = torch.ones(3, 2, 2, dtype=torch.bool)
        legal[2, 0, 1] = False
        model.set_state_legal(legal)
    loss = model.td_step(td_batch(next_legal=masks == "in the batch"))
    assert loss == pytest.approx(40.25 / 3)
    grad = second_layer_grad(model)  # (agent, hidden = state, action)
    assert grad[0, 0, 1] == pytest.approx(2 * -6 / 3) and grad[1, 0, 0] == pytest.approx(-4)
    assert grad[0, 1, 1] == pytest.approx(2 * 2 / 3) and grad[1, 1, 1] == pytest.approx(4 / 3)
    assert grad[0, 2, 0] == pytest.approx(2 * -0.5 / 3) and grad[1, 2, 0] == pytest.approx(-1 / 3)
    unplayed = torch.ones_like(grad, dtype=torch.bool)
    for agent, state, action in [(0, 0, 1), (1, 0, 0), (0, 1, 1), (1, 1, 1), (0, 2, 0), (1, 2, 0)]:
        unplayed[agent, state, action] = False
    assert (grad[unplayed] == 0).all()
    assert all(p.grad is None for p in model.target_agents.parameters())


@pytest.mark.parametrize("step", ["autograd", "fused"])
def test_a_target_copy_makes_the_target_the_online_network(step: str) -> None:
    model = td_model(step)
    model.sync_target()
    # now s' = 1 bootstraps from the online values: 1 + 0.5 (3 + 2) = 3.5, and so on
    loss = model.td_step(td_batch(next_legal=True))
    errors = [2.5 - 3.5, 4 - 2, 4 - 0.5 * (4 + 0)]
    assert loss == pytest.approx(sum(e * e for e in errors) / 3)


def set_table(layer, rows: list) -> None:
    """A group layer whose output for one-hot state ``s`` is ``rows[s]`` (bias 0)."""
    with torch.no_grad():
        layer.weight.copy_(torch.tensor(rows)[None])
        layer.bias.zero_()


def test_qmix_mixes_a_hand_chosen_input() -> None:
    """Two agents, two hidden units, two states that differ only in V(s). For q = (1, -2):
    |W1| = [[1, 2], [0.5, 1]], b1 = [0.5, -1]: pre-activations [0.5, -1],
    ELU: [0.5, e^-1 - 1]; |w2| = [3, 2]: 1.5 + 2 (e^-1 - 1);
    V(0) = 2 · relu(1) + 5 · relu(-1) + 0.25 = 2.25; V(1) = 5 · relu(0.5) + 0.25 = 2.75."""
    gens = [[torch.Generator().manual_seed(k) for k in range(3)]]
    mixer = QMixer(seeds=1, n_agents=2, in_dim=2, hidden=2, generators=gens)
    w1 = [1.0, -2.0, 0.5, 1.0]  # agent 0's two weights, then agent 1's (signs: abs)
    set_table(mixer.hyper_w1, [w1, w1])
    set_table(mixer.hyper_b1, [[0.5, -1.0], [0.5, -1.0]])
    set_table(mixer.hyper_w2, [[-3.0, 2.0], [-3.0, 2.0]])
    set_table(mixer.value_1, [[1.0, -1.0], [0.0, 0.5]])
    with torch.no_grad():
        mixer.value_2.weight.copy_(torch.tensor([[[2.0], [5.0]]]))
        mixer.value_2.bias.fill_(0.25)
    q = torch.tensor([[[1.0, -2.0], [1.0, -2.0]]])
    mixed = 1.5 + 2 * (math.exp(-1) - 1)
    expected = torch.tensor([[mixed + 2.25, mixed + 2.75]])
    states = torch.tensor([[0, 1]])
    assert torch.allclose(mixer(q, states), expected)
    one_hot = torch.nn.functional.one_hot(states, 2).float()
    assert torch.allclose(mixer(q, one_hot), expected)  # the dense path too
    higher = mixer(q + torch.tensor([0.1, 0.0]), states)
    assert (higher > expected).all()  # monotone in each agent's value


@pytest.mark.parametrize("mixer", ["vdn", "qmix"])
def test_agents_read_their_own_observation_and_the_mixer_the_state(mixer: str) -> None:
    """Inputs laid out as [s (4), o_1 (3), o_2 (3)]: agent i's Q is its MLP of o_i alone
    (computed here by hand from its weights); changing s or the other agent's observation
    leaves it; QMIX's Q_tot moves with s and is what the mixer makes of s alone."""
    model = ValueDecomposition([2, 2], 10, DeepConfig(mixer=mixer, hidden=5), seeds(1), own_dim=3)
    state = torch.randn(1, 6, 10)
    q = model.agents(state)  # (1, 6, 2, 2)
    w1, b1, w2, b2, wm, _ = (t.detach().numpy() for t in model.agents.feature_weights())
    assert wm.shape[1] == 0  # one hidden layer
    x = state.numpy()[0]
    for i, own in enumerate((x[:, 4:7], x[:, 7:10])):
        expected = np.maximum(own @ w1[i] + b1[i], 0.0) @ w2[i] + b2[i]
        np.testing.assert_allclose(q[0, :, i].detach().numpy(), expected, rtol=1e-5, atol=1e-6)
    other = state.clone()
    other[..., :4] += 1.0  # another s
    other[..., 7:] += 1.0  # another o_2
    assert torch.equal(model.agents(other)[..., 0, :], q[..., 0, :])
    if mixer == "qmix":
        chosen = torch.randn(1, 6, 2)
        by_state = model.mixer(chosen, state[..., :4])
        assert torch.equal(model.mixer(chosen, model._mixer_state(state)), by_state)
        assert not torch.allclose(model.mixer(chosen, other[..., :4]), by_state)
    actions = torch.zeros(1, 6, 2, dtype=torch.int64)
    batch = {"state": state, "actions": actions, "reward": torch.zeros(1, 6),
             "next_state": state, "terminal": torch.zeros(1, 6, dtype=torch.bool)}  # fmt: skip
    assert math.isfinite(model.td_step(batch))


def test_own_observations_need_a_feature_state_that_holds_them() -> None:
    from cmarlcd.learners.deep.agent import DeepAgent

    with pytest.raises(ConfigError, match="own_dim"):
        DeepAgent([2, 2], DeepConfig(), 10, state_dim=5, own_dim=3)
    with pytest.raises(ConfigError, match="own_dim"):
        DeepAgent([2, 2], DeepConfig(), 10, n_states=5, own_dim=1)
