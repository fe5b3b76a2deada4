"""The distributed sensor network task (Section V-A, Fig. 3).

Expected values are worked out by hand from the picture of the grid::

    s0 --- s1 --- s2 --- s3
    |  c0  |  c1  |  c2  |
    s4 --- s5 --- s6 --- s7
    |  c3  |  c4  |  c5  |
    s8 --- s9 --- s10 -- s11
"""

from __future__ import annotations

import math
import re
from collections import Counter
from itertools import product

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test, parallel_seed_test

from cmarlcd.errors import ConfigError
from cmarlcd.games import sensor_network as dsn
from cmarlcd.games.sensor_network import (
    SensorNetworkEnv,
    decode_state,
    done,
    dsn_move_targets,
    dsn_reset,
    dsn_sensor_phase,
    dsn_state,
    dsn_step,
    encode_state,
    optimal_joint_action,
    render_text,
)

# Cells each sensor touches, read off the picture (action k + 1 focuses the k-th).
TOUCHED = [[0], [0, 1], [1, 2], [2], [0, 3], [0, 1, 3, 4], [1, 2, 4, 5], [2, 5], [3], [3, 4]]
TOUCHED += [[4, 5], [5]]
UP, DOWN, LEFT, RIGHT, STAY = 1, 2, 3, 4, 0


def joint_focusing(focus: dict[int, int]) -> np.ndarray:
    """The joint action in which sensor ``s`` focuses cell ``focus[s]``, the rest idle."""
    joint = np.zeros(12, dtype=np.int64)
    for sensor, cell in focus.items():
        joint[sensor] = 1 + TOUCHED[sensor].index(cell)
    return joint


def arrays(targets: tuple[int, int], energy: tuple[int, int] = (3, 3)):
    return np.array(targets, dtype=np.int64), np.array(energy, dtype=np.int64)


def sensor_phase(targets, energy, focus: dict[int, int]) -> tuple[float, np.ndarray]:
    individual = np.full(12, np.nan)
    reward = dsn_sensor_phase(targets, energy, joint_focusing(focus), individual)
    return reward, individual


def random_joint(rng: np.random.Generator) -> np.ndarray:
    return np.array([rng.integers(len(cells) + 1) for cells in TOUCHED], dtype=np.int64)


# ------------------------------------------------------------------------ geometry


def test_geometry_matches_the_picture() -> None:
    assert dsn.ACTION_COUNTS.tolist() == [2, 3, 3, 2, 3, 5, 5, 3, 2, 3, 3, 2]
    assert math.prod(dsn.ACTION_COUNTS.tolist()) == 291_600 == 2**4 * 3**6 * 5**2
    for sensor, cells in enumerate(TOUCHED):
        assert dsn.SENSOR_CELLS[sensor].tolist() == cells + [-1] * (4 - len(cells))
    touches = Counter(c for cells in TOUCHED for c in cells)
    assert touches == dict.fromkeys(range(6), 4)
    assert Counter(dsn.SENSOR_CELLS[dsn.SENSOR_CELLS >= 0].tolist()) == touches
    corners, edges, interior = [0, 3, 8, 11], [1, 2, 4, 7, 9, 10], [5, 6]
    assert {int(dsn.ACTION_COUNTS[s]) for s in corners} == {2}
    assert {int(dsn.ACTION_COUNTS[s]) for s in edges} == {3}
    assert {int(dsn.ACTION_COUNTS[s]) for s in interior} == {5}
    assert dsn.MAX_ACTIONS == 5 and dsn.SENSOR_CELLS.shape == (12, 4)
    assert dsn.SENSOR_CELLS.dtype == dsn.ACTION_COUNTS.dtype == np.int64


