"""The object API every tabular learner shares, and acting from tables."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cmarlcd.learners import policy
from cmarlcd.learners.tabular.automata import LAOCA
from cmarlcd.learners.tabular.coordination import CMARLCDStochastic


def test_illegal_actions_are_never_chosen() -> None:
    learner = CMARLCDStochastic([3, 2], seed=3)
    masks = [np.array([0, 1, 0]), np.array([1, 1])]
    picks = {learner.act("s", masks)[0] for _ in range(200)}
    assert picks == {1}
    assert learner.tables.probs[0, 0].tolist() == pytest.approx([0.0, 1.0, 0.0])
    assert learner.greedy("s", masks)[0] == 1


def test_sample_action_never_returns_a_zero_probability_action() -> None:
    p = np.array([0.5, 0.5, 0.0])
    assert policy.sample_action(p, 3, np.nextafter(1.0, 0.0)) == 1
    assert policy.sample_action(np.array([0.0, 1.0, 0.0]), 3, 0.0) == 1


def test_hashable_states_grow_the_tables() -> None:
    learner = LAOCA([2, 2], seed=0)
    for k in range(40):
        learner.act(("state", k))
    assert learner.n_states >= 40
    assert learner.max_return(("state", 3)) == -math.inf


def _distributed_q(counts, n_states, seed):
    from cmarlcd.learners.tabular.distributed_q import DistributedQStochasticConfig
    from cmarlcd.learners.tabular.protocol import TabularLearner

    return TabularLearner(counts, DistributedQStochasticConfig(), n_states=n_states, seed=seed)


@pytest.mark.parametrize("make", [CMARLCDStochastic, LAOCA, _distributed_q])
def test_interleaved_copies_learn_each_episode_as_played_alone(make) -> None:
    """Steps of two copies' episodes interleaved, copy 1's ending first: the tables are
    those of a learner told copy 1's episode, then copy 0's, one after the other (for
    learners of whole episodes, and for distributed Q, which learns at every step)."""
    episodes = {0: [(0, (1, 0), 1.0), (2, (0, 1), 3.0)], 1: [(1, (1, 1), 2.0)]}
    together = make([2, 2], n_states=4, seed=0)
    for copy, step in ((0, 0), (1, 0), (0, 1)):  # act completes the copy's last step
        state, joint, reward = episodes[copy][step]
        together.act(state, copy=copy)
        together.observe(state, joint, reward, copy=copy)
    together.end_episode(final_state=3, terminated=False, copy=1)
    together.end_episode(final_state=3, terminated=True, copy=0)
    alone = make([2, 2], n_states=4, seed=0)
    for copy, terminated in ((1, False), (0, True)):
        for state, joint, reward in episodes[copy]:
            alone.act(state)
            alone.observe(state, joint, reward)
        alone.end_episode(final_state=3, terminated=terminated)
    for mine, theirs in zip(together.tables, alone.tables, strict=True):
        assert np.array_equal(mine, theirs, equal_nan=True)
