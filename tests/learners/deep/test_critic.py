"""Deep CMARL-CD with a centralised critic of joint actions as the record
(``update="critic"``): its loss on a hand-computed case (the critic's expectile loss at
the taken joint action, the tie of eqs. 14-15 for the critic's best joint action), the
critic rather than the visit's return deciding which actions rise, an unseen state
borrowing from its neighbour, the compiled loop bootstrapping from the critic's best,
determinism, a one-state game solved and bad settings refused."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from cmarlcd import ConfigError
from cmarlcd.learners.deep.coordination import MAX_JOINT_ACTIONS, DeepCMARLCDConfig
from cmarlcd.learners.deep.designs import CRITIC_DEEP_CMARLCD
from tests.learners.deep.lambda_case import SPEC, degree_layers, store_hand_episode

torch = pytest.importorskip("torch")

from cmarlcd.learners.deep.degree_model import DegreeModel  # noqa: E402

#: Two agents of 2 and 3 actions: joint action (a_0, a_1) is output 3 a_0 + a_1.
COUNTS = [2, 3]


def constant_model(degree: float, critic: list[float], **settings) -> DegreeModel:
    """One seed, agents of :data:`COUNTS`, one feature: every degree is ``degree`` and
    the critic (and its target copy) is ``critic`` at every state (weights zero, biases
    set)."""
    config = DeepCMARLCDConfig(update="critic", **settings)
    net = DegreeModel(COUNTS, 1, config, [np.random.SeedSequence(0)], device="cpu")
    with torch.no_grad():
        net.agents.first.weight.zero_(), net.agents.second.weight.zero_()
        net.agents.first.bias.fill_(1.0)  # ReLU(1) = 1 reaches the second layer's bias only
        net.agents.second.bias.fill_(degree)
        for record in (net.record, net.target_record):
            record.first.weight.zero_(), record.first.bias.zero_()
            record.second.weight.zero_()
            record.second.bias[0] = torch.tensor(critic)
    return net


def batch(returns: list[float], actions: list[list[int]]) -> dict[str, torch.Tensor]:
    count = len(returns)
    return {
        "state": torch.ones((1, count, 1)),
        "actions": torch.tensor(actions).reshape(1, count, len(COUNTS)),
        "reward": torch.tensor([returns]),
    }


def test_the_loss_by_hand() -> None:
    """Critic (0, 0.5, 0, 0, 0, 2): its best joint action is output 5, (1, 2). Visits:
    (1, 2) with return 3 against its estimate 2, τ 0.9: 0.9 · 1² = 0.9; (0, 1) (output
    1, estimate 0.5) with return 0: (1 − 0.9) · 0.5² = 0.025; mean 0.4625. Degrees all
    3 (c_max): the tie for (1, 2) keeps a_0 = 1 and a_1 = 2 at 3 and lowers the others
    to 2.95: 0.05² for agent 0's action 0, 2 · 0.05² for agent 1's: 0.0075 at every
    visit. Total 0.47."""
    critic = [0.0, 0.5, 0.0, 0.0, 0.0, 2.0]
    net = constant_model(3.0, critic, expectile=0.9, delta=0.05, critic_fit="tie")
    loss = net.critic_loss(batch([3.0, 0.0], [[1, 2], [0, 1]]))
    assert float(loss.detach()) == pytest.approx(0.47, rel=1e-6)
    assert net.loss(batch([3.0, 0.0], [[1, 2], [0, 1]])).item() == pytest.approx(0.47, rel=1e-6)


def test_the_cross_entropy_by_hand() -> None:
    """``critic_fit="imitation"`` on the same visits: degrees all equal (3, inside the
    bounds, no penalty), so each agent's strategy is uniform: −log(1/2) − log(1/3) =
    log 6 at every visit, plus the critic's 0.4625."""
    critic = [0.0, 0.5, 0.0, 0.0, 0.0, 2.0]
    net = constant_model(3.0, critic, expectile=0.9, critic_fit="imitation")
    loss = net.critic_loss(batch([3.0, 0.0], [[1, 2], [0, 1]]))
    assert float(loss.detach()) == pytest.approx(0.4625 + math.log(6), rel=1e-6)