def test_states_are_a_bijection_with_target_configurations() -> None:
    pairs = [(a, b) for a, b in product(range(-1, 6), repeat=2) if a != b or a == -1]
    assert len(pairs) == 30 + 6 + 6 + 1
    codes = [encode_state(a, b) for a, b in pairs]
    assert sorted(codes) == list(range(43))
    for (a, b), code in zip(pairs, codes, strict=True):
        assert decode_state(code) == (a, b)
        assert dsn_state(np.array([a, b], dtype=np.int64)) == code
    both_alive = [code for (a, b), code in zip(pairs, codes, strict=True) if a >= 0 and b >= 0]
    assert sorted(both_alive) == list(range(30))
    # the fixed encoding, by hand
    assert encode_state(0, 1) == 0 and encode_state(1, 0) == 5 and encode_state(5, 4) == 29
    assert encode_state(2, 4) == 2 * 5 + 3 and encode_state(4, 2) == 4 * 5 + 2
    assert encode_state(-1, 3) == 33 and encode_state(2, -1) == 38
    assert encode_state(-1, -1) == dsn.TERMINAL_STATE == 42 == dsn.N_STATES
    assert dsn.N_STATE_INDICES == 43


@pytest.mark.parametrize(("t0", "t1"), [(2, 2), (6, 0), (0, -2)])
def test_encode_rejects_impossible_configurations(t0: int, t1: int) -> None:
    with pytest.raises(ConfigError):
        encode_state(t0, t1)


@pytest.mark.parametrize("index", [-1, 43])
def test_decode_rejects_out_of_range_indices(index: int) -> None:
    with pytest.raises(ConfigError):
        decode_state(index)


# --------------------------------------------------------------------------- reset


def test_reset_places_targets_in_distinct_uniform_cells() -> None:
    rng = np.random.default_rng(2024)
    targets, energy = arrays((-1, -1), (0, 0))
    counts: Counter[tuple[int, int]] = Counter()
    n = 30_000
    for _ in range(n):
        dsn_reset(targets, energy, rng)
        assert energy.tolist() == [3, 3]
        counts[(int(targets[0]), int(targets[1]))] += 1
    assert set(counts) == {(a, b) for a, b in product(range(6), repeat=2) if a != b}
    expected = n / 30  # 1000, standard deviation about 31
    assert all(abs(c - expected) < 150 for c in counts.values()), counts


def test_reset_uses_exactly_two_draws_in_order() -> None:
    for seed in range(50):
        rng = np.random.default_rng(seed)
        targets, energy = arrays((-1, -1), (0, 0))
        dsn_reset(targets, energy, rng)
        u = np.random.default_rng(seed).random(3)
        first = int(6 * u[0])
        second = int(5 * u[1])
        second += second >= first
        assert targets.tolist() == [first, second]
        assert rng.random() == u[2]  # the stream moved on by exactly two draws


# ------------------------------------------------------------------ hits, captures


def test_three_sensors_hit_four_hit_once_two_miss() -> None:
    targets, energy = arrays((4, 0))
    sensor_phase(targets, energy, {5: 4, 6: 4, 9: 4})
    assert energy.tolist() == [2, 3]
    sensor_phase(targets, energy, {5: 4, 6: 4, 9: 4, 10: 4})
    assert energy.tolist() == [1, 3]
    sensor_phase(targets, energy, {5: 4, 10: 4, 0: 0, 1: 0})
    assert energy.tolist() == [1, 3] and targets.tolist() == [4, 0]


def test_three_hits_capture_the_target() -> None:
    targets, energy = arrays((1, 3))
    for hit in range(3):
        assert targets.tolist() == [1, 3]
        sensor_phase(targets, energy, {1: 1, 2: 1, 6: 1})
        assert energy.tolist() == [2 - hit, 3]
    assert targets.tolist() == [-1, 3] and not done(targets)
    sensor_phase(targets, energy, {1: 1, 2: 1, 6: 1, 5: 1})  # nothing left to hit
    assert energy.tolist() == [0, 3] and targets.tolist() == [-1, 3]


