"""Deep CMARL-CD's self-imitation gated by the record (``update="imitation"``): its loss on
hand-computed cases (a visit above the record imitated by its margin, one within the
tolerance, a lower return moving no degree), what a step does to the strategy, an
unseen state borrowing from its neighbour through the network, determinism, and a
one-state game solved."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cmarlcd import ConfigError
from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig
from cmarlcd.learners.deep.designs import IMITATION_DEEP_CMARLCD

torch = pytest.importorskip("torch")

from cmarlcd.learners.deep.degree_model import DegreeModel  # noqa: E402


def constant_model(degrees: list[float], record: float, **settings) -> DegreeModel:
    """One seed, one agent of ``len(degrees)`` actions, one feature: every state's degrees
    are ``degrees`` and its target record ``record`` (weights zero, biases set)."""
    config = DeepCMARLCDConfig(update="imitation", **settings)
    net = DegreeModel([len(degrees)], 1, config, [np.random.SeedSequence(0)], device="cpu")
    with torch.no_grad():
        for layer in (net.agents.first, net.agents.second, net.target_record.first):
            layer.weight.zero_()
        net.agents.first.bias.fill_(1.0)  # ReLU(1) = 1 reaches the second layer's bias only
        net.agents.second.bias[0] = torch.tensor(degrees)
        net.target_record.first.bias.zero_()
        net.target_record.second.weight.zero_()
        net.target_record.second.bias.fill_(record)
    return net


def batch(returns: list[float], actions: list[int]) -> dict[str, torch.Tensor]:
    count = len(returns)
    return {
        "state": torch.ones((1, count, 1)),
        "actions": torch.tensor(actions).reshape(1, count, 1),
        "reward": torch.tensor([returns]),
    }


def test_the_loss_by_hand() -> None:
    """Degrees (1, 2), T 1: π = (e/(e+e²), e²/(e+e²)) = (0.26894, 0.73106). Returns 3 and
    1, record 1.5, their spread (standard deviation) 1, tolerance 0.1: the first visit
    passes the record by 1.5 spreads, weight 1.6; the second is 0.5 below, weight 0.
    Imitation: 1.6 · (−log 0.26894) / 2 visits = 1.05064; no degree outside [0.5, 3]."""
    net = constant_model([1.0, 2.0], record=1.5, tolerance=0.1)
    data = batch([3.0, 1.0], [0, 1])
    record = net.record_loss(data["state"], data["reward"])
    imitation = net.imitation_loss(data) - record
    assert float(imitation.detach()) == pytest.approx(1.6 * -math.log(0.26894142) / 2, rel=1e-5)


def test_a_degree_outside_the_bounds_is_pulled_back() -> None:
    """Degrees (4, 0): the strategy reads (3, 0.5); the range penalty adds (4 − 3)² +
    (0.5 − 0)² = 1.25, and nothing is imitated (a lower return)."""
    net = constant_model([4.0, 0.0], record=10.0, tolerance=0.1)
    data = batch([0.0, 1.0], [0, 1])
    loss = net.imitation_loss(data) - net.record_loss(data["state"], data["reward"])
    assert float(loss.detach()) == pytest.approx(1.25, rel=1e-6)


def test_a_return_above_the_record_raises_its_action_and_a_lower_one_moves_nothing() -> None:
    above = constant_model([1.5, 1.5, 1.5], record=0.0, tolerance=0.1)
    above.learn(batch([2.0, 1.0], [2, 2]))
    degrees = above.agents(torch.ones((1, 1, 1)))[0, 0, 0].detach()
    assert degrees[2] > 1.5 > degrees[0] and degrees[0] == pytest.approx(float(degrees[1]))

    below = constant_model([1.5, 1.5, 1.5], record=10.0, tolerance=0.1)
    before = [p.detach().clone() for p in below.agents.parameters()]
    below.learn(batch([2.0, 1.0], [2, 0]))  # both far below the record: weight 0
    for p, q in zip(below.agents.parameters(), before, strict=True):
        assert torch.equal(p.detach(), q)


def test_a_tie_within_the_tolerance_is_imitated_and_just_below_it_is_not() -> None:
    """Record 2, returns 2.0 and 0.0 (spread 1): the first is 0 spreads off (weight =
    the tolerance, 0.5), the second 2 spreads below (weight 0)."""
    net = constant_model([1.5, 1.5], record=2.0, tolerance=0.5)
    net.learn(batch([2.0, 0.0], [1, 0]))
    degrees = net.agents(torch.ones((1, 1, 1)))[0, 0, 0].detach()
    assert degrees[1] > 1.5 > degrees[0]


def test_an_unseen_state_borrows_from_its_neighbour() -> None:
    """Feature states 1.0 and 1.1 (close), trained only at 1.0 towards action 1: the
    network's greedy action at 1.1, never visited, becomes action 1 too."""
    config = DeepCMARLCDConfig(update="imitation", tolerance=0.1, lr=0.01)
    net = DegreeModel([3], 1, config, [np.random.SeedSequence(4)], device="cpu")
    unseen = torch.full((1, 1, 1), 1.1)
    start = net.agents(unseen)[0, 0, 0].detach()
    data = {
        "state": torch.ones((1, 2, 1)),
        "actions": torch.tensor([[[1], [0]]]),
        "reward": torch.tensor([[5.0, -5.0]]),
    }
    for _ in range(200):
        net.learn(data)
    after = net.agents(unseen)[0, 0, 0].detach()
    assert int(after.clamp(0.5, 3.0).argmax()) == 1
    assert after[1] - after[0] > start[1] - start[0]


