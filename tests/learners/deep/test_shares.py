"""Deep CMARL-CD with the agents' degrees as their shares of the record
(``update="critic"``, ``critic_form="degrees"``): the loss by hand (the expectile loss
of the summed degrees at the taken joint action), a step moving only the taken actions'
shares, no clip, the λ-returns bootstrapped from the target copy at the live degrees'
greedy joint action (compiled loop, integer states and the object API), the target copy
following at ``sync_target``, determinism, the command line and bad settings refused."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from cmarlcd import ConfigError
from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig
from cmarlcd.learners.deep.designs import SHARES_DEEP_CMARLCD
from tests.learners.deep.lambda_case import SPEC, degree_layers, store_hand_episode

torch = pytest.importorskip("torch")

from cmarlcd.learners.deep.degree_model import DegreeModel  # noqa: E402

#: Two agents of 2 and 3 actions (agent 0's third output is padding).
COUNTS = [2, 3]


def shares(**settings) -> DeepCMARLCDConfig:
    return DeepCMARLCDConfig(
        update="critic", critic_form="degrees", critic_bootstrap="greedy", **settings
    )


def constant_model(live: list[list[float]], target: list[list[float]] | None = None,
                   in_dim: int = 1, **settings) -> DegreeModel:  # fmt: skip
    """One seed, agents of :data:`COUNTS`: agent ``i``'s degrees are ``live[i]`` at every
    state (weights zero, biases set), its target copy's ``target[i]`` (else the same)."""
    net = DegreeModel(COUNTS, in_dim, shares(**settings), [np.random.SeedSequence(0)], "cpu")
    with torch.no_grad():
        for agents, values in ((net.agents, live), (net.target_agents, target or live)):
            agents.first.weight.zero_(), agents.second.weight.zero_()
            agents.first.bias.fill_(1.0)  # ReLU(1) = 1 reaches the second layer's bias only
            for i, row in enumerate(values):
                agents.second.bias[i] = torch.tensor(row)
    return net


def batch(returns: list[float], actions: list[list[int]]) -> dict[str, torch.Tensor]:
    count = len(returns)
    return {
        "state": torch.ones((1, count, 1)),
        "actions": torch.tensor(actions).reshape(1, count, len(COUNTS)),
        "reward": torch.tensor([returns]),
    }


LIVE = [[1.0, 2.0, 0.0], [0.5, 1.0, 3.0]]


def test_the_loss_by_hand() -> None:
    """Degrees (1, 2 | 0.5, 1, 3). Visit (1, 2) with return 4: the record 2 + 3 = 5, τ
    0.5: 0.5 · 1² = 0.5; visit (0, 0) with return 0: 1 + 0.5 = 1.5, 0.5 · 1.5² = 1.125;
    mean 0.8125, and nothing else (no critic to distil from)."""
    net = constant_model(LIVE, expectile=0.5)
    data = batch([4.0, 0.0], [[1, 2], [0, 0]])
    assert float(net.critic_loss(data).detach()) == pytest.approx(0.8125, rel=1e-6)
    assert float(net.loss(data).detach()) == pytest.approx(0.8125, rel=1e-6)
    net = constant_model(LIVE, expectile=0.9)  # above the record: 0.9, below: 0.1
    assert float(net.loss(data).detach()) == pytest.approx((0.1 * 1 + 0.1 * 2.25) / 2, rel=1e-6)


@pytest.mark.parametrize("step", ["autograd", "fused"])
def test_the_step_returns_the_loss_by_hand(step: str) -> None:
    """The loss of :func:`test_the_loss_by_hand` as each step computes it before moving
    the weights: 0.8125 at τ 0.5, 0.1625 at τ 0.9."""
    data = batch([4.0, 0.0], [[1, 2], [0, 0]])
    assert constant_model(LIVE, expectile=0.5, step=step).learn(data) == pytest.approx(0.8125)
    assert constant_model(LIVE, expectile=0.9, step=step).learn(data) == pytest.approx(0.1625)


@pytest.mark.parametrize("step", ["autograd", "fused"])
def test_a_step_moves_the_taken_shares_only(step: str) -> None:
    """Every visit took (1, 2) and earned more than its record: those two shares rise by
    Adam's first step, the learning rate 0.01; agent 0's action 0 and agent 1's actions
    0 and 1, never taken, do not move (their gradient is zero, so Adam's first step
    leaves them)."""
    net = constant_model(LIVE, lr=0.01, step=step)
    net.learn(batch([9.0, 9.0], [[1, 2], [1, 2]]))
    after = net.agents(torch.ones((1, 1, 1)))[0, 0].detach()
    # Adam's first step moves each parameter of a nonzero gradient by the learning rate:
    # the share's bias, and its weight from each hidden unit, all at ReLU(1) = 1
    moved = 0.01 * (net.config.hidden + 1)
    assert after[0, 1].item() == pytest.approx(2.0 + moved, abs=1e-5)
    assert after[1, 2].item() == pytest.approx(3.0 + moved, abs=1e-5)
    assert after[0, 0].item() == 1.0 and after[1, :2].tolist() == [0.5, 1.0]


