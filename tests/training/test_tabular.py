"""Compiled tabular loops: they learn what the generic ParallelEnv loop learns."""

from __future__ import annotations

import numpy as np
import pytest

from cmarlcd.experiments.sensor_network import optimal_episodes
from cmarlcd.games import sensor_network as dsn
from cmarlcd.learners.tabular.automata import LAOCA, AutomatonConfig
from cmarlcd.learners.tabular.coordination import CMARLCDStochastic, StochasticConfig
from cmarlcd.learners.tabular.protocol import greedy_policy
from cmarlcd.training import TabularRun, evaluate, play_episodes


def values(tables) -> np.ndarray:
    """What the greedy action is taken over: degrees (CMARL-CD) or probabilities."""
    return tables.degrees if hasattr(tables, "degrees") else tables.probs


@pytest.mark.parametrize(
    ("learner_type", "config"),
    [(CMARLCDStochastic, StochasticConfig()), (LAOCA, AutomatonConfig())],
)
def test_python_path_learns_the_same_table_as_the_compiled_loop(learner_type, config) -> None:
    episodes = 300
    env = dsn.SensorNetworkEnv()
    learner = learner_type(dsn.ACTION_COUNTS, config, n_states=dsn.N_STATE_INDICES, seed=22)
    stats = play_episodes(env, learner, episodes, seed=11)
    run = TabularRun(dsn.SPEC, config, np.random.default_rng(11), np.random.default_rng(22))
    steps = run.train(episodes)
    assert steps == stats.lengths.sum()
    seen = np.isfinite(learner.tables.r_max)
    assert seen.sum() > 20  # the run visited most states
    assert np.array_equal(seen, np.isfinite(run.tables.r_max))
    assert np.array_equal(learner.tables.r_max[seen], run.tables.r_max[seen])
    assert np.array_equal(values(learner.tables)[seen], values(run.tables)[seen])
    assert stats.lengths.min() >= 1 and stats.lengths.max() <= dsn.MAX_STEPS


def test_training_in_pieces_equals_training_at_once() -> None:
    whole = TabularRun(
        dsn.SPEC, StochasticConfig(), np.random.default_rng(1), np.random.default_rng(2)
    )
    whole.train(500)
    pieces = TabularRun(
        dsn.SPEC, StochasticConfig(), np.random.default_rng(1), np.random.default_rng(2)
    )
    for chunk in (1, 99, 150, 250):
        pieces.train(chunk)
    assert np.array_equal(whole.tables.degrees, pieces.tables.degrees)
    assert np.array_equal(whole.greedy_policy(), pieces.greedy_policy())


def scripted_policy() -> np.ndarray:
    policy = np.zeros((dsn.N_STATE_INDICES, dsn.N_SENSORS), dtype=np.int64)
    for state in range(dsn.N_STATES):
        policy[state] = dsn.optimal_joint_action(state)
    return policy


def test_scripted_optimal_policy_evaluates_to_42_in_3_steps() -> None:
    stats = evaluate(dsn.SPEC, scripted_policy(), 2000, np.random.default_rng(0))
    assert set(stats.returns.tolist()) == {42.0} and set(stats.lengths.tolist()) == {3}
    assert optimal_episodes(stats).all()


def test_idle_policy_never_succeeds_and_runs_to_the_step_limit() -> None:
    policy = np.zeros((dsn.N_STATE_INDICES, dsn.N_SENSORS), dtype=np.int64)
    stats = evaluate(dsn.SPEC, policy, 100, np.random.default_rng(0))
    assert (stats.returns == 0).all() and (stats.lengths == dsn.MAX_STEPS).all()
    assert not optimal_episodes(stats).any()


def test_compiled_evaluation_agrees_with_the_env_greedy_loop() -> None:
    """Same greedy policy, same env seed: identical episodes through both paths."""
    learner = CMARLCDStochastic(dsn.ACTION_COUNTS, n_states=dsn.N_STATE_INDICES, seed=2)
    play_episodes(dsn.SensorNetworkEnv(), learner, 1000, seed=1)
    policy = greedy_policy(learner.config, learner.tables, learner.counts)
    compiled = evaluate(dsn.SPEC, policy, 300, np.random.default_rng(5))
    generic = play_episodes(dsn.SensorNetworkEnv(), learner, 300, learn=False, seed=5)
    assert np.array_equal(compiled.returns, generic.returns)
    assert np.array_equal(compiled.lengths, generic.lengths)


def test_cmarlcd_learns_the_dsn_optimum_in_every_state() -> None:
    """Long enough training gives an optimal joint action in all 42 states."""
    run = TabularRun(
        dsn.SPEC, StochasticConfig(), np.random.default_rng(3), np.random.default_rng(4)
    )
    run.train(150_000)
    stats = evaluate(dsn.SPEC, run.greedy_policy(), 5000, np.random.default_rng(0))
    assert optimal_episodes(stats).mean() > 0.9
