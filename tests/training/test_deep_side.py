"""VDN / QMIX as one side of a match: the compiled forward pass, the schedule, resuming."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from cmarlcd.compiled import kernel  # noqa: E402
from cmarlcd.errors import ConfigError  # noqa: E402
from cmarlcd.games import battlefield  # noqa: E402
from cmarlcd.learners.automata import AutomatonConfig  # noqa: E402
from cmarlcd.learners.coordination import BATTLEFIELD_CMARLCD  # noqa: E402
from cmarlcd.learners.deep_config import BATTLEFIELD_DEEP, DeepConfig  # noqa: E402
from cmarlcd.training import deep_side, match  # noqa: E402
from cmarlcd.training.match import Match, SideKernels  # noqa: E402

SMALL = dict(BATTLEFIELD_DEEP, buffer_size=500, batch_size=32, train_every=24, target_every=96)


def new_match(configs, episodes: int, seed: int = 0) -> Match:
    env, a, b = (np.random.default_rng(seed + k) for k in range(3))
    return Match(battlefield.SPEC, configs, env, (a, b), episodes)


@pytest.mark.parametrize("mixer", ["vdn", "qmix"])
def test_compiled_greedy_action_is_the_networks_argmax(mixer) -> None:
    played = new_match((DeepConfig(mixer=mixer, **SMALL), AutomatonConfig()), 40)
    played.learn()  # a few gradient steps: the weights are no longer the initial ones
    side = played.sides[0]
    assert side.model.optimizer.state  # Adam has stepped
    rng = np.random.default_rng(3)
    features = rng.random((200, battlefield.SPEC.n_features)).astype(np.float32)
    legal = rng.random((200, 6, 6)) < 0.6
    legal[:, :, 0] = True
    expected = side.model.greedy(torch.from_numpy(features)[None], torch.from_numpy(legal)[None])
    hidden = np.zeros(side.config.hidden)
    for n in range(200):
        for i in range(6):
            action = deep_side.greedy_agent(
                side.data.weights, i, features[n], legal[n, i], 6, hidden
            )
            assert action == int(expected[0, n, i])


def test_gradient_steps_and_target_copies_follow_the_schedule() -> None:
    config = DeepConfig(mixer="vdn", **SMALL)
    played = new_match((config, AutomatonConfig()), 60)
    steps, syncs = [], []
    side = played.sides[0]
    real_step, real_sync = side.model.td_step, side.model.sync_target
    side.model.td_step = lambda batch: (
        steps.append(int(side.data.counters[deep_side.TURNS])) or (real_step(batch))
    )
    side.model.sync_target = lambda: (
        syncs.append(int(side.data.counters[deep_side.TURNS])) or (real_sync())
    )
    played.learn()
    turns = int(side.data.counters[deep_side.TURNS])
    assert turns > 10 * config.train_every
    # one step at every multiple of train_every once a batch is stored; copies every 96
    first = -(-config.batch_size // config.train_every) * config.train_every
    assert steps == list(range(first, turns + 1, config.train_every))
    assert syncs == list(range(config.target_every, turns + 1, config.target_every))
    assert int(side.data.counters[deep_side.SIZE]) == min(turns, config.buffer_size)


@kernel
def always_pause(side) -> bool:
    return True


def test_a_match_stopped_after_every_turn_learns_what_an_unbroken_one_learns(monkeypatch) -> None:
    """The loop keeps its place in the clock: stopping it anywhere changes nothing."""
    configs = (BATTLEFIELD_CMARLCD, AutomatonConfig())
    unbroken = new_match(configs, 30, seed=4)
    unbroken.learn()
    real = match.Match.__init__

    def pausing(self, *args, **kwargs) -> None:
        real(self, *args, **kwargs)
        side = self.sides[0]
        side.kernels = SideKernels(*side.kernels[:5], always_pause, side.kernels[6])
        bound = {"game": self.spec.kernels, "first": side.kernels, "second": self.sides[1].kernels}
        self._learn = match.specialise(match.learn_match, **bound)

    monkeypatch.setattr(match.Match, "__init__", pausing)
    calls = []
    monkeypatch.setattr(match, "report_progress", lambda work: calls.append(work))
    broken = new_match(configs, 30, seed=4)
    broken.learn()
    assert len(calls) > 100  # one call per turn
    assert sum(calls) == 30
    for a, b in zip(unbroken.sides, broken.sides, strict=True):
        used = a.visited()
        assert used == b.visited() and np.array_equal(a.data.rows, b.data.rows)
        assert np.array_equal(a.data.tables.r_max[:used], b.data.tables.r_max[:used])


def test_same_seeds_same_deep_match() -> None:
    results = []
    for _ in range(2):
        played = new_match((DeepConfig(mixer="qmix", **SMALL), BATTLEFIELD_CMARLCD), 40, seed=8)
        played.learn()
        results.append(played.evaluate(50, np.random.default_rng(1)))
    assert results[0] == results[1]
    assert sum(results[0].wins) + results[0].ties == 50


def test_a_deep_side_needs_state_features() -> None:
    featureless = dataclasses.replace(battlefield.SPEC, n_features=0)
    rng = np.random.default_rng(0)
    with pytest.raises(ConfigError, match="state features"):
        Match(featureless, (DeepConfig(), AutomatonConfig()), rng, (rng, rng), 5)


@pytest.mark.parametrize("pairing", ["qmix-vdn", "cmarl-cd-vdn"])
def test_matches_learning_in_a_batch_play_what_they_play_alone(pairing) -> None:
    deep = {"qmix": DeepConfig(mixer="qmix", **SMALL), "vdn": DeepConfig(mixer="vdn", **SMALL)}
    configs = (
        (deep["qmix"], deep["vdn"]) if pairing == "qmix-vdn" else (BATTLEFIELD_CMARLCD, deep["vdn"])
    )
    positions = [(0, 1), (1, 0), (0, 1)]  # rounds swap sides

    def streams(m: int):
        rng = np.random.default_rng
        return rng(100 + m), (rng(200 + m), rng(300 + m))

    envs, agents = zip(*(streams(m) for m in range(3)), strict=True)
    batch = match.MatchBatch(battlefield.SPEC, configs, positions, envs, agents, 50)
    batch.learn()
    for m, order in enumerate(positions):
        env, rngs = streams(m)
        alone = Match(battlefield.SPEC, [configs[p] for p in order], env, rngs, 50)
        alone.learn()
        assert alone.turns == batch.matches[m].turns
        rng = np.random.default_rng(7)
        assert alone.evaluate(100, rng) == batch.matches[m].evaluate(100, np.random.default_rng(7))