def test_the_critic_not_the_return_decides_which_actions_rise() -> None:
    """Degrees 1.5; the critic's best is (1, 2); every visit took (0, 0) and earned a
    high return. A step raises (1, 2)'s degrees and lowers the taken ones; the critic's
    estimate of (0, 0) (output 0) moves towards the return."""
    net = constant_model(1.5, [0.0, 0.0, 0.0, 0.0, 0.0, 2.0], lr=0.01, record_lr=0.01)
    net.learn(batch([5.0, 5.0], [[0, 0], [0, 0]]))
    degrees = net.agents(torch.ones((1, 1, 1)))[0, 0].detach()
    assert degrees[0, 1] > 1.5 > degrees[0, 0]
    assert degrees[1, 2] > 1.5 > max(degrees[1, 0], degrees[1, 1])
    values = net.record.values(torch.ones((1, 1, 1)))[0, 0].detach()
    assert values[0] > 0.0
    assert net.record(torch.ones((1, 1, 1))).item() == pytest.approx(float(values.max()))


def test_an_unseen_state_borrows_from_its_neighbour() -> None:
    """Trained only at feature 1.0, where the critic's best is (0, 1): the greedy joint
    action at 1.1, never visited, becomes (0, 1) too."""
    config = DeepCMARLCDConfig(update="critic", lr=0.01)
    net = DegreeModel(COUNTS, 1, config, [np.random.SeedSequence(4)], device="cpu")
    with torch.no_grad():
        net.target_record.second.weight.zero_()
        net.target_record.second.bias[0] = torch.tensor([0.0, 9.0, 0.0, 0.0, 0.0, 0.0])
    data = batch([0.0, 0.0], [[1, 0], [1, 2]])
    for _ in range(300):
        net.learn(data)
    unseen = net.agents(torch.full((1, 1, 1), 1.1))[0, 0].detach().clamp(0.5, 3.0)
    assert int(unseen[0, :2].argmax()) == 0 and int(unseen[1].argmax()) == 1


def lambda_returns(bootstrap: str) -> list[float]:
    """The compiled loop's stored λ-returns of the λ-return tests' hand case (rewards 1,
    2, 4 at features 0, 1, 2; γ 0.5, λ 0.5) for one agent of 3 actions whose degrees
    take action 1 greedily everywhere, the critic's three outputs 3x, 10x and 12x (one
    hidden unit ReLU(x))."""
    from cmarlcd.training.deep_replay import BOOTSTRAPPED

    config = DeepCMARLCDConfig(
        update="critic", return_lambda=0.5, record_hidden=1, critic_bootstrap=bootstrap
    )
    ring = BOOTSTRAPPED.new(config, 1, np.array([3]), SPEC, 1)
    w1, _, w2, b2 = ring.record_weights[:4]
    assert w2.shape == (1, 1, 3) and b2.shape == (1, 3)
    w1[0, 0, 0] = 1.0
    w2[0, 0] = [3.0, 10.0, 12.0]
    replay = BOOTSTRAPPED.view(ring, 0)
    degrees = degree_layers(1, 3)
    degrees.b2[0] = [1.0, 2.0, 1.0]  # every state's degrees: action 1 greedy
    store_hand_episode(replay, np.array([3]), degrees, [[0], [2], [1]])
    return replay.ring.reward[:3].tolist()


def test_the_compiled_loop_bootstraps_from_the_greedy_joint_action() -> None:
    """The degrees' greedy action 1 reads the critic's 10x: estimates 10 and 20 at the
    next visits' features 1 and 2, the λ-return tests' 4, 8, 5.5."""
    assert lambda_returns("greedy") == [4.0, 8.0, 5.5]


def test_the_compiled_loop_bootstraps_from_the_critics_best() -> None:
    """The best output, 12x: estimates 12 and 24; G_2 = 4, G_1 = 2 + 0.5 (0.5 · 24 + 0.5
    · 4) = 9, G_0 = 1 + 0.5 (0.5 · 12 + 0.5 · 9) = 6.25."""
    assert lambda_returns("best") == [4.0, 9.0, 6.25]


