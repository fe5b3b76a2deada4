"""Deep CMARL-CD's standardised rewards (``standardise_rewards``, EPyMARL's VDN's rule on
the shares' one-step targets): the target by hand, each drawn visit's own reward, the
model learning on the standardised targets, determinism, and the setting refused where
a return sums more than one reward or where the compiled loop does not run."""

from __future__ import annotations

import copy
import math
from dataclasses import replace

import numpy as np
import pytest

from cmarlcd import ConfigError
from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig
from cmarlcd.learners.deep.designs import DESIGNS

pytest.importorskip("torch")

import torch

from cmarlcd.learners.deep.td_options import RewardStatistics

#: The one-step design with the standardisation, on a small ring and frequent steps.
ONE_STEP = replace(
    DESIGNS["shares-range-shared-refresh-slow-td"],
    standardise_rewards=True, batch_size=32, buffer_size=500, train_every=25, target_every=50,
)  # fmt: skip


def test_the_target_by_hand() -> None:
    """Rewards 0 and 1, one-step returns 0.5 and 1.5 (γ V' 0.5 each). The statistics
    start at count 1e-4, mean 0, variance 1; the batch's mean is 0.5 and its (unbiased)
    variance 0.5, so the mean becomes 0.5 · 2 / 2.0001 and the variance (1e-4 + 1 +
    0.25 · 2e-4 / 2.0001) / 2.0001: the rewards standardise to −0.707045 and 0.707115
    (the mean a little below 0.5), and the targets are −0.207045 and 1.207115."""
    from cmarlcd.learners.deep.degree_model import standardised_returns

    batch = {"reward": torch.tensor([[0.5, 1.5]]), "step_reward": torch.tensor([[0.0, 1.0]])}
    mean = 0.5 * 2 / 2.0001
    var = (1e-4 + 1.0 + 0.25 * 1e-4 * 2 / 2.0001) / 2.0001
    expected = [0.5 + (r - mean) / math.sqrt(var) for r in (0.0, 1.0)]
    got = standardised_returns(batch, RewardStatistics(1, torch.device("cpu")))
    assert got[0].tolist() == pytest.approx(expected, abs=1e-6)
    assert expected == pytest.approx([-0.207045, 1.207115], abs=1e-6)


def lbf_batch(config: DeepCMARLCDConfig, episodes: int = 40):
    from cmarlcd.experiments import games
    from cmarlcd.training.deep import DeepBatch

    spec = games.parse_game("foraging:5x5-2p-1f")[1].spec()
    batch = DeepBatch(spec, config, [np.random.SeedSequence(3)], episodes)
    batch.train([], lambda *args: None)
    return batch


def test_each_drawn_visit_carries_its_own_reward() -> None:
    """The batch's ``step_reward`` is the ring's own reward at the rows drawn (the same
    generator drawing them again), and at an episode's last visit it is its return."""
    from cmarlcd.learners.deep.replay import draw

    batch = lbf_batch(ONE_STEP)
    group = batch.group
    rngs = copy.deepcopy(group.replay_rngs)
    drawn = group.replay_kind.draw(group.ring, group.replay_rngs, 400)
    picks = draw(group.ring.ring, rngs, 400)
    assert np.array_equal(drawn["step_reward"][0], group.ring.step_reward[0, picks[0]])
    last = group.ring.ring.terminal[0, picks[0]]
    assert last.any()
    assert np.array_equal(drawn["step_reward"][0][last], drawn["reward"][0][last])


@pytest.mark.parametrize("step", ["autograd", "fused"])
def test_the_model_learns_on_the_standardised_targets(step: str) -> None:
    """One step of a model with the setting equals one step of the same model without it
    fed the targets standardised by hand: same loss, same weights (by autograd and by
    the shares' fused step)."""
    from cmarlcd.learners.deep.degree_model import DegreeModel, standardised_returns

    def model(standardise: bool) -> DegreeModel:
        config = replace(ONE_STEP, standardise_rewards=standardise, step=step)
        return DegreeModel([3, 3], 4, config, [np.random.SeedSequence(5)])

    gen = torch.Generator().manual_seed(0)
    batch = {
        "state": torch.rand(1, 16, 4, generator=gen),
        "actions": torch.randint(0, 3, (1, 16, 2), generator=gen),
        "reward": torch.rand(1, 16, generator=gen),
        "step_reward": (torch.rand(1, 16, generator=gen) > 0.8).float(),
    }
    on, off = model(True), model(False)
    assert (on.fused is not None) == (step == "fused")
    by_hand = standardised_returns(batch, RewardStatistics(1, torch.device("cpu")))
    assert not torch.allclose(by_hand, batch["reward"])
    assert on.learn(batch) == pytest.approx(off.learn({**batch, "reward": by_hand}))
    for a, b in zip(on.parameters(), off.parameters(), strict=True):
        assert torch.equal(a, b)


def test_the_same_seed_learns_the_same_weights_and_the_setting_changes_them() -> None:
    weights = [
        [p.detach().clone() for p in lbf_batch(config).group.model.parameters()]
        for config in (ONE_STEP, ONE_STEP, replace(ONE_STEP, standardise_rewards=False))
    ]
    assert all(torch.equal(a, b) for a, b in zip(weights[0], weights[1], strict=True))
    assert not all(torch.equal(a, b) for a, b in zip(weights[0], weights[2], strict=True))


@pytest.mark.parametrize(
    "settings",
    [
        {},  # the keyed memory
        {"update": "critic", "critic_form": "degrees", "return_lambda": 0.5},
        {"update": "imitation"},  # Monte-Carlo returns
    ],
)
def test_it_needs_one_step_returns(settings: dict) -> None:
    with pytest.raises(ConfigError, match="standardise_rewards: standardises the reward of one"):
        DeepCMARLCDConfig(standardise_rewards=True, **settings)


@pytest.mark.parametrize("name", ["standardise_rewards", "refresh_returns"])
def test_the_object_api_refuses_what_only_the_compiled_loop_runs(name: str) -> None:
    from cmarlcd.learners.deep.degree_agent import DegreeAgent

    base = replace(DESIGNS["shares-range-shared-refresh-slow-td"], refresh_returns=False)
    config = replace(base, **{name: True})
    with pytest.raises(ConfigError, match=f"{name}: is run by the compiled loop only"):
        DegreeAgent([3], config, 10, n_states=2, seed=0)
