"""The object API every tabular learner shares, and acting from tables."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cmarlcd.learners import policy
from cmarlcd.learners.automata import LAOCA
from cmarlcd.learners.coordination import CMARLCDStochastic


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