def test_the_degrees_are_not_clipped() -> None:
    """Shares are in the returns' units: no ``[c_min, c_max]`` as it acts, in the compiled
    loop's schedule or in a kept policy."""
    config = shares()
    assert config.degree_bounds == (-np.inf, np.inf)
    assert config.schedule(10)[1:3] == [-np.inf, np.inf]
    assert DeepCMARLCDConfig().degree_bounds == (0.5, 3.0)
    net = constant_model([[-40.0, -30.0, 0.0], [9.0, 7.0, 8.0]])
    assert net.greedy_table().tolist() == [[[1, 0]]]  # clipped, agent 0 would tie at 0.5


def test_the_estimate_is_the_target_copy_at_the_live_greedy_joint_action() -> None:
    """Live degrees (1, 2 | 2, 1, 1): greedy (1, 0). Target copy (5, 7 | 11, 13, 17):
    7 + 11 = 18, for integer states (the loop's copy of every state's estimate) and in
    the object API; not the target's own best (7 + 17) nor the live sum (2 + 2)."""
    live, target = [[1.0, 2.0, 0.0], [2.0, 1.0, 1.0]], [[5.0, 7.0, 0.0], [11.0, 13.0, 17.0]]
    net = constant_model(live, target, in_dim=2)
    assert net.record_table()[0].tolist() == [18.0, 18.0]
    assert net.estimate(torch.tensor([[0, 1]]))[0].tolist() == [18.0, 18.0]
    net.sync_target()
    assert net.record_table()[0].tolist() == [4.0, 4.0]


def test_the_compiled_loop_bootstraps_from_the_target_copy_by_hand() -> None:
    """Two agents of 2 actions, one feature x; live degrees greedy (1, 0) everywhere, the
    target copy's (3x, 10x | x, −x): estimates 10x + x = 11 and 22 at the next visits'
    features 1 and 2; rewards 1, 2, 4, γ 0.5, λ 0.5: G_2 = 4, G_1 = 2 + 0.5 (0.5 · 22 +
    0.5 · 4) = 8.5, G_0 = 1 + 0.5 (0.5 · 11 + 0.5 · 8.5) = 5.875."""
    from cmarlcd.training.deep_replay import BOOTSTRAPPED

    counts = np.array([2, 2])
    ring = BOOTSTRAPPED.new(shares(return_lambda=0.5), 1, counts, SPEC, 1)
    target = degree_layers(2, 2)
    target.w1[:, 0, 0] = 1.0  # hidden unit 0 = ReLU(x)
    target.w2[0, 0], target.w2[1, 0] = [3.0, 10.0], [1.0, -1.0]
    replay = BOOTSTRAPPED.view(ring._replace(record_weights=target), 0)
    live = degree_layers(2, 2)
    live.b2[0], live.b2[1] = [1.0, 2.0], [2.0, 1.0]  # greedy actions (1, 0)
    store_hand_episode(replay, counts, live, [[0, 0], [1, 1], [1, 0]], shares())
    assert replay.ring.reward[:3].tolist() == [4.0, 8.5, 5.875]


@pytest.mark.parametrize("step", ["autograd", "fused"])
def test_the_same_seed_learns_the_same_weights_on_lbf(step: str) -> None:
    """End to end on LBF's features, on either step: the loop's copy that returns
    bootstrap from is the degree networks' target copy (no target copy due within the
    budget: still the initial weights, where the live networks have learned), and two
    runs of one seed learn the same weights."""
    from cmarlcd.experiments import games
    from cmarlcd.training.deep import DeepBatch

    spec = games.parse_game("foraging:5x5-2p-1f")[1].spec()
    config = replace(
        SHARES_DEEP_CMARLCD, batch_size=64, buffer_size=2000, target_every=10**6, step=step
    )

    def weights() -> list:
        run = DeepBatch(spec, config, [np.random.SeedSequence(3)], 60)
        run.train([], lambda *args: None)
        model, copy = run.group.model, run.group.ring.record_weights
        target = [w.detach().numpy() for w in model.target_agents.feature_weights()]
        assert all(np.array_equal(a, b) for a, b in zip(copy, target, strict=True))
        live = model.agents.feature_weights()[2].detach().numpy()
        assert not np.array_equal(copy.w2, live)  # the live networks learned
        assert (model.fused is not None) is (step == "fused")
        return [p.detach().clone() for p in model.parameters()]

    first, second = weights(), weights()
    assert all((a == b).all() for a, b in zip(first, second, strict=True))


