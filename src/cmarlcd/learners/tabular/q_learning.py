"""Independent Q-learners (Claus & Boutilier, 1998): each agent learns the value of its
own actions from the global reward, as if the others were part of the environment.

Repeated games: ``Q_i(a_i) ← Q_i(a_i) + α (r − Q_i(a_i))`` after every game, and each
agent explores by Boltzmann over ``Q_i / T``. Stochastic games: Watkins' Q-learning per
agent, ``Q_i(s, a_i) ← Q_i(s, a_i) + α (r + γ max_a Q_i(s', a) − Q_i(s, a_i))``.

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
from cmarlcd.errors import check_discount
from cmarlcd.learners.tabular.independent import (
    BoltzmannSchedule,
    ClassicLearner,
    StateValueTables,
    ValueTables,
    boltzmann_joint,
    boltzmann_state_act,
    check_unit,
    greedy_state_values,
    greedy_values,
    init_state_values,
    kk_temperature,
    no_stopping_rule,
    state_value_tables,
    td_target,
    value_tables,
)
from cmarlcd.learners.tabular.protocol import (
    RepeatedKernels,
    TabularConfig,
    TabularKernels,
    no_episode_update,
)


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
class BoltzmannQSettings(BoltzmannSchedule):
    """A learning rate and Kapetanakis & Kudenko's schedule: the settings of IQL, JAL and
    central Q."""

    alpha: float = 0.1
    """[choice] Learning rate, in (0, 1]."""

    def __post_init__(self) -> None:
        super().__post_init__()
        check_unit(alpha=self.alpha)

    def params(self) -> BoltzmannQParams:
        return BoltzmannQParams(self.alpha, self.max_temperature, self.decay)


@dataclass(frozen=True)
class IQLConfig(BoltzmannQSettings, ClassicLearner):
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

    def new_tables(self, counts: np.ndarray) -> ValueTables:
        return value_tables(counts)


# ------------------------------------------------------------ stochastic games


class StateQParams(NamedTuple):
    alpha: float
    gamma: float
    max_temperature: float
    decay: float
    initial_value: float


@kernel
def iql_observe(tables, params, states, joints, rewards, t, next_s, terminal) -> None:
    """Every agent: ``Q_i(s, a_i) ← Q_i(s, a_i) + α (r + γ max_a Q_i(s', a) − Q_i(s, a_i))``."""
    s = states[t]
    for i in range(joints.shape[1]):
        a = joints[t, i]
        count = tables.legal.shape[2]
        target = td_target(tables, params, i, rewards[t], next_s, terminal, count)
        tables.values[s, i, a] = q_update(tables.values[s, i, a], target, params.alpha)


@dataclass(frozen=True)
class IQLStochasticConfig(IQLConfig, TabularConfig):
    """Independent Q-learners in stochastic games (Claus & Boutilier, 1998; Watkins'
    Q-learning per agent). [choice] Exploration: the repeated-game Boltzmann schedule,
    counted in visits of each state; ``γ = 0.9`` as the paper's DSN settings."""

    kernels: ClassVar[TabularKernels] = TabularKernels(  # type: ignore[assignment]
        init_state_values, boltzmann_state_act, greedy_state_values, iql_observe,
        no_episode_update,
    )  # fmt: skip

    gamma: float = 0.9
    """Discount, in [0, 1] (0: each step's own reward)."""

    def __post_init__(self) -> None:
        super().__post_init__()
        check_discount(self.gamma)

    def params(self) -> StateQParams:  # type: ignore[override]
        return StateQParams(self.alpha, self.gamma, self.max_temperature, self.decay, 0.0)

    def new_tables(self, n_states: int, counts: np.ndarray) -> StateValueTables:  # type: ignore[override]
        return state_value_tables(n_states, counts)
