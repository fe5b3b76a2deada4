"""Episode loops: the generic ParallelEnv path equals the compiled DSN path."""

from __future__ import annotations

import numpy as np
import pytest

from cmarlcd.games import sensor_network as dsn
from cmarlcd.learners.stochastic import LAOCA, AutomatonConfig, CMARLCDStochastic, StochasticConfig
from cmarlcd.rollouts import (
    dsn_evaluate,
    dsn_tables,
    greedy_policy,
    play_episodes,
    replay_sample,
    train_dsn,
)


@pytest.mark.parametrize(
    ("learner_type", "config"),
    [(CMARLCDStochastic, StochasticConfig()), (LAOCA, AutomatonConfig())],
)
def test_python_path_learns_the_same_table_as_the_compiled_loop(learner_type, config) -> None:
    episodes = 300
    env = dsn.SensorNetworkEnv()
    learner = learner_type(dsn.ACTION_COUNTS, config, n_states=dsn.N_STATE_INDICES, seed=22)
    stats = play_episodes(env, learner, episodes, seed=11)
    tables = dsn_tables(config.rule_params())
    train_dsn(tables, episodes, np.random.default_rng(11), np.random.default_rng(22))
    seen = np.isfinite(learner.tables.r_max)
    assert seen.sum() > 20  # the run visited most states
    assert np.array_equal(seen, np.isfinite(tables.r_max))
    assert np.array_equal(learner.tables.r_max[seen], tables.r_max[seen])
    assert np.allclose(learner.tables.values[seen], tables.values[seen], atol=0, rtol=0)
    assert stats.lengths.min() >= 1 and stats.lengths.max() <= dsn.MAX_STEPS


def test_scripted_optimal_policy_evaluates_to_42_in_3_steps() -> None:
    policy = np.zeros((dsn.N_STATE_INDICES, dsn.N_SENSORS), dtype=np.int64)
    for state in range(dsn.N_STATES):
        policy[state] = dsn.optimal_joint_action(state)
    successes, total_return, total_steps = dsn_evaluate(policy, 2000, np.random.default_rng(0))
    assert (successes, total_return, total_steps) == (2000, 42.0 * 2000, 3 * 2000)


def test_idle_policy_never_succeeds_and_runs_to_the_step_limit() -> None:
    policy = np.zeros((dsn.N_STATE_INDICES, dsn.N_SENSORS), dtype=np.int64)
    successes, total_return, total_steps = dsn_evaluate(policy, 100, np.random.default_rng(0))
    assert (successes, total_return, total_steps) == (0, 0.0, 100 * dsn.MAX_STEPS)


def test_compiled_evaluation_agrees_with_the_env_greedy_loop() -> None:
    """Same greedy policy, same env seed: identical episodes through both paths."""
    learner = CMARLCDStochastic(dsn.ACTION_COUNTS, n_states=dsn.N_STATE_INDICES, seed=2)
    play_episodes(dsn.SensorNetworkEnv(), learner, 1000, seed=1)
    policy = greedy_policy(learner.tables)
    successes, total_return, total_steps = dsn_evaluate(policy, 300, np.random.default_rng(5))
    stats = play_episodes(dsn.SensorNetworkEnv(), learner, 300, learn=False, seed=5)
    assert stats.returns.sum() == total_return and stats.lengths.sum() == total_steps
    wins = (stats.returns == dsn.OPTIMAL_RETURN) & (stats.lengths == dsn.OPTIMAL_STEPS)
    assert wins.sum() == successes


def test_cmarlcd_learns_the_dsn_optimum_in_every_state() -> None:
    """Long enough training gives an optimal joint action in all 42 states."""
    tables = dsn_tables(StochasticConfig().rule_params())
    train_dsn(tables, 150_000, np.random.default_rng(3), np.random.default_rng(4))
    successes, _, _ = dsn_evaluate(greedy_policy(tables), 5000, np.random.default_rng(0))
    assert successes / 5000 > 0.9


def test_replay_sample_draws_numpy_s_stream_from_the_stored_rows_of_each_seed() -> None:
    capacity, size = 7, np.array([5, 7])
    state = np.arange(2 * capacity, dtype=np.int8).reshape(2, capacity)  # rows are distinct
    buffer = (
        state,
        np.stack([state, -state], axis=-1),
        (state * 0.5).astype(np.float32),
        (state + 1).astype(np.int8),
        state % 2 == 0,
        np.zeros(2, np.int64),
        size,
    )
    out = (
        np.empty((2, 20), np.int64),
        np.empty((2, 20, 2), np.int64),
        np.empty((2, 20), np.float32),
        np.empty((2, 20), np.int64),
        np.empty((2, 20), np.bool_),
    )
    replay_sample(buffer, (np.random.default_rng(3), np.random.default_rng(4)), 20, out)
    for k, seed in enumerate((3, 4)):
        picks = np.random.default_rng(seed).integers(0, size[k], 20)  # NumPy, independently
        for stored, drawn in zip(buffer[:5], out, strict=True):
            assert np.array_equal(drawn[k], stored[k][picks])
