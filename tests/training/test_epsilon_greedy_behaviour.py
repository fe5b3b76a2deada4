"""Deep CMARL-CD's ε-greedy behaviour (``behaviour="epsilon-greedy"``, a diagnostic beyond
the paper): ε annealed by hand, the draws' frequencies by hand in the compiled loop and
in the object API, illegal actions never drawn, and bad settings rejected."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("torch")

from cmarlcd.errors import ConfigError
from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig
from cmarlcd.learners.deep.degree_agent import DegreeAgent
from tests.training.memory_draws import MEMORY, draws_at_state_2


def epsilon_greedy(start: float, end: float = 0.05, steps: int = 0) -> DeepCMARLCDConfig:
    return DeepCMARLCDConfig(
        behaviour="epsilon-greedy", epsilon_start=start, epsilon_end=end,
        epsilon_steps=steps, **MEMORY,
    )  # fmt: skip


def test_epsilon_anneals_linearly_then_stays() -> None:
    """From 1 to 0.05 over 100 steps: 1 at the start, 0.525 half-way, 0.05 after."""
    config = epsilon_greedy(1.0, 0.05, 100)
    values = [config.behaviour_epsilon(k) for k in (0, 50, 100, 10**9)]
    assert values == pytest.approx([1.0, 0.525, 0.05, 0.05])
    assert epsilon_greedy(0.3).behaviour_epsilon(10**9) == 0.3  # no anneal: the start


def compiled_draws(config: DeepCMARLCDConfig, times: int, turns: int = 0) -> list:
    """Joint actions at CHAIN's state 2, degrees (0.5, 3, 0.5) and (0.5, 0.5, 3)."""
    return draws_at_state_2(config, 3.0, times, turns)


def test_the_compiled_loop_draws_epsilon_greedy_by_hand() -> None:
    """ε 0.3 over 3 legal actions: each agent takes its greedy action with probability
    0.7 + 0.3 / 3 = 0.8 and each other with 0.1, so the greedy joint action (1, 2)
    with 0.64."""
    draws = np.array(compiled_draws(epsilon_greedy(0.3), 4_000))
    assert np.mean((draws == (1, 2)).all(axis=1)) == pytest.approx(0.64, abs=0.03)
    for agent, best in ((0, 1), (1, 2)):  # standard error 0.005
        freq = np.bincount(draws[:, agent], minlength=3) / len(draws)
        expected = np.full(3, 0.1)
        expected[best] = 0.8
        assert freq == pytest.approx(expected, abs=0.025)


def test_epsilon_at_its_ends_is_greedy_or_uniform() -> None:
    """ε 0 (here, 1 annealed to 0 over 100 steps, after them) always takes (1, 2); ε 1
    draws every joint action with probability 1/9."""
    assert set(compiled_draws(epsilon_greedy(1.0, 0.0, 100), 300, turns=100)) == {(1, 2)}
    draws = compiled_draws(epsilon_greedy(1.0), 9_000)
    counts = np.array([draws.count((a, b)) for a in range(3) for b in range(3)])
    assert counts / len(draws) == pytest.approx(np.full(9, 1 / 9), abs=0.015)


def test_the_softmax_behaviour_is_not_epsilon_greedy() -> None:
    """The default (eq. 17 at T = 1 on degrees 0.5 and 3) draws the greedy action with
    probability e^2.5 / (e^2.5 + 2) = 0.859 per agent, not ε-greedy's at any one ε:
    the setting is what switches the rule."""
    softmax = compiled_draws(DeepCMARLCDConfig(**MEMORY), 4_000)
    greedy = np.mean([j[0] == 1 for j in softmax])
    p = np.exp(2.5) / (np.exp(2.5) + 2)
    assert greedy == pytest.approx(p, abs=0.03)
    assert compiled_draws(epsilon_greedy(0.0), 50) == [(1, 2)] * 50


def test_the_object_api_is_epsilon_greedy_on_legal_actions() -> None:
    """A record at state 0 raises the taken action 1 above the others: at ε 0.3 it is
    drawn with probability 0.8; with action 1 illegal and ε 1, actions 0 and 2 only,
    each about half the time."""
    agent = DegreeAgent([3], epsilon_greedy(0.3), 10, n_states=2, seed=0)
    agent.observe(0, (1,), 5.0)
    agent.end_episode()
    draws = [agent.act(0)[0] for _ in range(3_000)]
    assert np.mean(np.array(draws) == 1) == pytest.approx(0.8, abs=0.03)
    uniform = DegreeAgent([3], epsilon_greedy(1.0), 10, n_states=2, seed=0)
    mask = [np.array([True, False, True])]
    draws = [uniform.act(0, mask)[0] for _ in range(2_000)]
    assert set(draws) == {0, 2}
    assert np.mean(np.array(draws) == 0) == pytest.approx(0.5, abs=0.04)


def test_the_object_api_anneals_over_the_steps_it_observed() -> None:
    """ε from 1 to 0 over 4 steps: after 4 observed steps the agent acts greedily."""
    agent = DegreeAgent([3], epsilon_greedy(1.0, 0.0, 4), 10, n_states=2, seed=0)
    agent.observe(0, (1,), 5.0)
    agent.end_episode()
    for _ in range(3):
        agent.observe(1, (0,), 0.0)
    agent.end_episode()
    assert agent.steps == 4
    assert {agent.act(0) for _ in range(200)} == {(1,)}


@pytest.mark.parametrize(
    ("settings", "name"),
    [
        ({"behaviour": "greedy"}, "behaviour"),
        ({"epsilon_start": 1.5}, "epsilon_start"),
        ({"epsilon_end": -0.1}, "epsilon_end"),
        ({"epsilon_end": float("nan")}, "epsilon_end"),
        ({"epsilon_steps": -1}, "epsilon_steps"),
    ],
)
def test_bad_behaviour_settings_are_rejected(settings: dict, name: str) -> None:
    with pytest.raises(ConfigError, match=name):
        DeepCMARLCDConfig(**settings)