def test_focusing_empty_cells_costs_one_per_sensor() -> None:
    targets, energy = arrays((0, 5))
    reward, individual = sensor_phase(targets, energy, {5: 4, 6: 4, 9: 4, 2: 1, 8: 3})
    assert reward == -5.0
    assert individual.tolist() == [0, 0, -1, 0, 0, -1, -1, 0, -1, -1, 0, 0]
    assert energy.tolist() == [3, 3]
    assert sensor_phase(targets, energy, {})[0] == 0.0


def test_capture_by_three_sensors_pays_27() -> None:
    targets, energy = arrays((4, 0), (1, 3))
    reward, individual = sensor_phase(targets, energy, {5: 4, 6: 4, 9: 4})
    assert reward == 27.0
    assert individual.tolist() == [0, 0, 0, 0, 0, 9, 9, 0, 0, 9, 0, 0]
    assert targets.tolist() == [-1, 0] and energy.tolist() == [0, 3]


def test_capture_by_four_sensors_credits_the_three_highest_indexed() -> None:
    targets, energy = arrays((2, 4), (3, 1))
    reward, individual = sensor_phase(targets, energy, {5: 4, 6: 4, 9: 4, 10: 4, 0: 0})
    assert reward == 30.0 - 5.0
    assert individual.tolist() == [-1, 0, 0, 0, 0, -1, 9, 0, 0, 9, 9, 0]
    assert targets.tolist() == [2, -1] and energy.tolist() == [3, 0]


def test_simultaneous_captures_pay_each() -> None:
    targets, energy = arrays((0, 5), (1, 1))
    reward, individual = sensor_phase(targets, energy, {0: 0, 1: 0, 4: 0, 7: 5, 10: 5, 11: 5})
    assert reward == 60.0 - 6.0
    assert individual.tolist() == [9, 9, 0, 0, 9, 0, 0, 9, 0, 0, 9, 9]
    assert done(targets) and dsn_state(targets) == dsn.TERMINAL_STATE


# ------------------------------------------------------------------------ movement


MOVES = [  # (cell, move, destination) with the other target out of the way
    (0, UP, 0), (0, LEFT, 0), (0, STAY, 0), (0, DOWN, 3), (0, RIGHT, 1),
    (2, RIGHT, 2), (2, UP, 2), (2, LEFT, 1), (3, DOWN, 3), (3, LEFT, 3), (3, UP, 0),
    (5, DOWN, 5), (5, RIGHT, 5), (5, UP, 2), (4, UP, 1), (4, LEFT, 3), (4, RIGHT, 5),
    (1, DOWN, 4), (4, DOWN, 4),
]  # fmt: skip


@pytest.mark.parametrize(("cell", "move", "destination"), MOVES)
def test_moves_off_the_grid_are_not_executed(cell: int, move: int, destination: int) -> None:
    targets = np.array([cell, -1], dtype=np.int64)
    dsn_move_targets(targets, np.array([move, RIGHT], dtype=np.int64))
    assert targets.tolist() == [destination, -1]
    targets = np.array([-1, cell], dtype=np.int64)
    dsn_move_targets(targets, np.array([DOWN, move], dtype=np.int64))
    assert targets.tolist() == [-1, destination]


def test_move_into_the_other_live_target_is_not_executed() -> None:
    targets = np.array([0, 1], dtype=np.int64)
    dsn_move_targets(targets, np.array([RIGHT, STAY], dtype=np.int64))
    assert targets.tolist() == [0, 1]
    targets = np.array([4, 1], dtype=np.int64)
    dsn_move_targets(targets, np.array([STAY, DOWN], dtype=np.int64))
    assert targets.tolist() == [4, 1]


