"""CMARL-CD for stochastic games (Algorithm 2, eqs. 14-17) and the LA-OCA stand-in."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cmarlcd import ConfigError
from cmarlcd.learners import policy
from cmarlcd.learners.stochastic import (
    LAOCA,
    AutomatonConfig,
    CMARLCDStochastic,
    StochasticConfig,
)


def softmax(values: list[float], temperature: float = 1.0) -> list[float]:
    weights = [math.exp(v / temperature) for v in values]
    return [w / sum(weights) for w in weights]


def episode(learner, steps) -> None:
    for state, joint, reward in steps:
        learner.observe(state, joint, reward)
    learner.end_episode()


def test_new_record_resets_and_takes_the_large_step() -> None:
    """DSN settings: c_init 1.5, δ_reset 0.5, δ 0.05, clip [0.5, 3.0], γ 0.9."""
    learner = CMARLCDStochastic([2, 3], n_states=3, seed=0)
    # one episode s0 -(1, 2), r=1-> s1 -(0, 0), r=2-> end. Backwards:
    # s1: G = 2 > -inf, record: reset to 1.5, chosen +0.5, others -0.5
    # s0: G = 1 + 0.9 * 2 = 2.8 > -inf, record as well
    episode(learner, [(0, (1, 2), 1.0), (1, (0, 0), 2.0)])
    values = learner.tables.values
    assert values[1, 0, :2].tolist() == [2.0, 1.0]
    assert values[1, 1].tolist() == [2.0, 1.0, 1.0]
    assert values[0, 0, :2].tolist() == [1.0, 2.0]
    assert values[0, 1].tolist() == [1.0, 1.0, 2.0]
    assert learner.max_return(0) == pytest.approx(2.8) and learner.max_return(1) == 2.0
    # eq. (17): p = softmax(c / T)
    assert learner.tables.probs[1, 1].tolist() == pytest.approx(softmax([2.0, 1.0, 1.0]))


def test_tie_takes_the_small_step_and_below_changes_nothing() -> None:
    learner = CMARLCDStochastic([3], n_states=1, seed=0)
    episode(learner, [(0, (0,), 5.0)])  # record: [2.0, 1.0, 1.0]
    episode(learner, [(0, (1,), 5.0)])  # tie: action 1 +0.05, others -0.05
    assert learner.tables.values[0, 0].tolist() == pytest.approx([1.95, 1.05, 0.95])
    episode(learner, [(0, (2,), 4.0)])  # below the record: nothing moves
    assert learner.tables.values[0, 0].tolist() == pytest.approx([1.95, 1.05, 0.95])
    episode(learner, [(0, (2,), 5.0 + 1e-12)])  # within the 1e-9 tolerance: a tie
    assert learner.tables.values[0, 0].tolist() == pytest.approx([1.9, 1.0, 1.0])
    assert learner.max_return(0) == 5.0


def test_degrees_are_clipped_to_c_min_c_max() -> None:
    learner = CMARLCDStochastic([2], StochasticConfig(delta=0.4), n_states=1, seed=0)
    episode(learner, [(0, (0,), 1.0)])  # record: [2.0, 1.0]
    for _ in range(5):  # ties: +0.4 / -0.4 until the clips hold
        episode(learner, [(0, (0,), 1.0)])
    assert learner.tables.values[0, 0].tolist() == [3.0, 0.5]


def test_every_visit_backward_order() -> None:
    """A state visited twice: the later visit (processed first) sets the record."""
    learner = CMARLCDStochastic([2], n_states=2, seed=0)
    # s0 -(0), r=0-> s1 -(1), r=0-> s0 -(1), r=10-> end
    # backwards: t=2 s0 G=10 record (action 1); t=1 s1 G=9 record; t=0 s0 G=8.1 < 10: nothing
    episode(learner, [(0, (0,), 0.0), (1, (1,), 0.0), (0, (1,), 10.0)])
    assert learner.tables.values[0, 0].tolist() == [1.0, 2.0]
    assert learner.max_return(0) == 10.0 and learner.max_return(1) == pytest.approx(9.0)


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


def test_greedy_breaks_ties_by_lowest_index() -> None:
    learner = CMARLCDStochastic([3, 3], n_states=1, seed=0)
    assert learner.greedy(0) == (0, 0)  # all degrees equal c_init


def test_la_oca_reward_inaction_update() -> None:
    learner = LAOCA([2, 3], AutomatonConfig(rate=0.1), seed=0)
    masks = [np.array([1, 1]), np.array([0, 1, 1])]
    learner.act("s", masks)  # first visit: uniform over the legal actions
    assert learner.tables.values[0, 1].tolist() == [0.0, 0.5, 0.5]
    episode(learner, [("s", (1, 2), 1.0)])  # record: p(a) += 0.1 (1 - p(a)), others × 0.9
    assert learner.tables.values[0, 0, :2].tolist() == pytest.approx([0.45, 0.55])
    assert learner.tables.values[0, 1].tolist() == pytest.approx([0.0, 0.45, 0.55])
    episode(learner, [("s", (0, 1), 0.5)])  # below R_max: inaction
    assert learner.tables.values[0, 0, :2].tolist() == pytest.approx([0.45, 0.55])
    episode(learner, [("s", (0, 1), 1.0)])  # tie: rewarded too
    assert learner.tables.values[0, 0, :2].tolist() == pytest.approx([0.505, 0.495])
    assert learner.tables.values[0, 1].tolist() == pytest.approx([0.0, 0.505, 0.495])


def test_hashable_states_grow_the_tables() -> None:
    learner = LAOCA([2, 2], seed=0)
    for k in range(40):
        learner.act(("state", k))
    assert learner.tables.n_states >= 40
    assert learner.max_return(("state", 3)) == -math.inf


@pytest.mark.parametrize(
    ("kwargs", "parameter"),
    [
        ({"c_min": 2.0, "c_max": 1.0}, "c_max"),
        ({"c_min": 0.0}, "c_min"),
        ({"c_init": 5.0}, "c_init"),
        ({"gamma": 0.0}, "gamma"),
        ({"gamma": 1.5}, "gamma"),
        ({"delta": 0.0}, "delta"),
        ({"temperature": -1.0}, "temperature"),
    ],
)
def test_bad_stochastic_config(kwargs: dict, parameter: str) -> None:
    with pytest.raises(ConfigError) as info:
        StochasticConfig(**kwargs)
    assert info.value.parameter == parameter


def test_bad_automaton_config_and_masks() -> None:
    with pytest.raises(ConfigError, match="rate"):
        AutomatonConfig(rate=1.0)
    learner = LAOCA([2, 2], seed=0)
    with pytest.raises(ConfigError, match="masks"):
        learner.act("s", [np.array([0, 0]), np.array([1, 1])])
    with pytest.raises(ConfigError, match="joint_action"):
        learner.observe("s", (0,), 1.0)
