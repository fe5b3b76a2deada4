"""VDN / QMIX as one side of a match: the compiled forward pass, the schedule, resuming."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from cmarlcd.compiled import kernel  # noqa: E402
from cmarlcd.errors import ConfigError  # noqa: E402
from cmarlcd.games import battlefield  # noqa: E402
from cmarlcd.learners.deep.config import BATTLEFIELD_DEEP, DeepConfig  # noqa: E402
from cmarlcd.learners.tabular.automata import AutomatonConfig  # noqa: E402
from cmarlcd.learners.tabular.coordination import BATTLEFIELD_CMARLCD  # noqa: E402
from cmarlcd.training import deep_kernels, loop, match  # noqa: E402
from cmarlcd.training.match import Match  # noqa: E402
from cmarlcd.training.protocol import SideKernels  # noqa: E402

SMALL = dict(BATTLEFIELD_DEEP, buffer_size=500, batch_size=32, train_every=24, target_every=96)


def stepped(model) -> bool:
    """Whether the model has taken a gradient step (autograd's Adam holds moments, or
    the fused step counts its steps)."""
    return bool(model.optimizer.state) or (model.fused is not None and model.fused.steps > 0)


def new_match(configs, episodes: int, seed: int = 0) -> Match:
    env, a, b = (np.random.default_rng(seed + k) for k in range(3))
    return Match(battlefield.SPEC, configs, env, (a, b), episodes)


@pytest.mark.parametrize("mixer", ["vdn", "qmix"])
def test_compiled_greedy_action_is_the_networks_argmax(mixer) -> None:
    played = new_match((DeepConfig(mixer=mixer, **SMALL), AutomatonConfig()), 40)
    played.learn()  # a few gradient steps: the weights are no longer the initial ones
    side = played.sides[0]
    assert stepped(side.model)
    rng = np.random.default_rng(3)
    features = rng.random((200, battlefield.SPEC.n_features)).astype(np.float32)
    legal = rng.random((200, 6, 6)) < 0.6
    legal[:, :, 0] = True
    expected = side.model.greedy(torch.from_numpy(features)[None], torch.from_numpy(legal)[None])
    hidden = np.zeros(side.config.hidden, np.float32)
    for n in range(200):
        for i in range(6):
            action = deep_kernels.greedy_agent(
                side.data.weights, i, features[n], legal[n, i], 6, hidden
            )
            assert action == int(expected[0, n, i])


@pytest.mark.parametrize("mixer", ["vdn", "qmix"])
def test_greedy_cache_changes_no_action(mixer) -> None:
    """The battlefield's state determines its features: its deep sides keep the greedy
    actions they computed at each state. They play exactly as a game that does not say
    so (every action from the networks), learning and in the evaluations between
    learning stages, where the weights have changed since the last."""
    uncached = dataclasses.replace(battlefield.SPEC, state_determines_features=False)
    configs = (DeepConfig(mixer=mixer, **SMALL), DeepConfig(mixer="vdn", **SMALL))
    plays = []
    for spec in (battlefield.SPEC, uncached):
        env, a, b = (np.random.default_rng(k) for k in range(3))
        plays.append(Match(spec, configs, env, (a, b), 120))
    cached, plain = plays
    assert cached.sides[0].data.cache.keys.size > 0 and plain.sides[0].data.cache.keys.size == 0
    for stage in range(3):
        results = []
        for played in plays:
            played.learn(40)
            results.append(played.evaluate(300, np.random.default_rng(10 + stage)))
        assert results[0] == results[1]
        assert cached.turns == plain.turns
    side = cached.sides[0]
    assert stepped(side.model) and int(side.counters[deep_kernels.GENERATION]) > 2
    assert (side.data.cache.actions >= 0).any()  # the cache was used


def test_gradient_steps_and_target_copies_follow_the_schedule() -> None:
    config = DeepConfig(mixer="vdn", **SMALL)
    played = new_match((config, AutomatonConfig()), 60)
    steps, syncs = [], []
    side = played.sides[0]
    real_step, real_sync = side.model.td_step, side.model.sync_target
    side.model.td_step = lambda batch: (
        steps.append(int(side.data.counters[deep_kernels.TURNS])) or (real_step(batch))
    )
    side.model.sync_target = lambda: (
        syncs.append(int(side.data.counters[deep_kernels.TURNS])) or (real_sync())
    )
    played.learn()
    turns = int(side.data.counters[deep_kernels.TURNS])
    assert turns > 10 * config.train_every
    # one step at every multiple of train_every once a batch is stored; copies every 96
    first = -(-config.batch_size // config.train_every) * config.train_every
    assert steps == list(range(first, turns + 1, config.train_every))
    assert syncs == list(range(config.target_every, turns + 1, config.target_every))
    assert int(side.data.replay.size[0]) == min(turns, config.buffer_size)


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
        self._learn = loop.specialise(loop.learn_turns, **bound)

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


def test_a_deep_side_reads_state_indices_where_a_game_has_no_features() -> None:
    from cmarlcd.testing import DUEL

    featureless = dataclasses.replace(DUEL, n_features=0)
    played = new_match_on(featureless, (DeepConfig(mixer="qmix", **SMALL), AutomatonConfig()), 60)
    played.learn()
    side = played.sides[0]
    assert side.group.inputs == "index" and stepped(side.model)
    result = played.evaluate(50, np.random.default_rng(1))
    assert sum(result.wins) + result.ties == 50


def test_a_deep_side_without_features_needs_a_game_small_enough_for_one_hot_states() -> None:
    featureless = dataclasses.replace(battlefield.SPEC, n_features=0)
    rng = np.random.default_rng(0)
    with pytest.raises(ConfigError, match="no state features and 802,816 states"):
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


def test_a_turn_goes_into_the_replay_ring_as_a_hand_built_transition() -> None:
    """Turn t's features, joint action and reward, and turn t + 1's features and masks
    as its successor; a terminal turn's successor is zeros with every action legal (never
    bootstrapped from, but its maximum must stay finite)."""
    from cmarlcd.testing import DUEL

    config = DeepConfig(buffer_size=4, batch_size=2, train_every=2, target_every=4)
    side = new_match_on(DUEL, (config, AutomatonConfig()), 5).sides[0].data
    side.obs[:3] = [[0.0, 0.0], [0.5, 0.0], [1.0, 0.25]]  # exact in float32
    side.legal[:3] = True
    side.legal[1, 1, 2] = False  # turn 1: agent 1 may not play action 2
    side.joints[:2] = [[0, 0], [2, 1]]
    side.rewards[:2] = [0.0, 5.0]
    start = int(side.replay.position[0])
    deep_kernels.features_observe(side, 0, 1, False)
    deep_kernels.features_observe(side, 1, 2, True)
    ring = side.replay
    first, second = start, (start + 1) % 4
    assert ring.state[first].tolist() == [0.0, 0.0]
    assert ring.next_state[first].tolist() == [0.5, 0.0]
    assert ring.actions[first].tolist() == [0, 0] and ring.reward[first] == 0.0
    assert not ring.terminal[first]
    assert ring.next_legal[first].tolist() == [[True, True, True], [True, True, False]]
    assert ring.state[second].tolist() == [0.5, 0.0]
    assert ring.next_state[second].tolist() == [0, 0]
    assert ring.actions[second].tolist() == [2, 1] and ring.reward[second] == 5.0
    assert ring.terminal[second] and ring.next_legal[second].all()


def new_match_on(spec, configs, episodes: int) -> Match:
    env, a, b = (np.random.default_rng(k) for k in range(3))
    return Match(spec, configs, env, (a, b), episodes)


def test_a_deep_side_explores_only_legal_actions() -> None:
    """ε = 1: every action is a uniform draw over the legal ones, never a masked one."""
    from cmarlcd.testing import DUEL

    random = DeepConfig(eps_start=1.0, eps_end=1.0, eps_after=1.0, **SMALL)
    side = new_match_on(DUEL, (random, AutomatonConfig()), 5).sides[0].data
    side.obs[0] = [0.5, 0.0]
    side.legal[0] = True
    side.legal[0, 1, 2] = False
    joint = np.zeros(2, dtype=np.int64)
    rng = np.random.default_rng(0)
    seen = set()
    for _ in range(300):
        deep_kernels.features_act(side, 0, rng, joint)
        seen.add(int(joint[1]))
    assert seen == {0, 1}


def test_a_match_of_a_batch_refuses_to_learn_on_its_own() -> None:
    """Its deep side waits for the batch's gradient step: learning it alone would stop
    after every turn and never train, so it is refused in one line."""
    deep = DeepConfig(mixer="vdn", **SMALL)
    rngs = [np.random.default_rng(k) for k in range(6)]
    batch = match.MatchBatch(
        battlefield.SPEC, (deep, AutomatonConfig()), [(0, 1), (1, 0)], rngs[:2],
        [(rngs[2], rngs[3]), (rngs[4], rngs[5])], 20,
    )  # fmt: skip
    with pytest.raises(ConfigError, match="learns in a batch"):
        batch.matches[0].learn()