def test_target_zero_moves_first() -> None:
    # both head for cell 1: target 0 gets there first, target 1 is blocked
    targets = np.array([0, 2], dtype=np.int64)
    dsn_move_targets(targets, np.array([RIGHT, LEFT], dtype=np.int64))
    assert targets.tolist() == [1, 2]
    # target 0 is blocked by target 1 before target 1 moves away
    targets = np.array([0, 1], dtype=np.int64)
    dsn_move_targets(targets, np.array([RIGHT, RIGHT], dtype=np.int64))
    assert targets.tolist() == [0, 2]
    # target 1 follows into the cell target 0 just left
    targets = np.array([1, 0], dtype=np.int64)
    dsn_move_targets(targets, np.array([RIGHT, RIGHT], dtype=np.int64))
    assert targets.tolist() == [2, 1]


def test_captured_target_neither_moves_nor_blocks() -> None:
    targets = np.array([-1, 3], dtype=np.int64)
    dsn_move_targets(targets, np.array([RIGHT, RIGHT], dtype=np.int64))
    assert targets.tolist() == [-1, 4]


def test_step_draws_one_move_per_live_target_after_the_captures() -> None:
    for seed in range(40):
        # target 0 (energy 1, cell 4) is captured; target 1 may walk into cell 4
        targets, energy = arrays((4, 3), (1, 3))
        rng = np.random.default_rng(seed)
        individual = np.zeros(12)
        reward = dsn_step(targets, energy, joint_focusing({5: 4, 6: 4, 10: 4}), rng, individual)
        assert reward == 27.0
        u = np.random.default_rng(seed).random(2)
        expected = {STAY: 3, UP: 0, DOWN: 3, LEFT: 3, RIGHT: 4}[int(5 * u[0])]
        assert targets.tolist() == [-1, expected]
        assert rng.random() == u[1]  # no draw for the captured target

        targets, energy = arrays((0, 5))  # both alive: two draws, target 0 first
        rng = np.random.default_rng(seed)
        dsn_step(targets, energy, np.zeros(12, dtype=np.int64), rng, individual)
        u = np.random.default_rng(seed).random(3)
        m0, m1 = int(5 * u[0]), int(5 * u[1])
        assert targets.tolist() == [[0, 0, 3, 0, 1][m0], [5, 2, 5, 4, 5][m1]]
        assert rng.random() == u[2]


def test_long_random_play_keeps_targets_apart() -> None:
    rng = np.random.default_rng(7)
    actions = np.random.default_rng(8)
    targets, energy = arrays((-1, -1), (0, 0))
    individual = np.zeros(12)
    dsn_reset(targets, energy, rng)
    captures = steps = 0
    for _ in range(20_000):
        alive_before = int((targets >= 0).sum())
        joint = random_joint(actions)
        reward = dsn_step(targets, energy, joint, rng, individual)
        steps += 1
        alive = targets[targets >= 0]
        assert len(set(alive.tolist())) == alive.size and ((alive >= 0) & (alive < 6)).all()
        assert ((energy >= 0) & (energy <= 3)).all()
        assert ((targets < 0) == (energy == 0)).all()
        captured = alive_before - alive.size
        captures += captured
        assert reward == pytest.approx(individual.sum())
        assert reward == -int((joint > 0).sum()) + 30 * captured
        if done(targets) or steps == dsn.MAX_STEPS:
            dsn_reset(targets, energy, rng)
            steps = 0
    assert captures > 50  # random play does capture now and then


# ------------------------------------------------------------------------- optimum


def test_scripted_joint_actions_put_exactly_three_sensors_on_each_live_target() -> None:
    for state in range(dsn.N_STATES):
        joint = optimal_joint_action(state)
        assert ((joint >= 0) & (joint < dsn.ACTION_COUNTS)).all()
        focus = Counter(TOUCHED[s][a - 1] for s, a in enumerate(joint) if a > 0)
        live = [cell for cell in decode_state(state) if cell >= 0]
        assert focus == dict.fromkeys(live, 3)
    with pytest.raises(ConfigError):
        optimal_joint_action(dsn.TERMINAL_STATE)


