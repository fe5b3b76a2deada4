"""Deep IQL and hysteretic DQN: each agent its own TD target on the team reward (no
mixer), hysteretic DQN weighing negative TD errors by β; against hand-computed batches."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from cmarlcd import ConfigError, registry  # noqa: E402
from cmarlcd.learners.deep.config import HYSTERETIC_NEGATIVE_RATE, DeepConfig  # noqa: E402
from cmarlcd.learners.deep.value_decomposition import ValueDecomposition  # noqa: E402

#: Q-values (state, agent, action) of the online and target networks (as in
#: test_value_decomposition.py's VDN oracle, so the two can be read side by side).
ONLINE = [[[1.0, 2.0], [0.5, -1.0]], [[0.0, 3.0], [2.0, 1.0]], [[4.0, 0.0], [0.0, 0.0]]]
TARGET = [[[10.0, 20.0], [1.0, 1.0]], [[5.0, 7.0], [2.0, 8.0]], [[3.0, 9.0], [6.0, 4.0]]]
PLAYED = [(0, 0, 1), (1, 0, 0), (0, 1, 1), (1, 1, 1), (0, 2, 0), (1, 2, 0)]


def set_q_tables(agents, q: list) -> None:
    """The agent networks compute ``q[s][i][a]`` exactly (one-hot state copied through
    the first layer, the table in the second)."""
    table = torch.tensor(q).permute(1, 0, 2)
    with torch.no_grad():
        agents.first.weight.copy_(torch.eye(len(q)).expand_as(agents.first.weight))
        agents.first.bias.zero_()
        agents.second.weight.copy_(table)
        agents.second.bias.zero_()


def model_of(mixer: str, **settings) -> ValueDecomposition:
    config = DeepConfig(mixer=mixer, hidden=3, gamma=0.5, **settings)
    model = ValueDecomposition([2, 2], 3, config, [np.random.SeedSequence(0)])
    set_q_tables(model.agents, ONLINE)
    set_q_tables(model.target_agents, TARGET)
    model.optimizer.step = lambda: None  # keep the gradients, move nothing
    return model


def batch(next_legal: bool) -> dict:
    """(s=0, a=(1,0), r=1, s'=1); (s=1, a=(1,1), r=2, terminal); (s=2, a=(0,0), r=0,
    s'=2, where agent 0 may not play action 1)."""
    out = {
        "state": torch.tensor([[0, 1, 2]]),
        "actions": torch.tensor([[[1, 0], [1, 1], [0, 0]]]),
        "reward": torch.tensor([[1.0, 2.0, 0.0]]),
        "next_state": torch.tensor([[1, 2, 2]]),
        "terminal": torch.tensor([[False, True, False]]),
    }
    if next_legal:
        legal = torch.ones(1, 3, 2, 2, dtype=torch.bool)
        legal[0, 2, 0, 1] = False
        out["next_legal"] = legal
    return out


def second_layer_grad(model: ValueDecomposition) -> torch.Tensor:
    """The gradient of the agents' second layer (agent, hidden = state, action), from
    autograd's step or the fused step's own arrays."""
    if model.fused is not None:
        return torch.as_tensor(model.fused.agent_grads[2])
    return model.agents.second.weight.grad


def step(model: ValueDecomposition, masks: str) -> float:
    if masks == "per state":
        legal = torch.ones(3, 2, 2, dtype=torch.bool)
        legal[2, 0, 1] = False
        model.set_state_legal(legal)
    return model.td_step(batch(next_legal=masks == "in the batch"))


#: Each agent's own target r + γ max_{a legal} Q_i^target(s', a) (r alone at the end),
#: and its error Q_i(s, a) − target, in the order of PLAYED:
#:   agent 0, t1: Q 2,   target 1 + 0.5·7 = 4.5           -> −2.5
#:   agent 1, t1: Q 0.5, target 1 + 0.5·8 = 5             -> −4.5
#:   agent 0, t2: Q 3,   target 2 (terminal)              ->  1
#:   agent 1, t2: Q 1,   target 2                         -> −1
#:   agent 0, t3: Q 4,   target 0 + 0.5·3 = 1.5 (9 illegal) -> 2.5
#:   agent 1, t3: Q 0,   target 0 + 0.5·6 = 3             -> −3
ERRORS = [-2.5, -4.5, 1.0, -1.0, 2.5, -3.0]


@pytest.mark.parametrize("kind", ["autograd", "fused"])
@pytest.mark.parametrize("masks", ["in the batch", "per state"])
def test_deep_iql_one_td_step_against_a_hand_computed_batch(masks: str, kind: str) -> None:
    """loss: the mean over 3 transitions × 2 agents of the squared errors, 43.75 / 6;
    dloss/dQ_i(s, a) = 2 · error / 6 at each played entry, 0 elsewhere."""
    model = model_of("independent", step=kind)
    assert (model.fused is not None) == (kind == "fused")
    assert step(model, masks) == pytest.approx(43.75 / 6)
    grad = second_layer_grad(model)
    for (agent, state, action), error in zip(PLAYED, ERRORS, strict=True):
        assert grad[agent, state, action] == pytest.approx(error / 3)
    unplayed = torch.ones_like(grad, dtype=torch.bool)
    for entry in PLAYED:
        unplayed[entry] = False
    assert (grad[unplayed] == 0).all()


@pytest.mark.parametrize("kind", ["autograd", "fused"])
@pytest.mark.parametrize("masks", ["in the batch", "per state"])
def test_hysteretic_dqn_moves_a_negative_td_error_by_the_smaller_rate(
    masks: str, kind: str
) -> None:
    """The two errors with Q above its target (agent 0 at t2 and t3: TD errors −1 and
    −2.5) are weighed by β = 0.2: loss (6.25 + 20.25 + 0.2 + 1 + 1.25 + 9) / 6, and their
    gradients are 0.2 times deep IQL's."""
    model = model_of("hysteretic", step=kind)
    assert model.config.negative_weight == HYSTERETIC_NEGATIVE_RATE == 0.2
    assert step(model, masks) == pytest.approx(37.95 / 6)
    grad = second_layer_grad(model)
    for (agent, state, action), error in zip(PLAYED, ERRORS, strict=True):
        weight = 0.2 if error > 0 else 1.0
        assert grad[agent, state, action] == pytest.approx(weight * error / 3)


@pytest.mark.parametrize("mixer", ["independent", "hysteretic"])
def test_step_auto_keeps_autograds_step_until_a_study_compares_the_runs(mixer: str) -> None:
    assert model_of(mixer).fused is None  # auto: autograd's, on a CPU too
    assert model_of(mixer, step="fused").fused is not None


def test_hysteretic_dqn_with_beta_one_is_deep_iql() -> None:
    iql, hysteretic = model_of("independent"), model_of("hysteretic", negative_rate=1.0)
    assert step(iql, "per state") == step(hysteretic, "per state")
    assert torch.equal(iql.agents.second.weight.grad, hysteretic.agents.second.weight.grad)


def test_the_same_seed_learns_the_same_and_another_seed_does_not() -> None:
    config = DeepConfig(mixer="hysteretic", hidden=4, lr=0.01)

    def learned(seed: int) -> torch.Tensor:
        model = ValueDecomposition([2, 2], 3, config, [np.random.SeedSequence(seed)])
        gen = torch.Generator().manual_seed(5)
        for _ in range(5):
            model.td_step(
                {
                    "state": torch.randint(0, 3, (1, 20), generator=gen),
                    "actions": torch.randint(0, 2, (1, 20, 2), generator=gen),
                    "reward": torch.randn(1, 20, generator=gen),
                    "next_state": torch.randint(0, 3, (1, 20), generator=gen),
                    "terminal": torch.rand(1, 20, generator=gen) < 0.2,
                }
            )
        return model.agents.second.weight.detach().clone()

    assert torch.equal(learned(1), learned(1))
    assert not torch.equal(learned(1), learned(2))


def test_the_registry_names_them_and_keeps_them_out_of_the_papers_tournament() -> None:
    assert registry.LEARNERS["deep-iql"] == DeepConfig(mixer="independent")
    assert registry.LEARNERS["hysteretic-dqn"] == DeepConfig(mixer="hysteretic")
    assert registry.display_name("hysteretic-dqn") == "Hysteretic DQN"
    assert registry.needs_torch("deep-iql")
    assert not {"deep-iql", "hysteretic-dqn"} & set(registry.learners_on(registry.BATTLEFIELD))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"mixer": "hysteretic", "negative_rate": 0.0}, r"in \(0, 1\]"),
        ({"mixer": "hysteretic", "negative_rate": 1.5}, r"in \(0, 1\]"),
        ({"mixer": "vdn", "negative_rate": 0.5}, "hysteretic-dqn only"),
    ],
)
def test_bad_settings_are_refused(kwargs: dict, match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        DeepConfig(**kwargs)


def test_the_command_lines_set_reads_an_optional_rate_as_a_number() -> None:
    from cmarlcd.cli.options import apply_settings

    configs = (registry.LEARNERS["hysteretic-dqn"], registry.LEARNERS["deep-iql"])
    hysteretic, iql = apply_settings("hysteretic-dqn.negative_rate=0.5", configs)
    assert hysteretic.negative_rate == 0.5 and hysteretic.negative_weight == 0.5
    assert iql == registry.LEARNERS["deep-iql"]
    (back,) = apply_settings("hysteretic-dqn.negative_rate=none", configs[:1])
    assert back.negative_rate is None
    with pytest.raises(ConfigError, match=r"hysteretic-dqn\.negative_rate: expected a number"):
        apply_settings("hysteretic-dqn.negative_rate=abc", configs)
    with pytest.raises(ConfigError, match=r"deep-iql\.share: expected true or false"):
        apply_settings("deep-iql.share=yes", configs)
    with pytest.raises(ConfigError, match=r"deep-iql\.hidden_layers: expected an integer"):
        apply_settings("deep-iql.hidden_layers=two", configs)
    with pytest.raises(ConfigError, match="hysteretic-dqn only"):
        apply_settings("deep-iql.negative_rate=0.5", configs)
