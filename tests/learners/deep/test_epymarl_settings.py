"""EPyMARL's optional parts of the deep learners' TD step (double Q, standardised
rewards, each seed's gradient norm clipped, ε annealed over a number of steps), each
against a hand-computed case."""

from __future__ import annotations

import math

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from cmarlcd import ConfigError  # noqa: E402
from cmarlcd.learners.deep.config import DeepConfig, epsilon  # noqa: E402
from cmarlcd.learners.deep.td_options import RewardStatistics  # noqa: E402
from cmarlcd.learners.deep.value_decomposition import ValueDecomposition  # noqa: E402

#: Q-values (state, agent, action) of the online and target networks (the VDN oracle's of
#: test_value_decomposition.py, where the online and target greedy actions differ).
ONLINE = [[[1.0, 2.0], [0.5, -1.0]], [[0.0, 3.0], [2.0, 1.0]], [[4.0, 0.0], [0.0, 0.0]]]
TARGET = [[[10.0, 20.0], [1.0, 1.0]], [[5.0, 7.0], [2.0, 8.0]], [[3.0, 9.0], [6.0, 4.0]]]


def set_q_tables(agents, q: list) -> None:
    """The agent networks compute ``q[s][i][a]`` exactly, for every seed."""
    table = torch.tensor(q).permute(1, 0, 2)
    with torch.no_grad():
        agents.first.weight.copy_(torch.eye(len(q)).expand_as(agents.first.weight))
        agents.first.bias.zero_()
        agents.second.weight.copy_(table.repeat(agents.seeds, 1, 1))
        agents.second.bias.zero_()


def model_of(seeds: int = 1, **settings) -> ValueDecomposition:
    config = DeepConfig(hidden=3, gamma=0.5, **settings)
    model = ValueDecomposition([2, 2], 3, config, [np.random.SeedSequence(k) for k in range(seeds)])
    set_q_tables(model.agents, ONLINE)
    set_q_tables(model.target_agents, TARGET)
    model.optimizer.step = lambda: None  # keep the gradients, move nothing
    return model


def batch(rewards: list[list[float]], next_legal: bool = True) -> dict:
    """Per seed: (s=0, a=(1,0), s'=1); (s=1, a=(1,1), terminal); (s=2, a=(0,0), s'=2,
    where agent 0 may not play action 1), with the given rewards."""
    seeds = len(rewards)
    out = {
        "state": torch.tensor([[0, 1, 2]] * seeds),
        "actions": torch.tensor([[[1, 0], [1, 1], [0, 0]]] * seeds),
        "reward": torch.tensor(rewards),
        "next_state": torch.tensor([[1, 2, 2]] * seeds),
        "terminal": torch.tensor([[False, True, False]] * seeds),
    }
    if next_legal:
        legal = torch.ones(seeds, 3, 2, 2, dtype=torch.bool)
        legal[:, 2, 0, 1] = False
        out["next_legal"] = legal
    return out


def second_layer_grad(model: ValueDecomposition) -> np.ndarray:
    """The gradient of the agents' second layer (agent, hidden, action), from either step."""
    if model.fused is not None:
        return model.fused.agent_grads[2]
    return model.agents.second.weight.grad.numpy()


@pytest.mark.parametrize("step", ["autograd", "fused"])
@pytest.mark.parametrize("masks", ["in the batch", "per state"])
def test_double_q_values_the_online_choice_with_the_target_networks(masks: str, step: str) -> None:
    """VDN, γ = 0.5; the online networks choose each agent's next action, the target
    networks value it:
      1. s' = 1: online (0, 3) -> 1, (2, 1) -> 0; target 7 + 2; Q_tot 2.5,
         target 1 + 0.5·9 = 5.5                                        -> error −3
      2. terminal: Q_tot 4, target 2                                   -> error  2
      3. s' = 2: online (4, ·) -> 0 (1 illegal), (0, 0) -> 0; target 3 + 6; Q_tot 4,
         target 0 + 0.5·9 = 4.5                                        -> error −0.5
    loss (9 + 4 + 0.25) / 3 (without double Q, 40.25 / 3: the target's own 7 + 8)."""
    model = model_of(double_q=True, step=step)
    assert (model.fused is not None) == (step == "fused")
    if masks == "per state":
        legal = torch.ones(3, 2, 2, dtype=torch.bool)
        legal[2, 0, 1] = False
        model.set_state_legal(legal)
    loss = model.td_step(batch([[1.0, 2.0, 0.0]], next_legal=masks == "in the batch"))
    assert loss == pytest.approx(13.25 / 3)
    grad = second_layer_grad(model)  # (agent, hidden = state, action)
    assert grad[0, 0, 1] == pytest.approx(2 * -3 / 3) and grad[1, 0, 0] == pytest.approx(-2)


