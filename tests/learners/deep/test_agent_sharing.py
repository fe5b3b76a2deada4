"""Parameter sharing (``share``): one agent network per seed for every agent, the agent's
one-hot index appended to its input, for VDN, QMIX, deep IQL and hysteretic DQN."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from cmarlcd.learners.deep.config import DeepConfig  # noqa: E402
from cmarlcd.learners.deep.value_decomposition import ValueDecomposition  # noqa: E402

#: Inputs laid out as [s (4), o_1 (3), o_2 (3)], as in test_value_decomposition.
STATE, OWN, AGENTS = 4, 3, 2


def seeds(*keys: int) -> list[np.random.SeedSequence]:
    return [np.random.SeedSequence(k) for k in keys]


def shared_model(mixer: str = "vdn", keys: tuple[int, ...] = (0,), **settings):
    config = DeepConfig(mixer=mixer, hidden=5, share=True, step="autograd", **settings)
    return ValueDecomposition([3, 3], STATE + AGENTS * OWN, config, seeds(*keys), own_dim=OWN)


def batch_of(count: int, generator: torch.Generator, seeds_: int = 1) -> dict:
    state = torch.randn(seeds_, count, STATE + AGENTS * OWN, generator=generator)
    return {
        "state": state,
        "actions": torch.randint(0, 3, (seeds_, count, AGENTS), generator=generator),
        "reward": torch.randn(seeds_, count, generator=generator),
        "next_state": torch.randn(seeds_, count, STATE + AGENTS * OWN, generator=generator),
        "terminal": torch.rand(seeds_, count, generator=generator) < 0.2,
    }


def test_each_agent_reads_its_own_observation_and_its_index_through_one_network() -> None:
    """Agent i's values are the shared MLP of [o_i, one-hot(i)], computed here from the
    shared weights by concatenating the inputs; the compiled loop's per-agent layers
    (the index row folded into the bias) give the same; two agents seeing the same
    observation differ only by their index."""
    model = shared_model()
    state = torch.randn(1, 6, STATE + AGENTS * OWN)
    q = model.agents(state).detach().numpy()[0]  # (6, n, A)
    first, second = model.agents.first, model.agents.second
    w1, b1 = first.weight.detach().numpy()[0], first.bias.detach().numpy()[0]
    w2, b2 = second.weight.detach().numpy()[0], second.bias.detach().numpy()[0]
    assert w1.shape == (OWN + AGENTS, 5)  # one network: the observation and the index
    x = state.numpy()[0]
    loop = [t.detach().numpy() for t in model.agents.feature_weights()]
    for i in range(AGENTS):
        own = x[:, STATE + i * OWN : STATE + (i + 1) * OWN]
        index = np.zeros((len(own), AGENTS), np.float32)
        index[:, i] = 1.0
        expected = np.maximum(np.hstack([own, index]) @ w1 + b1, 0.0) @ w2 + b2
        np.testing.assert_allclose(q[:, i], expected, rtol=1e-5, atol=1e-6)
        by_loop = np.maximum(own @ loop[0][i] + loop[1][i], 0.0) @ loop[2][i] + loop[3][i]
        np.testing.assert_allclose(by_loop, expected, rtol=1e-5, atol=1e-6)
    same = state.clone()
    same[..., STATE + OWN :] = same[..., STATE : STATE + OWN]  # o_2 := o_1
    values = model.agents(same)[0]
    assert not torch.allclose(values[:, 0], values[:, 1])  # the index tells them apart
    with torch.no_grad():
        first.weight[0, OWN:] = first.weight[0, OWN]  # the same index row for both
    values = model.agents(same)[0]
    assert torch.allclose(values[:, 0], values[:, 1])


@pytest.mark.parametrize("mixer", ["vdn", "qmix", "independent", "hysteretic"])
def test_the_shared_gradient_is_the_sum_of_the_agents_gradients(mixer: str) -> None:
    """Chain rule: per-agent networks holding the shared network's weights (each its index
    row folded into its first bias) take the same loss, and the shared network's
    gradient is theirs summed over the agents (its index rows: each agent's bias
    gradient)."""
    shared = shared_model(mixer)
    config = DeepConfig(mixer=mixer, hidden=5, step="autograd")
    apart = ValueDecomposition([3, 3], STATE + AGENTS * OWN, config, seeds(0), own_dim=OWN)
    pairs = ((shared.agents, apart.agents), (shared.target_agents, apart.target_agents))
    for source, copy in pairs:
        with torch.no_grad():
            w1, b1, w2, b2, _, _ = source.feature_weights()
            copy.first.weight.copy_(w1), copy.first.bias.copy_(b1)
            copy.second.weight.copy_(w2), copy.second.bias.copy_(b2)
    apart.mixer.load_state_dict(shared.mixer.state_dict())
    apart.target_mixer.load_state_dict(shared.target_mixer.state_dict())
    for model in (shared, apart):
        model.optimizer.step = lambda: None  # keep the gradients, move nothing
    batch = batch_of(16, torch.Generator().manual_seed(3))
    assert shared.td_step(batch) == pytest.approx(apart.td_step(batch), rel=1e-5)
    one, per = shared.agents, apart.agents

    def close(a: torch.Tensor, b: torch.Tensor) -> None:
        torch.testing.assert_close(a, b, rtol=1e-4, atol=1e-6)

    close(one.second.weight.grad[0], per.second.weight.grad.sum(0))
    close(one.second.bias.grad[0], per.second.bias.grad.sum(0))
    close(one.first.weight.grad[0, :OWN], per.first.weight.grad.sum(0))
    close(one.first.bias.grad[0], per.first.bias.grad.sum(0))
    close(one.first.weight.grad[0, OWN:], per.first.bias.grad)  # each index row: its agent's


def test_stacked_seeds_share_nothing_between_them() -> None:
    """Seed 1 of a two-seed stacked model starts and steps exactly as seed 1 alone."""
    both, alone = shared_model(keys=(0, 1)), shared_model(keys=(1,))
    for a, b in zip(both.agents.parameters(), alone.agents.parameters(), strict=True):
        assert torch.equal(a[1], b[0])
    batch = batch_of(8, torch.Generator().manual_seed(5), seeds_=2)
    both.td_step(batch)
    alone.td_step({key: value[1:] for key, value in batch.items()})
    for a, b in zip(both.agents.parameters(), alone.agents.parameters(), strict=True):
        torch.testing.assert_close(a[1], b[0], rtol=1e-5, atol=1e-7)


def test_auto_takes_autograds_step_with_sharing() -> None:
    config = DeepConfig(share=True)  # step=auto
    assert not config.auto_fuses
    model = ValueDecomposition([2, 2], 10, config, seeds(0), own_dim=3)
    assert model.fused is None


@pytest.mark.parametrize("mixer", ["vdn", "qmix", "independent", "hysteretic"])
@pytest.mark.parametrize("inputs", ["own", "integers"])
def test_the_fused_step_of_a_shared_network_is_autograds(mixer: str, inputs: str) -> None:
    """Three steps of the fused kernels and of autograd from the same weights, with the
    EPyMARL options on: the same losses and parameters to float32 rounding."""
    settings = dict(mixer=mixer, hidden=5, share=True, double_q=True, grad_clip=1.0)
    models = []
    for step in ("autograd", "fused"):
        config = DeepConfig(step=step, **settings)
        if inputs == "own":
            model = ValueDecomposition([3, 3], STATE + AGENTS * OWN, config, seeds(0, 1),
                                       own_dim=OWN)  # fmt: skip
        else:
            model = ValueDecomposition([3, 3], 7, config, seeds(0, 1))
        models.append(model)
    assert models[0].fused is None and models[1].fused is not None
    generator = torch.Generator().manual_seed(11)
    for _ in range(3):
        batch = batch_of(8, generator, seeds_=2)
        if inputs == "integers":
            batch["state"] = torch.randint(0, 7, (2, 8), generator=generator)
            batch["next_state"] = torch.randint(0, 7, (2, 8), generator=generator)
        losses = [model.td_step(batch) for model in models]
        assert losses[1] == pytest.approx(losses[0], rel=1e-4, abs=1e-6)
    for (name, a), (_, b) in zip(models[0].named_parameters(), models[1].named_parameters(),
                                 strict=True):  # fmt: skip
        torch.testing.assert_close(a, b, rtol=1e-4, atol=1e-5, msg=name)


def test_sharing_works_on_integer_states_too() -> None:
    """Integer (one-hot) states: the looked-up table equals the dense one-hot product."""
    config = DeepConfig(hidden=4, share=True, step="autograd")
    model = ValueDecomposition([2, 3], 5, config, seeds(0))
    states = torch.tensor([[0, 3, 4, 3]])
    dense = model.agents(torch.nn.functional.one_hot(states, 5).float())
    torch.testing.assert_close(model.agents(states), dense, rtol=1e-6, atol=1e-6)
