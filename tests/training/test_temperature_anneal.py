"""Deep CMARL-CD's behaviour temperature annealed over a seed's steps
(``temperature_steps``, ``temperature_end``): the anneal by hand, in the compiled loop and
in the object API, and rejected settings."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("torch")

from cmarlcd.errors import ConfigError
from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig
from cmarlcd.learners.deep.degree_agent import DegreeAgent
from cmarlcd.learners.policy import annealed
from cmarlcd.testing import CHAIN
from cmarlcd.training.deep import DeepBatch
from cmarlcd.training.deep_kernels import TURNS

#: From near uniform (T = 100 over degrees in [0.5, 3]) to near greedy (T = 0.01) over
#: ten steps.
ANNEALS = {"temperature": 100.0, "temperature_end": 0.01, "temperature_steps": 10}


def test_the_temperature_anneals_linearly_then_stays() -> None:
    assert annealed(1.0, 0.1, 100, 0) == 1.0
    assert annealed(1.0, 0.1, 100, 50) == pytest.approx(0.55)
    assert annealed(1.0, 0.1, 100, 100) == pytest.approx(0.1)
    assert annealed(1.0, 0.1, 100, 10_000) == pytest.approx(0.1)
    assert annealed(1.0, 0.1, 0, 50) == 1.0  # no anneal: the paper's fixed T
    config = DeepCMARLCDConfig(temperature=2.0, temperature_end=0.5, temperature_steps=4)
    assert [config.behaviour_temperature(k) for k in (0, 1, 4, 9)] == pytest.approx(
        [2.0, 1.625, 0.5, 0.5]
    )
    assert DeepCMARLCDConfig().behaviour_temperature(10**9) == 1.0


def draws(act, times: int = 40) -> set[tuple[int, ...]]:
    return {tuple(act()) for _ in range(times)}


def test_the_compiled_loop_explores_at_the_start_and_acts_greedily_after_the_anneal() -> None:
    """CHAIN's one-hot state 2 kept with degrees that make (1, 2) greedy: before the
    anneal (T = 100) the side draws other joint actions too; after its ten steps (T =
    0.01) it draws (1, 2) every time."""
    config = DeepCMARLCDConfig(
        act_from="memory", unseen_record="first-visit", buffer_size=64, batch_size=8,
        train_every=4, **ANNEALS,
    )  # fmt: skip
    batch = DeepBatch(CHAIN, config, [np.random.SeedSequence(3)], 300)
    view = batch.group.views[0]
    data, memory = view.data, view.data.replay.memory
    memory.filled[2], memory.key[2] = True, np.uint64(2)
    memory.target[2] = [[0.5, 3.0, 0.5], [0.5, 0.5, 3.0]]
    rng, joint = np.random.default_rng(0), np.zeros(2, np.int64)

    def act() -> np.ndarray:
        view.kernels.act(data, 2, rng, joint)
        return joint

    assert len(draws(act)) > 1
    data.counters[TURNS] = 10
    assert draws(act) == {(1, 2)}


def test_the_object_api_anneals_over_the_steps_it_observed() -> None:
    config = DeepCMARLCDConfig(act_from="memory", unseen_record="first-visit", **ANNEALS)
    agent = DegreeAgent([3], config, 10, n_states=2, seed=0)
    agent.observe(0, (1,), 5.0)  # a record: the memory's degrees [1, 2, 1]
    agent.end_episode()
    assert len(draws(lambda: agent.act(0))) > 1
    agent.steps = 10
    assert draws(lambda: agent.act(0)) == {(1,)}


@pytest.mark.parametrize(
    ("settings", "named"),
    [
        ({"temperature_end": 0.0}, "temperature_end"),
        ({"temperature_end": float("nan")}, "temperature_end"),
        ({"temperature_steps": -1}, "temperature_steps"),
    ],
)
def test_bad_anneals_are_rejected(settings: dict, named: str) -> None:
    with pytest.raises(ConfigError, match=named):
        DeepCMARLCDConfig(**settings)
