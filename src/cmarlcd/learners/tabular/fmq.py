"""The Frequency Maximum Q-value heuristic, FMQ (Kapetanakis & Kudenko, 2002).

Each agent learns ``Q_i(a) ← Q_i(a) + α (r − Q_i(a))`` as an independent learner, but
explores by Boltzmann over

    ``EV_i(a) = Q_i(a) + c · freq(maxR_i(a)) · maxR_i(a)``,

``maxR_i(a)`` being the largest reward received with ``a`` and ``freq`` the fraction of
the plays of ``a`` that received it (its count restarts when a larger reward appears).
The temperature follows ``T(t) = 500 e^(-0.006 t) + 1``; ``c = 10``. Defined for
repeated games only.

[choice] ``α = 0.9`` as in public reproductions of the paper (we could not check the
text); greedy execution is over ``EV`` (what the agents act on); ``Q = 0`` at the start.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, NamedTuple

import numpy as np

from cmarlcd.compiled import kernel
from cmarlcd.learners.tabular.independent import (
    BoltzmannSchedule,
    ClassicLearner,
    check_positive,
    check_unit,
    greedy_values,
    no_stopping_rule,
    real_actions,
)
from cmarlcd.learners.tabular.protocol import RepeatedKernels
from cmarlcd.learners.tabular.q_learning import boltzmann_act, q_update


class FMQTables(NamedTuple):
    values: np.ndarray
    """``EV_i(a)``, what the agents act on, shape (n_agents, width)."""
    legal: np.ndarray
    probs: np.ndarray
    plays: np.ndarray
    q: np.ndarray
    """``Q_i(a)``."""
    max_reward: np.ndarray
    """``maxR_i(a)`` (``-inf`` before ``a`` is played)."""
    max_count: np.ndarray
    """Plays of ``a`` that received ``maxR_i(a)``."""
    action_count: np.ndarray
    """Plays of ``a``."""


class FMQParams(NamedTuple):
    alpha: float
    weight: float
    max_temperature: float
    decay: float


@kernel
def fmq_learn(tables, params, counts, joint, reward: float) -> bool:
    """Every agent: the Q step, the max-reward frequency, then ``EV`` of its action."""
    tables.plays[0] += 1
    for i in range(counts.shape[0]):
        a = joint[i]
        tables.q[i, a] = q_update(tables.q[i, a], reward, params.alpha)
        tables.action_count[i, a] += 1
        if reward > tables.max_reward[i, a]:
            tables.max_reward[i, a] = reward
            tables.max_count[i, a] = 1
        elif reward == tables.max_reward[i, a]:
            tables.max_count[i, a] += 1
        frequency = tables.max_count[i, a] / tables.action_count[i, a]
        bonus = params.weight * frequency * tables.max_reward[i, a]
        tables.values[i, a] = tables.q[i, a] + bonus
    return True


@dataclass(frozen=True)
class FMQConfig(BoltzmannSchedule, ClassicLearner):
    """FMQ learners in repeated games (Kapetanakis & Kudenko, 2002)."""

    name: ClassVar[str] = "fmq"
    display_name: ClassVar[str] = "FMQ"
    citation: ClassVar[str] = (
        "Kapetanakis & Kudenko (2002), Reinforcement learning of coordination in "
        "cooperative multi-agent systems, AAAI"
    )
    kernels: ClassVar[RepeatedKernels] = RepeatedKernels(
        boltzmann_act, fmq_learn, no_stopping_rule, greedy_values
    )

    alpha: float = 0.9
    """[choice] Learning rate of ``Q``, in (0, 1]."""
    weight: float = 10.0
    """``c``: the weight of the heuristic, > 0."""

    def __post_init__(self) -> None:
        super().__post_init__()
        check_unit(alpha=self.alpha)
        check_positive(weight=self.weight)

    def params(self) -> FMQParams:
        return FMQParams(self.alpha, self.weight, self.max_temperature, self.decay)

    def new_tables(self, counts: np.ndarray) -> FMQTables:
        legal = real_actions(counts)
        zeros = np.zeros(legal.shape)
        return FMQTables(
            zeros.copy(),
            legal,
            zeros.copy(),
            np.zeros(1, dtype=np.int64),
            zeros.copy(),
            np.full(legal.shape, -np.inf),
            np.zeros(legal.shape, dtype=np.int64),
            np.zeros(legal.shape, dtype=np.int64),
        )