@pytest.mark.parametrize("step", ["autograd", "fused"])
def test_double_q_follows_the_online_networks_as_they_learn(step: str) -> None:
    """The online choice is read at every step, not kept with the target values: after
    the online values of s' = 1 change so that agent 0 prefers action 0, its next value
    is the target's 5, not 7. (A learning rate of 1e-9: the fused step's Adam moves the
    weights by about that, far below the tolerance.)"""
    model = model_of(double_q=True, step=step, lr=1e-9)
    model.set_state_legal(torch.ones(3, 2, 2, dtype=torch.bool))
    one = batch([[1.0, 2.0, 0.0]], next_legal=False)
    first = model.td_step(one)
    with torch.no_grad():
        model.agents.second.weight[0, 1] = torch.tensor([9.0, 3.0])  # agent 0 at state 1
    second = model.td_step(one)
    # transition 1's target 1 + 0.5 (5 + 2) = 4.5 (error −2); the others as before, but
    # transition 3 is s'=2 with every action legal: online (4, 0) -> 0, target 3 + 6
    assert first == pytest.approx((9 + 4 + 0.25) / 3)
    assert second == pytest.approx((4 + 4 + 0.25) / 3)


def test_standardised_rewards_follow_epymarls_running_statistics() -> None:
    """One batch (1, 2, 3) from the start (count 1e-4, mean 0, variance 1): its mean 2 and
    unbiased variance 1 pooled with the start's by the parallel rule,
      count = 3.0001, mean = 2·3 / 3.0001,
      var = (1·1e-4 + 1·3 + 2²·1e-4·3 / 3.0001) / 3.0001,
    and the rewards returned as (r − mean) / sqrt(var). Seed 1's statistics are its own."""
    stats = RewardStatistics(2, torch.device("cpu"))
    out = stats.standardise(torch.tensor([[1.0, 2.0, 3.0], [5.0, 5.0, 5.0]]))
    count = 3.0001
    mean = 6 / count
    var = (1e-4 + 3 + 4 * 3e-4 / count) / count
    assert stats.mean[0].item() == pytest.approx(mean, rel=1e-6)
    assert stats.var[0].item() == pytest.approx(var, rel=1e-6)
    expected = [(r - mean) / math.sqrt(var) for r in (1, 2, 3)]
    assert out[0].tolist() == pytest.approx(expected, rel=1e-5, abs=1e-6)
    # seed 1: mean 15 / 3.0001, variance (1e-4 + 0 + 25·3e-4 / 3.0001) / 3.0001
    assert stats.mean[1].item() == pytest.approx(15 / count, rel=1e-6)
    assert stats.var[1].item() == pytest.approx((1e-4 + 25 * 3e-4 / count) / count, rel=1e-5)


@pytest.mark.parametrize("step", ["autograd", "fused"])
def test_a_td_step_with_standardised_rewards_learns_from_the_standardised_rewards(
    step: str,
) -> None:
    """The step's loss is the plain step's on the rewards standardised by hand."""
    rewards = [[1.0, 2.0, 3.0]]
    with_stats = model_of(standardise_rewards=True, step=step)
    plain = model_of(step=step)
    count, mean = 3.0001, 6 / 3.0001
    var = (1e-4 + 3 + 4 * 3e-4 / count) / count
    by_hand = [[(r - mean) / math.sqrt(var) for r in rewards[0]]]
    assert with_stats.td_step(batch(rewards)) == pytest.approx(
        plain.td_step(batch(by_hand)), rel=1e-5
    )