def test_scripted_optimum_returns_42_in_3_steps_with_the_kernels() -> None:
    individual = np.zeros(12)
    for (t0, t1), seed in product(product(range(6), repeat=2), range(4)):
        if t0 == t1:
            continue
        targets, energy = arrays((t0, t1))
        rng = np.random.default_rng(seed)
        total, steps = 0.0, 0
        while not done(targets):
            joint = optimal_joint_action(dsn_state(targets))
            total += dsn_step(targets, energy, joint, rng, individual)
            steps += 1
        assert (total, steps) == (dsn.OPTIMAL_RETURN, dsn.OPTIMAL_STEPS) == (42.0, 3)


def test_scripted_optimum_returns_42_in_3_steps_in_the_env() -> None:
    env = SensorNetworkEnv()
    seeds: dict[tuple[int, int], list[int]] = {}
    seed = 0
    while len(seeds) < 30 or min(len(v) for v in seeds.values()) < 3:
        env.reset(seed=seed)
        seeds.setdefault(decode_state(env.state()), []).append(seed)
        seed += 1
    for start, found in seeds.items():
        for seed in found[:3]:
            observations, _ = env.reset(seed=seed)
            assert decode_state(observations["sensor_0"]) == start
            total, steps = 0.0, 0
            while env.agents:
                joint = optimal_joint_action(env.state())
                actions = {agent: int(a) for agent, a in zip(env.agents, joint, strict=True)}
                observations, rewards, terminations, truncations, _ = env.step(actions)
                total += rewards["sensor_0"]
                steps += 1
            assert (total, steps) == (42.0, 3)
            assert all(terminations.values()) and not any(truncations.values())
            assert set(observations.values()) == {dsn.TERMINAL_STATE}


# --------------------------------------------------------------------- ParallelEnv


def test_parallel_api() -> None:
    env = SensorNetworkEnv()
    parallel_api_test(env, num_cycles=200)
    assert env.metadata["name"] == "sensor_network_v0"
    assert env.possible_agents == [f"sensor_{s}" for s in range(12)]
    for agent, count in zip(env.possible_agents, dsn.ACTION_COUNTS, strict=True):
        assert env.action_space(agent).n == count
        assert env.observation_space(agent).n == 43
    assert env.state_space.n == 43


def test_parallel_seed() -> None:
    parallel_seed_test(SensorNetworkEnv, num_cycles=50)


def play(env_seed: int, action_seed: int, episodes: int = 4) -> list:
    """Every observation, reward, termination, truncation and info of a few episodes."""
    env = SensorNetworkEnv()
    actions_rng = np.random.default_rng(action_seed)
    trace: list = []
    for episode in range(episodes):
        observations, _ = env.reset(seed=env_seed if episode == 0 else None)
        trace.append(observations)
        while env.agents:
            joint = random_joint(actions_rng)
            result = env.step(dict(zip(env.agents, joint.tolist(), strict=True)))
            individual = {a: info["individual_reward"] for a, info in result[4].items()}
            trace.append((*result[:4], individual))
    return trace


def test_same_seed_same_episodes_different_seed_different() -> None:
    first = play(3, 11)
    assert len(first) > 4 * 5
    assert first == play(3, 11)
    assert first != play(4, 11)


def test_env_runs_the_same_transition_as_the_kernels() -> None:
    env = SensorNetworkEnv()
    rng = np.random.default_rng(5)
    actions_rng = np.random.default_rng(6)
    targets, energy = arrays((-1, -1), (0, 0))
    individual = np.zeros(12)
    for episode in range(3):
        observations, infos = env.reset(seed=5 if episode == 0 else None)
        dsn_reset(targets, energy, rng)
        assert observations == dict.fromkeys(env.possible_agents, dsn_state(targets))
        assert [len(info["action_mask"]) for info in infos.values()] == dsn.ACTION_COUNTS.tolist()
        steps = 0
        while env.agents:
            joint = random_joint(actions_rng)
            actions = {f"sensor_{s}": np.int64(a) for s, a in enumerate(joint)}
            _, rewards, terminations, truncations, infos = env.step(actions)
            reward = dsn_step(targets, energy, joint, rng, individual)
            steps += 1
            assert env.state() == dsn_state(targets)
            assert set(rewards.values()) == {reward}
            assert [info["individual_reward"] for info in infos.values()] == individual.tolist()
            assert all(info["action_mask"].all() for info in infos.values())
            assert set(terminations.values()) == {bool(done(targets))}
            assert set(truncations.values()) == {not done(targets) and steps == 40}
        assert done(targets) or steps == dsn.MAX_STEPS


