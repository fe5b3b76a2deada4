"""The time left as an input (``games/time_left.py``): each agent's observation followed
by ``(T - t) / T``, the game's own transition, states and arrays untouched."""

from __future__ import annotations

import numpy as np
import pytest

from cmarlcd.errors import ConfigError
from cmarlcd.games.foraging import Foraging
from cmarlcd.games.observations import own_observations
from cmarlcd.games.spread import SimpleSpread
from cmarlcd.games.time_left import with_time_left


def play(spec, steps: int, seed: int = 0):
    """``steps`` uniformly random legal joint actions from a reset; the features and
    state index after each, and the rewards."""
    env, rng = spec.new_env(), np.random.default_rng(seed)
    spec.kernels.reset(env, rng)
    draw = np.random.default_rng(seed + 1)
    masks = np.zeros((spec.n_agents, spec.width), np.bool_)
    rewards = np.zeros(spec.n_teams)
    seen = []
    for _ in range(steps):
        x = np.zeros(spec.n_features, np.float32)
        spec.kernels.features(env, 0, x)
        spec.kernels.legal(env, masks)
        seen.append((x, spec.kernels.state(env, 0), spec.kernels.done(env), rewards.copy()))
        joint = np.array([draw.choice(np.flatnonzero(m)) for m in masks], np.int64)
        spec.kernels.step(env, joint, rng, rewards)
    return seen, env


@pytest.mark.parametrize("rules", [Foraging(8, 2, 2), SimpleSpread(N=3)], ids=["lbf", "spread"])
def test_each_agents_observation_is_followed_by_the_time_left(rules) -> None:
    base, width = rules.spec(), rules.observation_size
    timed = with_time_left(base, width)
    n = base.n_agents
    assert timed.n_features == n * (width + 1)
    plain, _ = play(base, 12)
    clocked, env = play(timed, 12)
    for t, ((x, s, done, r), (y, s2, done2, r2)) in enumerate(zip(plain, clocked, strict=True)):
        left = (base.max_steps - t) / base.max_steps  # e.g. 50 steps: 1, 0.98, 0.96, ...
        rows = y.reshape(n, width + 1)
        assert np.array_equal(rows[:, :width], x.reshape(n, width)), t  # the same game
        assert np.allclose(rows[:, width], left, atol=1e-7), t
        assert (s, done) == (s2, done2) and np.array_equal(r, r2)
    # the game's own arrays lead the tuple, as its kernels and its renderer read them
    assert len(env) == len(base.new_env()) + 1
    assert env[-1].tolist() == [12, base.max_steps, width, n]


def test_a_reset_sets_the_clock_back() -> None:
    rules = Foraging(5, 2, 1)
    timed = with_time_left(rules.spec(), rules.observation_size)
    _, env = play(timed, 7)
    timed.kernels.reset(env, np.random.default_rng(5))
    x = np.zeros(timed.n_features, np.float32)
    timed.kernels.features(env, 0, x)
    assert env[-1][0] == 0
    assert x[rules.observation_size] == 1.0 and x[-1] == 1.0


def test_own_observations_at_the_wider_width_read_the_time_too() -> None:
    rules = SimpleSpread(N=3)
    width = rules.observation_size + 1
    spec = own_observations(with_time_left(rules.spec(), rules.observation_size), width)
    assert spec.own_dim == width and spec.n_features == 2 * 3 * width
    seen, _ = play(spec, 3)
    x = seen[2][0]
    for i in range(3):  # every agent's own slice ends in the time left after 2 steps
        assert x[3 * width + i * width + width - 1] == pytest.approx(23 / 25)


def test_features_that_are_not_observations_are_refused() -> None:
    rules = Foraging(5, 2, 1)
    with pytest.raises(ConfigError, match="time_left"):
        with_time_left(rules.spec(), rules.observation_size + 1)