def test_monte_carlo_returns_need_no_copy() -> None:
    """With λ 1 the ring stores Monte-Carlo returns (no bootstrap, no copy of the
    degrees): it learns on LBF's features all the same."""
    from cmarlcd.experiments import games
    from cmarlcd.training.deep import DeepBatch

    spec = games.parse_game("foraging:5x5-2p-1f")[1].spec()
    config = replace(SHARES_DEEP_CMARLCD, return_lambda=1.0, batch_size=64, buffer_size=2000)
    run = DeepBatch(spec, config, [np.random.SeedSequence(3)], 60)
    before = [p.detach().clone() for p in run.group.model.agents.parameters()]
    run.train([], lambda *args: None)
    after = list(run.group.model.agents.parameters())
    assert not hasattr(run.group.ring, "record_weights")
    assert any((a != b).any() for a, b in zip(before, after, strict=True))


def test_bad_settings_are_refused() -> None:
    assert shares().record_outputs(COUNTS) == 1
    with pytest.raises(ConfigError, match="'degrees' bootstraps from the degrees' greedy"):
        DeepCMARLCDConfig(update="critic", critic_form="degrees")
    with pytest.raises(ConfigError, match="critic_form: must be one of joint, sum, degrees"):
        DeepCMARLCDConfig(update="critic", critic_form="shares")


def test_the_command_line_runs_it(tmp_path) -> None:
    """``train`` on LBF with the shares, end to end on a tiny budget."""
    import subprocess
    import sys

    d = "deep-cmarl-cd"
    settings = f"{d}.update=critic,{d}.critic_form=degrees,{d}.critic_bootstrap=greedy"
    done = subprocess.run(
        [sys.executable, "-m", "cmarlcd", "train", "--game", "foraging:5x5-2p-1f",
         "--algorithms", d, "--steps", "2k", "--runs", "1", "--curve-points", "2",
         "--eval-episodes", "2", "--workers", "1", "--no-progress",
         "--store", str(tmp_path / "s.sqlite"), "--figures", str(tmp_path / "f"),
         "--set", f"{settings},{d}.return_lambda=0.9,{d}.batch_size=32"],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "1 runs computed" in done.stdout or "1 run computed" in done.stdout, done.stdout


@pytest.mark.slow
@pytest.mark.parametrize("step", ["auto", "fused"])
def test_the_design_passes_every_learner_check(step: str) -> None:
    from cmarlcd.testing import check_learner

    check_learner(replace(SHARES_DEEP_CMARLCD, step=step))


def test_two_hidden_layers_act_in_the_loop_as_the_networks_compute() -> None:
    """``hidden_layers=2``: each degree network gets a middle layer, the loop's copy of
    the weights carries it, and the compiled degrees at sampled features are the
    networks' own (to float32 rounding) after a few hundred learning steps on LBF."""
    from cmarlcd.experiments import games
    from cmarlcd.training.deep import DeepBatch
    from cmarlcd.training.deep_kernels import hidden_scratch
    from cmarlcd.training.degree_kernels import agent_degrees

    spec = games.parse_game("foraging:5x5-2p-1f")[1].spec()
    config = replace(
        SHARES_DEEP_CMARLCD, hidden_layers=2, hidden=16, batch_size=64, buffer_size=2000
    )
    run = DeepBatch(spec, config, [np.random.SeedSequence(3)], 200)
    run.train([], lambda *args: None)
    model, group = run.group.model, run.group
    names = [name for name, _ in model.agents.named_parameters()]
    assert any(name.startswith("middle.") for name in names)
    weights = group.weights
    assert weights.wm.shape[1:] == (1, 16, 16)
    rng = np.random.default_rng(0)
    x = rng.standard_normal((50, spec.n_features)).astype(np.float32)
    with torch.no_grad():
        expected = model.agents(torch.from_numpy(x)[None]).numpy()[0]  # (50, agents, width)
    hidden, out = hidden_scratch(weights), np.zeros(spec.width, np.float64)
    for k in range(len(x)):
        for i in range(spec.n_agents):
            agent_degrees(weights, i, x[k], 0, spec.width, hidden, out)
            np.testing.assert_allclose(out, expected[k, i], rtol=1e-5, atol=1e-5)


def test_hidden_layers_is_checked_and_refuses_the_fused_step() -> None:
    with pytest.raises(ConfigError, match="hidden_layers"):
        DeepCMARLCDConfig(hidden_layers=0)
    assert DeepCMARLCDConfig().fused_covered
    assert not DeepCMARLCDConfig(hidden_layers=2).fused_covered
    with pytest.raises(ConfigError, match="hidden_layers=1"):
        DeepCMARLCDConfig(hidden_layers=2, step="fused")
