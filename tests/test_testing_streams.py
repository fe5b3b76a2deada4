"""The stream-equivalence instrument (:mod:`cmarlcd.testing.streams`): two learners fed one
stream of visits, compared state by state."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from cmarlcd.errors import ConfigError
from cmarlcd.games.sensor_network import SensorNetworkEnv
from cmarlcd.learners import CMARLCDStochastic, StochasticConfig
from cmarlcd.testing.streams import stream_equivalence

HAS_TORCH = importlib.util.find_spec("torch") is not None


def counts(env) -> list[int]:
    return [int(env.action_space(agent).n) for agent in env.possible_agents]


def test_a_table_fed_the_stream_of_another_learns_exactly_its_degrees() -> None:
    """Algorithm 2's updates depend on the visits alone, not on who chose them: a second
    table that only observes ends with the reference's degrees to the bit."""
    env = SensorNetworkEnv()
    reference = CMARLCDStochastic(counts(env), seed=1)
    candidate = CMARLCDStochastic(counts(env), seed=2)  # never acts: its seed is unused
    points = stream_equivalence(env, reference, candidate, checkpoints=(200, 1, 50))
    assert [p.episodes for p in points] == [1, 50, 200]
    assert all(p.agreement == p.agent_agreement == 1.0 for p in points)
    assert all(p.max_difference == 0.0 for p in points)
    assert 0 < points[0].states <= points[1].states <= points[2].states <= 43


def test_a_candidate_with_another_tie_step_is_told_apart() -> None:
    """A tie moves the taken action's degree by δ: a table with δ = 0.1 beside one with
    0.05 differs by at least 0.05 once any state has had a tie (within 300 episodes of
    the DSN, many have)."""
    env = SensorNetworkEnv()
    reference = CMARLCDStochastic(counts(env), seed=1)
    candidate = CMARLCDStochastic(counts(env), StochasticConfig(delta=0.1), seed=1)
    (point,) = stream_equivalence(env, reference, candidate, checkpoints=(300,))
    assert point.max_difference >= 0.05 - 1e-12


@pytest.mark.parametrize("checkpoints", [(), (0,), (10, -1)])
def test_bad_checkpoints_are_refused(checkpoints) -> None:
    env = SensorNetworkEnv()
    learner = CMARLCDStochastic(counts(env), seed=0)
    with pytest.raises(ConfigError, match="checkpoints"):
        stream_equivalence(env, learner, learner, checkpoints)


@pytest.mark.skipif(not HAS_TORCH, reason="needs the [deep] extra (torch)")
def test_deep_cmarl_cd_is_compared_on_every_visited_state() -> None:
    from cmarlcd.learners import DeepCMARLCDConfig
    from cmarlcd.learners.deep.degree_agent import DegreeAgent

    env = SensorNetworkEnv()
    reference = CMARLCDStochastic(counts(env), seed=0)
    config = DeepCMARLCDConfig(batch_size=40, buffer_size=400)
    candidate = DegreeAgent(counts(env), config, 60, n_states=43, seed=0)
    first, last = stream_equivalence(env, reference, candidate, checkpoints=(20, 60))
    assert 0 < first.states <= last.states
    for point in (first, last):
        assert 0.0 <= point.agreement <= point.agent_agreement <= 1.0
        assert 0.0 <= point.max_difference <= config.c_max - config.c_min


@pytest.mark.skipif(not HAS_TORCH, reason="needs the [deep] extra (torch)")
def test_deep_cmarl_cd_s_keyed_memory_holds_the_table_and_its_network_follows() -> None:
    """On the table's own stream, deep CMARL-CD's keyed memory under the table's rule for
    first visits holds the table: on every visited state the same record and the same
    degrees (to float32's precision); and the
    network fitted to it agrees with the table's greedy joint action on most states
    after 1,000 episodes, given a gradient step per 50 environment steps (69 % on this
    stream; the replayed update: 0 %; at the default step per 200 the network has taken
    about 20 steps by then and agrees on none yet)."""
    from cmarlcd.learners import DeepCMARLCDConfig
    from cmarlcd.learners.deep.degree_agent import DegreeAgent
    from cmarlcd.learners.deep.degree_memory import find
    from cmarlcd.testing.streams import Stream

    env = SensorNetworkEnv()
    reference = CMARLCDStochastic(counts(env), seed=1)
    # the table's rule throughout, and enough gradient steps for 1,000 episodes
    config = DeepCMARLCDConfig(unseen_record="first-visit", train_every=50, target_every=500)
    candidate = DegreeAgent(counts(env), config, 1_000, n_states=43, seed=1)
    stream = Stream(env, reference, candidate, 1)
    stream.play(1_000)
    memory = candidate._memory
    for state in range(43):
        slot = find(memory, np.uint64(state))
        if reference.max_return(state) == -np.inf:
            assert slot < 0, f"state {state} was never reached, yet kept"
            continue
        assert memory.record[slot] == pytest.approx(reference.max_return(state), abs=1e-9)
        assert memory.target[slot] == pytest.approx(reference.degrees(state), abs=1e-5)
    assert stream.compare().agreement >= 0.6
