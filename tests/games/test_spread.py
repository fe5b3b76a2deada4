"""simple_spread (``games/spread``): the physics and rewards on hand-computed cases, the
observation layout, the ParallelEnv, task names, and a short form of the check against
mpe2 (``benchmarks/check_spread.py`` runs it at full length)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test, parallel_seed_test

from cmarlcd.errors import ConfigError
from cmarlcd.games.spread import SimpleSpread, SimpleSpreadEnv
from cmarlcd.games.spread import kernels as k

NONE, LEFT, RIGHT, DOWN, UP = range(5)


def place(rules: SimpleSpread, agents, landmarks) -> tuple:
    """A game in a hand-made state: agents (x, y) at rest, landmarks (x, y)."""
    env = rules.new_env()
    for i, (x, y) in enumerate(agents):
        env[0][i] = (x, y, 0.0, 0.0)
    for m, place_ in enumerate(landmarks):
        env[1][m] = place_
    return env


def step(env, *actions) -> float:
    team = np.zeros(1)
    k.spread_step(env, np.array(actions, dtype=np.int64), np.random.default_rng(0), team)
    return float(team[0])


def test_a_push_accelerates_then_damping_slows() -> None:
    """A push of 5 for dt 0.1 gives velocity 0.5; the position moves a step later, and
    damping keeps 0.75 of the velocity each step."""
    env = place(SimpleSpread(N=1), [(0.0, 0.0)], [(0.5, 0.5)])
    step(env, RIGHT)
    assert env[0][0].tolist() == [0.0, 0.0, 0.5, 0.0]
    step(env, NONE)
    assert env[0][0].tolist() == pytest.approx([0.05, 0.0, 0.375, 0.0])
    step(env, DOWN)
    assert env[0][0].tolist() == pytest.approx([0.0875, 0.0, 0.28125, -0.5])


def test_overlapping_agents_push_each_other_apart() -> None:
    """At distance 0.2 (radii 0.15 each), the penetration is k · log(1 + e^((0.3 -
    0.2) / k)) ≈ 0.1, so the force is 100 · 0.1 = 10 along the line between them: each
    gains velocity 10 · dt = 1 away from the other."""
    env = place(SimpleSpread(N=2), [(0.0, 0.0), (0.2, 0.0)], [(1, 1), (-1, -1)])
    step(env, NONE, NONE)
    penetration = 0.001 * math.log1p(math.exp(0.1 / 0.001))
    assert env[0][0, k.VX] == pytest.approx(-100 * penetration * 0.1)
    assert env[0][1, k.VX] == pytest.approx(100 * penetration * 0.1)
    assert env[0][0, k.VX] == pytest.approx(-1.0, abs=1e-12)
    assert env[0][:, k.VY].tolist() == [0.0, 0.0]


def test_rewards_weigh_the_global_and_the_own_by_local_ratio() -> None:
    """Landmarks at (0, 0) and (1, 0), agents at (0, 0) and (0.2, 0), overlapping: the
    global reward is -(0 + 0.8), each agent's own -1; with local_ratio 0.5 each gets
    -0.9 (positions move only from the next step)."""
    env = place(SimpleSpread(N=2), [(0.0, 0.0), (0.2, 0.0)], [(0.0, 0.0), (1.0, 0.0)])
    assert step(env, NONE, NONE) == pytest.approx(-1.8)
    assert env[4].tolist() == pytest.approx([-0.9, -0.9])
    env = place(
        SimpleSpread(N=2, local_ratio=0), [(0.0, 0.0), (0.2, 0.0)], [(0.0, 0.0), (1.0, 0.0)]
    )
    step(env, NONE, NONE)
    assert env[4].tolist() == pytest.approx([-0.8, -0.8])


def test_the_team_reward_is_the_mean_where_the_rules_say_so() -> None:
    rules = SimpleSpread(N=2, reward="mean")
    env = place(rules, [(0.0, 0.0), (0.2, 0.0)], [(0.0, 0.0), (1.0, 0.0)])
    assert step(env, NONE, NONE) == pytest.approx(-0.9)
    assert rules.name.endswith(",reward=mean") and SimpleSpread.from_name(rules.name) == rules


def test_observation_layout() -> None:
    rules = SimpleSpread(N=2)
    env = place(rules, [(0.5, -0.5), (0.0, 0.25)], [(1.0, 1.0), (-1.0, 0.0)])
    out = np.zeros(rules.spec().n_features, dtype=np.float32)
    k.spread_features(env, 0, out)
    width = rules.observation_size
    assert width == 4 + 4 + 4
    assert out[:width].tolist() == [0, 0, 0.5, -0.5, 0.5, 1.5, -1.5, 0.5, -0.5, 0.75, 0, 0]
    assert out[width:].tolist() == [0, 0, 0, 0.25, 1.0, 0.75, -1.0, -0.25, 0.5, -0.75, 0, 0]


def test_resets_draw_positions_in_the_square_at_rest() -> None:
    rules = SimpleSpread(N=4)
    env, rng = rules.new_env(), np.random.default_rng(0)
    seen = []
    for _ in range(2000):
        k.spread_reset(env, rng)
        assert np.abs(env[0][:, :2]).max() <= 1 and np.abs(env[1]).max() <= 1
        assert not env[0][:, 2:].any()
        seen.append(env[0][0, 0])
    assert -1 < np.mean(seen) < 1 and np.std(seen) == pytest.approx(2 / math.sqrt(12), rel=0.1)


@pytest.mark.parametrize(
    ("text", "expected"),
    [("", SimpleSpread()), ("N=5,local_ratio=0", SimpleSpread(5, 0.0)),
     ("max_cycles=50", SimpleSpread(max_cycles=50))],
)  # fmt: skip
def test_task_names(text, expected) -> None:
    assert SimpleSpread.from_name(text) == expected
    assert SimpleSpread.from_name(expected.name) == expected


@pytest.mark.parametrize(
    "text",
    ["N=0", "N=2.5", "local_ratio=2", "speed=1", "N", "local_ratio=x", "N=17", "reward=max"],
)
def test_bad_names_are_refused(text) -> None:
    with pytest.raises(ConfigError):
        SimpleSpread.from_name(text)


def test_parallel_api() -> None:
    parallel_api_test(SimpleSpreadEnv(), num_cycles=100)
    parallel_api_test(SimpleSpreadEnv("N=5,local_ratio=1"), num_cycles=60)


def test_parallel_seed() -> None:
    parallel_seed_test(lambda: SimpleSpreadEnv("N=2"), num_cycles=30)


def test_env_truncates_after_max_cycles_and_gives_each_agent_its_reward() -> None:
    env = SimpleSpreadEnv("max_cycles=3")
    env.reset(seed=1)
    for _ in range(3):
        _, rewards, terminations, truncations, _ = env.step(dict.fromkeys(env.agents, NONE))
    assert all(truncations.values()) and not any(terminations.values()) and not env.agents
    assert list(rewards.values()) == pytest.approx(env.env[4].tolist())


def test_equal_to_mpe2_step_for_step() -> None:
    pytest.importorskip("mpe2")
    from cmarlcd.testing.spread import compare_steps

    for text in ("", "N=5,local_ratio=0", "local_ratio=1"):
        report = compare_steps(SimpleSpread.from_name(text), 600, seed=2)
        assert report.equal, report.mismatches
        assert report.largest_difference <= 1e-5


def test_resets_distributed_as_mpe2_s() -> None:
    pytest.importorskip("mpe2")
    from cmarlcd.testing.spread import compare_resets

    report = compare_resets(SimpleSpread(N=3), 3000, seed=3)
    assert report.equal, report.p_values
