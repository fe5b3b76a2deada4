"""Independent Q-learners (Claus & Boutilier, 1998): each agent learns the value of its
own actions from the global reward, as if the others were part of the environment.

Repeated games: ``Q_i(a_i) ← Q_i(a_i) + α (r − Q_i(a_i))`` after every game, and each
agent explores by Boltzmann over ``Q_i / T``.

[choice] Claus & Boutilier's temperature schedule is not stated in a form we could
check; the schedule is Kapetanakis & Kudenko's (2002) ``T(t) = 500 e^(-0.006 t) + 1``,
so that this learner and FMQ differ by FMQ's heuristic alone. [choice] ``α = 0.1`` and
``Q = 0`` at the start.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, NamedTuple

import numpy as np
from numba import njit

from cmarlcd.compiled import kernel
from cmarlcd.learners.independent import (
    KK_DECAY,
    KK_MAX_TEMPERATURE,
    ClassicLearner,
    ValueTables,
    boltzmann_joint,
    check_positive,
    check_unit,
    greedy_values,
    kk_temperature,
    no_stopping_rule,
    value_tables,
)
from cmarlcd.learners.tabular import RepeatedKernels


class BoltzmannQParams(NamedTuple):
    """The compiled parameters of a Q-learner exploring on Kapetanakis & Kudenko's schedule."""

    alpha: float
    max_temperature: float
    decay: float


@njit(cache=True)
def q_update(value: float, target: float, rate: float) -> float:
    """``Q ← Q + rate · (target − Q)``: the Q-learning step towards ``target``."""
    return value + rate * (target - value)


@kernel
def boltzmann_act(tables, params, counts, rng, joint) -> None:
    """Each agent samples from ``softmax(Q_i / T(t))``, ``t`` the games played so far."""
    temperature = kk_temperature(tables.plays[0], params.max_temperature, params.decay)
    boltzmann_joint(tables.values, tables.legal, tables.probs, counts, temperature, rng, joint)


@kernel
def iql_learn(tables, params, counts, joint, reward: float) -> bool:
    """Every agent: ``Q_i(a_i) ← Q_i(a_i) + α (r − Q_i(a_i))``."""
    tables.plays[0] += 1
    for i in range(counts.shape[0]):
        a = joint[i]
        tables.values[i, a] = q_update(tables.values[i, a], reward, params.alpha)
    return True


@dataclass(frozen=True)
class IQLConfig(ClassicLearner):
    """Independent Q-learners in repeated games (Claus & Boutilier, 1998)."""

    name: ClassVar[str] = "iql"
    display_name: ClassVar[str] = "IQL"
    citation: ClassVar[str] = (
        "Claus & Boutilier (1998), The dynamics of reinforcement learning in cooperative "
        "multiagent systems, AAAI"
    )
    kernels: ClassVar[RepeatedKernels] = RepeatedKernels(
        boltzmann_act, iql_learn, no_stopping_rule, greedy_values
    )

    alpha: float = 0.1
    """[choice] Learning rate, in (0, 1]."""
    max_temperature: float = KK_MAX_TEMPERATURE
    """Boltzmann schedule ``T(t) = max_temperature · e^(-decay t) + 1``."""
    decay: float = KK_DECAY
    """See ``max_temperature``."""

    def __post_init__(self) -> None:
        check_unit(alpha=self.alpha)
        check_positive(max_temperature=self.max_temperature, decay=self.decay)

    def params(self) -> BoltzmannQParams:
        return BoltzmannQParams(self.alpha, self.max_temperature, self.decay)

    def new_tables(self, counts: np.ndarray) -> ValueTables:
        return value_tables(counts)