def test_the_estimate_of_integer_states_and_the_object_api() -> None:
    """Integer states (the loop's copy of every state's estimate, and the object API's
    estimate): the critic's value at the degrees' greedy joint action (1, 0), output 3,
    or its best, output 5."""
    for bootstrap, expected in (("greedy", 4.0), ("best", 7.0)):
        config = DeepCMARLCDConfig(update="critic", critic_bootstrap=bootstrap)
        net = DegreeModel(COUNTS, 2, config, [np.random.SeedSequence(0)], device="cpu")
        with torch.no_grad():
            net.agents.first.weight.zero_(), net.agents.second.weight.zero_()
            net.agents.first.bias.fill_(1.0)
            net.agents.second.bias[0] = torch.tensor([1.0, 2.0, 0.0])  # agent 0: action 1
            net.agents.second.bias[1] = torch.tensor([2.0, 1.0, 1.0])  # agent 1: action 0
            net.record.first.weight.zero_(), net.record.first.bias.zero_()
            net.record.second.weight.zero_()
            net.record.second.bias[0] = torch.tensor([0.0, 1.0, 2.0, 4.0, 5.0, 7.0])
        assert net.record_table()[0].tolist() == [expected, expected]
        assert net.estimate(torch.tensor([[0, 1]]))[0].tolist() == [expected, expected]


def test_the_same_seed_learns_the_same_weights_on_lbf() -> None:
    """End to end on LBF's features (the loop's ring of λ-returns, the critic's copy
    refreshed after each step): two runs of one seed learn the same weights."""
    from cmarlcd.experiments import games
    from cmarlcd.training.deep import DeepBatch

    spec = games.parse_game("foraging:5x5-2p-1f")[1].spec()
    config = replace(CRITIC_DEEP_CMARLCD, batch_size=64, buffer_size=2000)

    def weights() -> list:
        run = DeepBatch(spec, config, [np.random.SeedSequence(3)], 60)
        run.train([], lambda *args: None)
        copy, critic = run.group.ring.record_weights, run.group.model.record_weights()
        assert copy.w2.shape[-1] == 36  # 6 × 6 joint actions
        assert np.array_equal(copy.w2, critic[2].detach().numpy())
        return [p.detach().clone() for p in run.group.model.parameters()]

    first, second = weights(), weights()
    assert all((a == b).all() for a, b in zip(first, second, strict=True))


def test_a_one_state_game_is_solved() -> None:
    """The climbing game as a one-step stochastic game (optimum (0, 0), 11, beside −30
    on either side of it), in 10,000 episodes: every seed's greedy joint action is the
    optimum, where independent learners settle on a safer one."""
    from cmarlcd.games.matrix import climbing_game
    from cmarlcd.training.deep import DeepBatch

    spec = climbing_game().spec()
    config = DeepCMARLCDConfig(
        update="critic", expectile=0.9, buffer_size=500, batch_size=50, train_every=10,
        target_every=50,
    )  # fmt: skip
    final = {}
    run = DeepBatch(spec, config, [np.random.SeedSequence(k) for k in range(5)], 10_000)
    run.train([], lambda k, budget, policy: final.__setitem__(k, policy.table[0].tolist()))
    assert list(final.values()) == [[0, 0]] * 5


def test_the_critic_settings_stay_out_of_other_runs_identities() -> None:
    """Their defaults are the design as first run, so a run of any other update (or of
    the first critic) keeps the identity it had before they existed; the mended critic
    carries them."""
    from cmarlcd.learners.deep.designs import BEST_CRITIC_DEEP_CMARLCD
    from cmarlcd.runs import identity

    names = {"critic_bootstrap", "critic_fit", "critic_form"}
    for config in (DeepCMARLCDConfig(), BEST_CRITIC_DEEP_CMARLCD):
        assert not names & set(identity(config))
    assert {"critic_bootstrap", "critic_fit"} <= set(identity(CRITIC_DEEP_CMARLCD))


def test_too_many_joint_actions_are_refused() -> None:
    config = DeepCMARLCDConfig(update="critic")
    assert config.record_outputs([6, 6, 6]) == 216
    assert DeepCMARLCDConfig().record_outputs([6, 6, 6]) == 1
    with pytest.raises(ConfigError, match=f"10000 here, more than {MAX_JOINT_ACTIONS}"):
        config.record_outputs([10, 10, 10, 10])
    with pytest.raises(ConfigError, match="critic_fit: must be one of imitation, tie"):
        DeepCMARLCDConfig(update="critic", critic_fit="max")
    with pytest.raises(ConfigError, match="critic_bootstrap: must be one of greedy, best"):
        DeepCMARLCDConfig(update="critic", critic_bootstrap="mean")
    with pytest.raises(ConfigError, match="update='critic' set act_from=network"):
        DeepCMARLCDConfig(update="critic", act_from="memory")