def test_idle_sensors_are_truncated_after_40_steps() -> None:
    env = SensorNetworkEnv()
    env.reset(seed=0)
    idle = dict.fromkeys(env.possible_agents, 0)
    for step in range(1, 41):
        assert env.agents == env.possible_agents
        _, rewards, terminations, truncations, _ = env.step(idle)
        assert set(rewards.values()) == {0.0}
        assert set(terminations.values()) == {False}
        assert set(truncations.values()) == {step == 40}
    assert env.agents == []
    with pytest.raises(RuntimeError, match="reset"):
        env.step(idle)


def test_render_shows_targets_and_focus(capsys: pytest.CaptureFixture[str]) -> None:
    env = SensorNetworkEnv(render_mode="ansi")
    env.reset(seed=1)
    text = env.render()
    assert isinstance(text, str) and "T0 e=3" in text and "T1 e=3" in text
    joint = optimal_joint_action(env.state())
    env.step(dict(zip(env.agents, joint.tolist(), strict=True)))
    text = env.render()
    assert "e=2" in text
    assert all(f"s{s}" in text for s in np.flatnonzero(joint))
    targets, energy = arrays((-1, 4), (0, 2))
    text = render_text(targets, energy, joint_focusing({5: 4, 6: 4}))
    assert "T1 e=2" in text and "s5,s6" in text and "captured: T0" in text
    human = SensorNetworkEnv(render_mode="human")
    human.reset(seed=1)
    assert human.render() is None
    assert "T0 e=3" in capsys.readouterr().out


BAD_ACTIONS = [
    ({"sensor_0": 2}, "sensor_0: action must be in 0..1"),
    ({"sensor_5": 5}, "sensor_5: action must be in 0..4"),
    ({"sensor_3": -1}, "in 0..1"),
    ({"sensor_1": 1.0}, "must be an integer"),
    ({"sensor_1": "1"}, "must be an integer"),
    ({"sensor_99": 0}, "unknown"),
]


@pytest.mark.parametrize(("change", "message"), BAD_ACTIONS)
def test_bad_actions_raise_value_error(change: dict, message: str) -> None:
    env = SensorNetworkEnv()
    env.reset(seed=0)
    actions = {**dict.fromkeys(env.agents, 0), **change}
    with pytest.raises(ValueError, match=re.escape(message)):
        env.step(actions)
    with pytest.raises(ValueError, match="no action for 'sensor_11'"):
        env.step({agent: 0 for agent in env.agents[:-1]})
    env.step(dict.fromkeys(env.agents, 0))  # the env is still usable


def test_validate_joint() -> None:
    assert dsn.validate_joint([1] * 12).tolist() == [1] * 12
    with pytest.raises(ConfigError, match=re.escape("sensor 3 action must be in 0..1")):
        dsn.validate_joint([0, 0, 0, 2] + [0] * 8)
    with pytest.raises(ConfigError, match="12 integer actions"):
        dsn.validate_joint([0] * 11)
    with pytest.raises(ConfigError, match="12 integer actions"):
        dsn.validate_joint([0.5] * 12)


def test_bad_configuration_raises() -> None:
    with pytest.raises(ConfigError, match="render_mode"):
        SensorNetworkEnv(render_mode="rgb_array")
    with pytest.raises(ValueError, match="unknown agent"):
        SensorNetworkEnv().action_space("sensor_12")
    with pytest.raises(RuntimeError):
        SensorNetworkEnv().step({})
