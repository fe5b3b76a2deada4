"""Deep CMARL-CD's behaviour temperature in the range of the degrees
(``temperature_unit="range"``): the range by hand, the strategy by hand in the compiled
loop and in the object API, the same draws whatever the degrees' scale, and a bad unit
rejected."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("torch")

from cmarlcd.errors import ConfigError
from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig
from cmarlcd.learners.deep.degree_agent import DegreeAgent
from cmarlcd.training.degree_kernels import legal_range
from tests.training.memory_draws import MEMORY, draws_at_state_2

#: The strategy of degrees (a, b, a), b > a, at T = 0.5 ranges: softmax of (-2, 0, -2).
P_BEST = 1 / (1 + 2 * math.exp(-2))


def test_the_range_is_over_the_legal_degrees() -> None:
    row = np.array([1.0, 2.0, 4.0])
    assert legal_range(row, np.array([True, True, True]), 3) == 3.0
    assert legal_range(row, np.array([True, True, False]), 3) == 1.0
    assert legal_range(row, np.array([True, True, True]), 2) == 1.0  # the first 2 actions
    assert legal_range(np.array([2.0, 2.0]), np.array([True, True]), 2) == 1.0  # all equal


def compiled_draws(unit: str, best: float, times: int) -> list[tuple[int, int]]:
    """``times`` joint actions drawn at CHAIN's state 2, whose memory holds degrees
    (0.5, best, 0.5) for agent 0 and (0.5, 0.5, best) for agent 1, at T = 0.5."""
    config = DeepCMARLCDConfig(temperature=0.5, temperature_unit=unit, **MEMORY)
    return draws_at_state_2(config, best, times)


def test_the_compiled_loop_draws_from_the_strategy_by_hand() -> None:
    """Degrees (0.5, 3, 0.5) at T = 0.5 ranges (2.5): T 1.25, the best action drawn
    with probability 1 / (1 + 2 e^-2) = 0.787 by each agent; at a fixed T of 0.5 with
    1 / (1 + 2 e^-5) = 0.987."""
    draws = compiled_draws("range", 3.0, 4_000)
    best = np.mean([j == (1, 2) for j in draws])
    assert best == pytest.approx(P_BEST**2, abs=0.03)  # standard error 0.008
    fixed = np.mean([j == (1, 2) for j in compiled_draws("fixed", 3.0, 4_000)])
    assert fixed == pytest.approx((1 / (1 + 2 * math.exp(-5))) ** 2, abs=0.01)


def test_the_draws_do_not_depend_on_the_degrees_scale() -> None:
    """Degrees (0.5, 1, 0.5) have a fifth of (0.5, 3, 0.5)'s range: in ranges the two
    are one strategy, and the same generator draws the same joint actions; at a fixed T
    they differ."""
    assert compiled_draws("range", 1.0, 500) == compiled_draws("range", 3.0, 500)
    assert compiled_draws("fixed", 1.0, 500) != compiled_draws("fixed", 3.0, 500)


def test_the_object_api_measures_t_in_the_range_of_the_degrees() -> None:
    """A record resets the memory's degrees to (1, 2, 1): range 1, so T = 0.5 ranges is
    T 0.5 and the best action is drawn with probability 0.787; scaled tenfold (from
    ``c_init`` 5.5 by ``delta_reset`` 5: degrees (0.5, 10.5, 0.5)) the same."""
    for c_init, delta_reset in ((1.5, 0.5), (5.5, 5.0)):
        config = DeepCMARLCDConfig(
            temperature=0.5, temperature_unit="range", c_init=c_init,
            delta_reset=delta_reset, c_max=11.0, **MEMORY,
        )  # fmt: skip
        agent = DegreeAgent([3], config, 10, n_states=2, seed=0)
        agent.observe(0, (1,), 5.0)  # a record at state 0: the taken action raised
        agent.end_episode()
        best = np.mean([agent.act(0) == (1,) for _ in range(3_000)])
        assert best == pytest.approx(P_BEST, abs=0.03)  # standard error 0.007


def test_an_unknown_unit_is_rejected() -> None:
    with pytest.raises(ConfigError, match="temperature_unit"):
        DeepCMARLCDConfig(temperature_unit="spread")