@pytest.mark.slow
def test_the_design_passes_every_learner_check() -> None:
    from cmarlcd.testing import check_learner

    check_learner(CRITIC_DEEP_CMARLCD)


def test_the_command_line_runs_it_and_refuses_too_many_joint_actions(tmp_path) -> None:
    """``field`` on LBF with the critic, end to end on a tiny budget; a game of 10,000
    joint actions is one line and status 2."""
    import subprocess
    import sys

    def run(game: str) -> subprocess.CompletedProcess:
        return subprocess.run(
            [sys.executable, "-m", "cmarlcd", "train", "--game", game, "--algorithms",
             "deep-cmarl-cd", "--steps", "2k", "--runs", "1", "--curve-points", "2",
             "--eval-episodes", "2", "--workers", "1", "--no-progress",
             "--store", str(tmp_path / "s.sqlite"), "--figures", str(tmp_path / "f"),
             "--set", "deep-cmarl-cd.update=critic,deep-cmarl-cd.batch_size=32"],
            capture_output=True, text=True, check=False,
        )  # fmt: skip

    done = run("foraging:5x5-2p-1f")
    assert done.returncode == 0, done.stderr
    assert "1 run computed" in done.stdout or "1 runs computed" in done.stdout, done.stdout
    done = run("foraging:10x10-5p-3f")
    assert done.returncode == 2, done.stdout
    assert "more than 4096" in done.stderr and done.stderr.strip().count("\n") == 0, done.stderr


def test_the_summed_critic_by_hand() -> None:
    """``critic_form="sum"`` over agents of 2 and 3 actions: outputs (1, 2 | 10, 20, 30);
    joint action (1, 2) is worth 2 + 30 = 32, (0, 0) 11; its best joint action is each
    agent's best, (1, 2); it has 5 outputs, not 6."""
    config = DeepCMARLCDConfig(update="critic", critic_form="sum", critic_bootstrap="greedy")
    assert config.record_outputs(COUNTS) == 5
    net = DegreeModel(COUNTS, 1, config, [np.random.SeedSequence(0)], device="cpu")
    values = torch.tensor([1.0, 2.0, 10.0, 20.0, 30.0]).expand(1, 2, 5)
    actions = torch.tensor([[[1, 2], [0, 0]]])
    assert net.critic_at(values, actions).tolist() == [[32.0, 11.0]]
    assert net.critic_best(values).tolist() == [[[1, 2], [1, 2]]]
    with pytest.raises(ConfigError, match="'sum' bootstraps from the degrees' greedy"):
        DeepCMARLCDConfig(update="critic", critic_form="sum", critic_bootstrap="best")


def test_the_compiled_loop_bootstraps_a_summed_critic_by_hand() -> None:
    """Two agents of 2 actions, one feature x, the summed critic's outputs (3x, 10x | x,
    −x) and the degrees' greedy actions (1, 0): estimates 10x + x = 11 and 22 at the next
    visits' features 1 and 2; rewards 1, 2, 4, γ 0.5, λ 0.5: G_2 = 4, G_1 = 2 + 0.5 (0.5
    · 22 + 0.5 · 4) = 8.5, G_0 = 1 + 0.5 (0.5 · 11 + 0.5 · 8.5) = 5.875."""
    from cmarlcd.training.deep_replay import BOOTSTRAPPED

    counts = np.array([2, 2])
    config = DeepCMARLCDConfig(
        update="critic", return_lambda=0.5, record_hidden=1, critic_form="sum",
        critic_bootstrap="greedy",
    )  # fmt: skip
    ring = BOOTSTRAPPED.new(config, 1, counts, SPEC, 1)
    w1, _, w2, _ = ring.record_weights[:4]
    w1[0, 0, 0] = 1.0
    w2[0, 0] = [3.0, 10.0, 1.0, -1.0]
    replay = BOOTSTRAPPED.view(ring, 0)
    degrees = degree_layers(2, 2)
    degrees.b2[0], degrees.b2[1] = [1.0, 2.0], [2.0, 1.0]  # greedy actions (1, 0)
    store_hand_episode(replay, counts, degrees, [[0, 0], [1, 1], [1, 0]])
    assert replay.ring.reward[:3].tolist() == [4.0, 8.5, 5.875]
