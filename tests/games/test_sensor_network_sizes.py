"""The DSN at any size (R x C cells, K targets): the paper's grid plays as before, the
state numbering is a bijection, and the rules hold at several sizes."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from cmarlcd import ConfigError
from cmarlcd.games import sensor_network as dsn
from cmarlcd.games.sensor_network import layout, make_spec

SIZES = [(2, 3, 2), (3, 4, 3), (1, 3, 1), (4, 5, 4), (2, 2, 4)]


def random_episode_trace(spec, seed: int, steps: int = 60) -> list:
    """(state, reward, done, targets) after every step of random joint actions."""
    env, rng, act = spec.new_env(), np.random.default_rng(seed), np.random.default_rng(seed + 1)
    rewards, trace = np.zeros(1), []
    spec.kernels.reset(env, rng)
    for _ in range(steps):
        joint = np.array([act.integers(0, c) for c in spec.action_counts], dtype=np.int64)
        spec.kernels.step(env, joint, rng, rewards)
        done = spec.kernels.done(env)
        trace.append((spec.kernels.state(env, 0), float(rewards[0]), done, env[0].tolist()))
        if done:
            spec.kernels.reset(env, rng)
    return trace


def test_the_paper_grid_plays_the_same_episodes_as_the_paper_spec() -> None:
    sized = make_spec()
    assert sized.n_states == dsn.N_STATE_INDICES and sized.max_steps == dsn.MAX_STEPS
    assert np.array_equal(sized.action_counts, dsn.ACTION_COUNTS)
    for seed in range(5):
        assert random_episode_trace(sized, seed, 300) == random_episode_trace(dsn.SPEC, seed, 300)


@pytest.mark.parametrize(("rows", "cols", "targets"), SIZES)
def test_state_numbering_is_a_bijection_onto_the_state_count(rows, cols, targets) -> None:
    cells = rows * cols
    n = layout.state_count(cells, targets)
    offsets = layout.state_offsets(cells, targets)
    seen = set()
    for placement in itertools.product(range(-1, cells), repeat=targets):
        live = [c for c in placement if c >= 0]
        if len(set(live)) < len(live):
            continue  # two live targets never share a cell
        seen.add(layout.state_index(np.array(placement, dtype=np.int64), cells, offsets))
    assert seen == set(range(n))
    everyone_captured = np.full(targets, -1, dtype=np.int64)
    assert layout.state_index(everyone_captured, cells, offsets) == n - 1  # terminal last


def test_state_counts_by_hand() -> None:
    assert layout.state_count(6, 2) == 6 * 5 + 2 * 6 + 1 == 43  # the paper's
    assert layout.state_count(12, 3) == 12 * 11 * 10 + 3 * 12 * 11 + 3 * 12 + 1 == 1_753
    assert layout.state_count(49, 3) == 117_748  # 7 x 7 with 3 targets: past 10^5


@pytest.mark.parametrize(("rows", "cols", "targets"), SIZES)
def test_sensors_and_their_actions_follow_the_grid(rows, cols, targets) -> None:
    spec = make_spec(rows, cols, targets)
    counts = spec.action_counts
    assert len(counts) == (rows + 1) * (cols + 1) == len(spec.agents)
    corners = [0, cols, rows * (cols + 1), (rows + 1) * (cols + 1) - 1]
    assert all(counts[c] == 2 for c in corners)  # idle + the one cell a corner touches
    assert counts.sum() == (rows + 1) * (cols + 1) + 4 * rows * cols  # each cell: 4 sensors
    assert spec.max_steps == 20 * targets and spec.n_features == targets * (rows * cols + 1)


@pytest.mark.parametrize(("rows", "cols", "targets"), SIZES)
def test_rules_hold_over_random_play(rows, cols, targets) -> None:
    spec = make_spec(rows, cols, targets)
    env, rng, act = spec.new_env(), np.random.default_rng(3), np.random.default_rng(4)
    rewards, features = np.zeros(1), np.zeros(spec.n_features)
    cells = rows * cols
    for _episode in range(30):
        spec.kernels.reset(env, rng)
        live = env[0][env[0] >= 0]
        assert len(live) == targets == len(set(live.tolist())) and (env[1] == 3).all()
        for _ in range(spec.max_steps):
            before = env[0].copy()
            joint = np.array([act.integers(0, c) for c in spec.action_counts], dtype=np.int64)
            spec.kernels.step(env, joint, rng, rewards)
            after = env[0]
            assert rewards[0] == pytest.approx(env[2].sum())  # the global reward is the sum
            assert (after[before < 0] == -1).all()  # captured targets stay captured
            alive = after[after >= 0]
            assert len(set(alive.tolist())) == len(alive) and (alive < cells).all()
            captures = int(((before >= 0) & (after < 0)).sum())
            focusing = int((joint > 0).sum())
            assert rewards[0] == pytest.approx(-focusing + 30 * captures)
            spec.kernels.features(env, 0, features)
            assert features.sum() == targets  # one 1 per target: its cell or captured
            if spec.kernels.done(env):
                assert (after == -1).all()
                break


def test_three_sensors_on_a_target_capture_it_in_three_steps() -> None:
    spec = make_spec(1, 1, 1)  # one cell, four sensors touching it, one target
    env, rng, rewards = spec.new_env(), np.random.default_rng(0), np.zeros(1)
    spec.kernels.reset(env, rng)
    assert env[0].tolist() == [0]
    for step in range(3):
        spec.kernels.step(env, np.array([1, 1, 1, 0]), rng, rewards)
        assert rewards[0] == (-3 + 30 if step == 2 else -3)
    assert spec.kernels.done(env) and spec.kernels.state(env, 0) == spec.n_states - 1


@pytest.mark.parametrize(
    ("args", "parameter"),
    [
        ((0, 3, 1), "grid"),
        ((2, 3, 0), "targets"),
        ((2, 3, 7), "targets"),  # 6 cells hold at most 6 targets
        ((2, 3, 2, 0), "max_steps"),
        ((20, 20, 4), "targets"),  # 400 cells, 4 targets: about 2.6e10 states
    ],
)
def test_bad_layouts_are_refused(args, parameter) -> None:
    with pytest.raises(ConfigError) as err:
        make_spec(*args)
    assert err.value.parameter == parameter


def test_a_larger_network_passes_the_game_conformance_checks() -> None:
    from cmarlcd.testing import check_game

    check_game(make_spec(3, 4, 3))