def test_the_same_seed_learns_the_same_weights() -> None:
    def weights() -> list[torch.Tensor]:
        net = DegreeModel([3, 2], 2, IMITATION_DEEP_CMARLCD, [np.random.SeedSequence(9)])
        rng = np.random.default_rng(1)
        for _ in range(5):
            net.learn(
                {
                    "state": torch.as_tensor(rng.normal(size=(1, 8, 2)).astype(np.float32)),
                    "actions": torch.as_tensor(np.stack([rng.integers(0, 3, (1, 8)),
                                                         rng.integers(0, 2, (1, 8))], -1)),
                    "reward": torch.as_tensor(rng.normal(size=(1, 8)).astype(np.float32)),
                }
            )  # fmt: skip
        return [p.detach().clone() for p in net.parameters()]

    for a, b in zip(weights(), weights(), strict=True):
        assert torch.equal(a, b)


def test_it_takes_a_ring_of_visits_and_acts_from_its_network() -> None:
    config = DeepCMARLCDConfig(update="imitation")
    assert not config.keyed and config.ready(config.batch_size) and not config.ready(1)
    with pytest.raises(ConfigError, match="update='imitation' set act_from=network"):
        DeepCMARLCDConfig(update="imitation", act_from="memory")
    with pytest.raises(ConfigError, match="step"):
        DeepCMARLCDConfig(update="imitation", step="fused")


def test_a_one_state_game_is_solved() -> None:
    """The climbing game as a one-step stochastic game (optimum (0, 0), 11, among 7, 6,
    5), in 10,000 episodes: every seed's greedy joint action is the optimum."""
    from cmarlcd.games.matrix import climbing_game
    from cmarlcd.training.deep import DeepBatch

    spec = climbing_game().spec()
    config = DeepCMARLCDConfig(
        update="imitation", tolerance=0.1, expectile=0.9, buffer_size=500, batch_size=50,
        train_every=10, target_every=50,
    )  # fmt: skip
    final = {}
    run = DeepBatch(spec, config, [np.random.SeedSequence(k) for k in range(5)], 10_000)
    run.train([], lambda k, budget, policy: final.__setitem__(k, policy.table[0].tolist()))
    assert list(final.values()) == [[0, 0]] * 5


@pytest.mark.slow
def test_the_design_passes_every_learner_check() -> None:
    from cmarlcd.testing import check_learner

    check_learner(IMITATION_DEEP_CMARLCD)


def test_the_command_line_runs_the_designs_and_refuses_a_bad_lambda(tmp_path) -> None:
    """``train`` on LBF with self-imitation on λ-returns, end to end on a tiny budget; a
    λ out of range is one line and status 2."""
    import subprocess
    import sys

    base = [sys.executable, "-m", "cmarlcd", "train", "--game", "foraging:5x5-2p-1f",
            "--algorithms", "deep-cmarl-cd", "--steps", "2k", "--runs", "1", "--curve-points",
            "2", "--eval-episodes", "2", "--workers", "1", "--no-progress",
            "--store", str(tmp_path / "s.sqlite"), "--figures", str(tmp_path / "f")]  # fmt: skip
    good = (
        "deep-cmarl-cd.update=imitation,deep-cmarl-cd.return_lambda=0.9,deep-cmarl-cd.batch_size=32"
    )
    done = subprocess.run([*base, "--set", good], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    assert "1 runs computed" in done.stdout or "1 run computed" in done.stdout, done.stdout
    bad = "deep-cmarl-cd.update=imitation,deep-cmarl-cd.return_lambda=2"
    done = subprocess.run([*base, "--set", bad], capture_output=True, text=True, check=False)
    assert done.returncode == 2
    assert "deep-cmarl-cd.return_lambda must be in [0, 1] (got 2.0)" in done.stderr
    assert done.stderr.strip().count("\n") == 0, done.stderr
