"""Deep CMARL-CD's λ-returns recomputed at each target copy (``refresh_returns``): the
kernel by hand on one episode and on a ring that has wrapped, the returns the compiled
store computed found again from the same estimates, the loop recomputing them at a
target copy, determinism, and the setting refused where no λ-return is stored."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from cmarlcd import ConfigError
from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig
from cmarlcd.learners.deep.designs import SHARES_DEEP_CMARLCD
from cmarlcd.learners.deep.replay import (
    new_ring,
    push_visit,
    recompute_lambda_returns,
    seed_view,
)
from tests.learners.deep.lambda_case import SPEC, degree_layers, store_hand_episode

pytest.importorskip("torch")


def ring_of(capacity: int, episodes: list[list[float]]) -> tuple:
    """A one-seed ring of integer states with ``episodes`` (each a list of rewards) pushed
    as the compiled store pushes them, last step first, with a return of −1 each (to be
    recomputed), and their own rewards; the state of step t of episode e is 10 e + t."""
    view = seed_view(new_ring(1, capacity, 1, 2, 100), 0)
    rewards = np.zeros(capacity, np.float32)
    for e, episode in enumerate(episodes):
        for t in range(len(episode) - 1, -1, -1):
            p = int(view.position[0])
            push_visit(view, 10 * e + t, np.zeros(1, np.int64), -1.0)
            view.terminal[p], rewards[p] = t == len(episode) - 1, episode[t]
    return view, rewards


def test_one_episode_by_hand() -> None:
    """Rewards 1, 2, 4, γ 0.5, λ 0.5, V(s_1) = 11, V(s_2) = 22: G_2 = 4, G_1 = 2 + 0.5
    (0.5 · 22 + 0.5 · 4) = 8.5, G_0 = 1 + 0.5 (0.5 · 11 + 0.5 · 8.5) = 5.875."""
    view, rewards = ring_of(8, [[1.0, 2.0, 4.0]])
    values = np.zeros(8)
    for p in range(3):  # V of the visit's own state: s_0 0, s_1 11, s_2 22
        values[p] = {0: 0.0, 1: 11.0, 2: 22.0}[int(view.state[p])]
    recompute_lambda_returns(view, rewards, values, 0.5, 0.5)
    by_step = {int(view.state[p]): float(view.reward[p]) for p in range(3)}
    assert by_step == {2: 4.0, 1: 8.5, 0: 5.875}


def test_lambda_zero_gives_one_step_returns() -> None:
    """λ 0 (the one-step form): rewards 1, 2, 4, γ 0.5, V(s_1) = 11, V(s_2) = 22: G_2 = 4
    (the episode's end), G_1 = 2 + 0.5 · 22 = 13, G_0 = 1 + 0.5 · 11 = 6.5; no later
    return reaches an earlier one."""
    view, rewards = ring_of(8, [[1.0, 2.0, 4.0]])
    values = np.zeros(8)
    for p in range(3):
        values[p] = {0: 0.0, 1: 11.0, 2: 22.0}[int(view.state[p])]
    recompute_lambda_returns(view, rewards, values, 0.5, 0.0)
    by_step = {int(view.state[p]): float(view.reward[p]) for p in range(3)}
    assert by_step == {2: 4.0, 1: 13.0, 0: 6.5}


def test_a_wrapped_ring_keeps_the_return_whose_successor_is_gone() -> None:
    """Capacity 4, two episodes of 3 visits: the second overwrites the first's last two
    steps, so the first's step 0 (the oldest visit) keeps its return (−1); the second
    episode's rewards 1, 1, 1 with every value 2, γ 1, λ 0.5: G_2 = 1, G_1 = 1 + (0.5 · 2
    + 0.5 · 1) = 2.5, G_0 = 1 + (0.5 · 2 + 0.5 · 2.5) = 3.25."""
    view, rewards = ring_of(4, [[5.0, 5.0, 5.0], [1.0, 1.0, 1.0]])
    recompute_lambda_returns(view, rewards, np.full(4, 2.0), 1.0, 0.5)
    by_state = {int(s): float(g) for s, g in zip(view.state, view.reward, strict=True)}
    assert by_state == {0: -1.0, 12: 1.0, 11: 2.5, 10: 3.25}


def test_the_stores_returns_are_found_again_from_the_same_estimates() -> None:
    """The compiled store's λ-returns (the record network's 11x at the next visit's
    feature x, γ 0.5, λ 0.5; rewards 1, 2, 4: 4, 8.5, 5.875 as by hand above), then
    recomputed from the record's estimate of each stored visit: the same returns."""
    from cmarlcd.training.deep_replay import BOOTSTRAPPED

    config = DeepCMARLCDConfig(update="imitation", return_lambda=0.5, record_hidden=1)
    ring = BOOTSTRAPPED.new(config, 1, np.array([2]), SPEC, 1)
    ring.record_weights.w1[0, 0, 0], ring.record_weights.w2[0, 0, 0] = 1.0, 11.0
    replay = BOOTSTRAPPED.view(ring, 0)
    store_hand_episode(replay, np.array([2]), degree_layers(1, 2), [[0], [1], [1]])
    stored = replay.ring.reward[:3].copy()
    assert stored.tolist() == [4.0, 8.5, 5.875]
    values = 11.0 * replay.ring.state[:, 0].astype(np.float64)
    recompute_lambda_returns(replay.ring, replay.step_reward, values, 0.5, 0.5)
    assert replay.ring.reward[:3].tolist() == stored.tolist()
    assert replay.ring.terminal[:3].tolist() == [True, False, False]


def test_the_loop_recomputes_at_a_target_copy() -> None:
    """On LBF's features, the shares design with a target copy every gradient step: the
    ring's returns at the end are those recomputed from the model's estimates at the last
    copy (its estimate of the oldest ... newest visits), not those stored at each
    episode's end; and the same seed learns the same weights."""
    from cmarlcd.experiments import games
    from cmarlcd.training.deep import DeepBatch

    spec = games.parse_game("foraging:5x5-2p-1f")[1].spec()
    config = replace(
        SHARES_DEEP_CMARLCD, batch_size=64, buffer_size=2000, train_every=25, target_every=1
    )

    def run(refresh: bool) -> tuple[np.ndarray, list]:
        batch = DeepBatch(
            spec, replace(config, refresh_returns=refresh), [np.random.SeedSequence(3)], 40
        )
        batch.train([], lambda *args: None)
        stored = batch.group.ring.ring.reward[0].copy()
        return stored, [p.detach().clone() for p in batch.group.model.parameters()]

    plain, refreshed = run(False), run(True)
    again = run(True)
    assert not np.array_equal(plain[0], refreshed[0])
    assert np.array_equal(refreshed[0], again[0])
    assert all((a == b).all() for a, b in zip(refreshed[1], again[1], strict=True))


def test_it_needs_stored_lambda_returns() -> None:
    with pytest.raises(ConfigError, match="refresh_returns: recomputes λ-returns"):
        DeepCMARLCDConfig(update="imitation", refresh_returns=True)
    with pytest.raises(ConfigError, match="refresh_returns"):
        DeepCMARLCDConfig(refresh_returns=True)  # the keyed memory
    assert DeepCMARLCDConfig(update="imitation", return_lambda=0.9, refresh_returns=True)