@pytest.mark.parametrize("step", ["autograd", "fused"])
def test_each_seeds_gradient_is_clipped_to_the_norm_on_its_own(step: str) -> None:
    """Seed 0 has the oracle's batch (errors −6, 2, −0.5: a gradient of norm > 1), seed 1
    one whose errors are all 0.01 (a tiny gradient). With the clip at 1, seed 0's
    gradient is rescaled to norm 1 in the same direction; seed 1's stays as it was
    (a clip of the two seeds' joint norm would have shrunk it too)."""
    rewards = [[1.0, 2.0, 0.0], [-5.01, 3.99, -0.51]]  # seed 1: Q_tot − target = 0.01
    plain = model_of(seeds=2, step="autograd")  # the gradients kept where they are read
    clipped = model_of(seeds=2, grad_clip=1.0, step=step)
    plain.td_step(batch(rewards))
    clipped.td_step(batch(rewards))

    def per_seed(model) -> list[torch.Tensor]:
        if model.fused is not None:  # the fused step's gradients, clipped before Adam
            grads = [torch.as_tensor(g).reshape(2, -1) for g in model.fused.agent_grads]
        else:
            grads = [p.grad.reshape(2, -1) for p in model.agents.parameters()]
        return [torch.cat([g[k] for g in grads]) for k in range(2)]

    before, after = per_seed(plain), per_seed(clipped)
    assert before[0].norm() > 1 and before[1].norm() < 1
    assert after[0].norm().item() == pytest.approx(1.0, rel=1e-5)
    assert torch.allclose(after[0], before[0] / (before[0].norm() + 1e-6), atol=1e-6)
    # seed 1 untouched (the fused step's own sums equal autograd's to float32 rounding)
    assert torch.allclose(after[1], before[1], rtol=1e-5, atol=0)


def test_epsilon_anneals_over_a_number_of_steps_whatever_the_budget() -> None:
    """1 -> 0.05 over 10 steps: step k (1-based) has 1 − 0.95 k / 10, then 0.05; the
    episode and the budget do not matter."""
    config = DeepConfig(eps_end=0.05, anneal_steps=10)
    assert not config.anneals and config.explores_by_steps
    for budget in (20, 1_000):
        assert epsilon(7, budget, config, step=1) == pytest.approx(0.905)
        assert epsilon(1, budget, config, step=10) == pytest.approx(0.05)
        assert epsilon(1, budget, config, step=11) == pytest.approx(0.05)
        assert epsilon(1, budget, config, step=1_000_000) == pytest.approx(0.05)


def test_the_compiled_side_anneals_over_the_steps_where_the_budget_counts_episodes() -> None:
    from cmarlcd.games.foraging import Foraging
    from cmarlcd.training.deep import DeepBatch
    from cmarlcd.training.deep_kernels import EPISODES, TURNS, exploration

    config = DeepConfig(
        buffer_size=500, batch_size=16, train_every=20, target_every=40, eps_end=0.05,
        anneal_steps=100,
    )  # fmt: skip
    side = DeepBatch(Foraging(5, 2, 1).spec(), config, [np.random.SeedSequence(1)], 1000)
    data = side.group.views[0].data
    for turns, expected in ((0, 1 - 0.95 / 100), (49, 1 - 0.95 * 50 / 100), (500, 0.05)):
        data.counters[TURNS], data.counters[EPISODES] = turns, 3
        assert exploration(data) == pytest.approx(expected)


@pytest.mark.parametrize(
    ("settings", "parameter"),
    [
        ({"grad_clip": 0.0}, "grad_clip"),
        ({"anneal_steps": 0}, "anneal_steps"),
    ],
)
def test_bad_settings_are_refused(settings: dict, parameter: str) -> None:
    with pytest.raises(ConfigError) as info:
        DeepConfig(**settings)
    assert info.value.parameter == parameter


def test_the_settings_stay_out_of_the_identity_of_runs_that_leave_them_off() -> None:
    """Stores made before 0.7 keep resuming: a config with the new settings at their
    defaults has the identity it had; one that sets them is a new run."""
    from cmarlcd.runs import identity

    names = {"double_q", "grad_clip", "standardise_rewards", "anneal_steps", "share"}
    assert not names & set(identity(DeepConfig()))
    assert names <= set(
        identity(
            DeepConfig(
                double_q=True, grad_clip=10.0, standardise_rewards=True, anneal_steps=5, share=True
            )
        )
    )


def test_every_difference_from_epymarl_is_on_the_field_page() -> None:
    from pathlib import Path

    from cmarlcd.learners.deep.epymarl import DIFFERENCES, EPYMARL_COMMIT

    page = (Path(__file__).resolve().parents[3] / "docs" / "anchors.md").read_text()
    assert f"commit {EPYMARL_COMMIT}" in page
    for what, _, _ in DIFFERENCES:
        assert f"| {what} |" in page, what
