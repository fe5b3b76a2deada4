"""The LA-OCA stand-in: reward-inaction automata on the max-return indicator."""

from __future__ import annotations

import numpy as np
import pytest

from cmarlcd import ConfigError
from cmarlcd.learners.tabular.automata import LAOCA, AutomatonConfig


def episode(learner, steps) -> None:
    for state, joint, reward in steps:
        learner.observe(state, joint, reward)
    learner.end_episode()


def test_la_oca_reward_inaction_update() -> None:
    learner = LAOCA([2, 3], AutomatonConfig(rate=0.1), seed=0)
    masks = [np.array([1, 1]), np.array([0, 1, 1])]
    learner.act("s", masks)  # first visit: uniform over the legal actions
    assert learner.tables.probs[0, 1].tolist() == [0.0, 0.5, 0.5]
    episode(learner, [("s", (1, 2), 1.0)])  # record: p(a) += 0.1 (1 - p(a)), others × 0.9
    assert learner.tables.probs[0, 0, :2].tolist() == pytest.approx([0.45, 0.55])
    assert learner.tables.probs[0, 1].tolist() == pytest.approx([0.0, 0.45, 0.55])
    episode(learner, [("s", (0, 1), 0.5)])  # below R_max: inaction
    assert learner.tables.probs[0, 0, :2].tolist() == pytest.approx([0.45, 0.55])
    episode(learner, [("s", (0, 1), 1.0)])  # tie: rewarded too
    assert learner.tables.probs[0, 0, :2].tolist() == pytest.approx([0.505, 0.495])
    assert learner.tables.probs[0, 1].tolist() == pytest.approx([0.0, 0.505, 0.495])


def test_bad_automaton_config_and_masks() -> None:
    with pytest.raises(ConfigError, match="rate"):
        AutomatonConfig(rate=1.0)
    learner = LAOCA([2, 2], seed=0)
    with pytest.raises(ConfigError, match="masks"):
        learner.act("s", [np.array([0, 0]), np.array([1, 1])])
    with pytest.raises(ConfigError, match="joint_action"):
        learner.observe("s", (0,), 1.0)
