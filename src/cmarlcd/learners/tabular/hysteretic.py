"""Hysteretic Q-learning (Matignon, Laurent & Le Fort-Piat, 2007): independent
Q-learners that learn fast from good news and slowly from bad news.

Repeated games: ``δ = r − Q_i(a_i)``, then ``Q_i(a_i) ← Q_i(a_i) + α δ`` if ``δ ≥ 0``,
else ``Q_i(a_i) + β δ``, with ``β < α``: a teammate's exploration, which lowers the
reward, is forgiven more than it is learned. Stochastic games: the same with
``δ = r + γ max_a Q_i(s', a) − Q_i(s, a_i)``.

Defaults ``α = 0.1``, ``β = 0.01`` are the paper's matrix-game settings (with ``γ = 0``
in a repeated game). [choice] The paper explores by softmax without a schedule we could
check; it uses Kapetanakis & Kudenko's ``T(t) = 500 e^(-0.006 t) + 1``, as IQL and FMQ
do here. [choice] ``Q = 0`` at the start.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, NamedTuple

import numpy as np
from numba import njit

from cmarlcd.compiled import kernel
from cmarlcd.errors import check_discount, require
from cmarlcd.learners.tabular.independent import (
    BoltzmannSchedule,
    ClassicLearner,
    StateValueTables,
    ValueTables,
    boltzmann_state_act,
    check_unit,
    greedy_state_values,
    greedy_values,
    init_state_values,
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
from cmarlcd.learners.tabular.q_learning import boltzmann_act


class HystereticParams(NamedTuple):
    alpha: float
    beta: float
    max_temperature: float
    decay: float


@njit(cache=True)
def hysteretic_update(value: float, target: float, alpha: float, beta: float) -> float:
    """``Q + α δ`` if ``δ = target − Q ≥ 0``, else ``Q + β δ``."""
    delta = target - value
    return value + (alpha if delta >= 0.0 else beta) * delta


@kernel
def hysteretic_learn(tables, params, counts, joint, reward: float) -> bool:
    """Every agent's hysteretic step on the action it played."""
    tables.plays[0] += 1
    for i in range(counts.shape[0]):
        a = joint[i]
        tables.values[i, a] = hysteretic_update(
            tables.values[i, a], reward, params.alpha, params.beta
        )
    return True


@dataclass(frozen=True)
class HystereticConfig(BoltzmannSchedule, ClassicLearner):
    """Hysteretic Q-learners in repeated games (Matignon, Laurent & Le Fort-Piat, 2007)."""

    name: ClassVar[str] = "hysteretic"
    display_name: ClassVar[str] = "Hysteretic"
    citation: ClassVar[str] = (
        "Matignon, Laurent & Le Fort-Piat (2007), Hysteretic Q-learning: an algorithm for "
        "decentralized reinforcement learning in cooperative multi-agent teams, IROS"
    )
    kernels: ClassVar[RepeatedKernels] = RepeatedKernels(
        boltzmann_act, hysteretic_learn, no_stopping_rule, greedy_values
    )

    alpha: float = 0.1
    """Rate of increases (``δ ≥ 0``), in (0, 1]."""
    beta: float = 0.01
    """Rate of decreases (``δ < 0``), in (0, alpha]."""

    def __post_init__(self) -> None:
        super().__post_init__()
        check_unit(alpha=self.alpha, beta=self.beta)
        require(
            self.beta <= self.alpha, "beta", f"must be <= alpha = {self.alpha} (got {self.beta})"
        )

    def params(self) -> HystereticParams:
        return HystereticParams(self.alpha, self.beta, self.max_temperature, self.decay)

    def new_tables(self, counts: np.ndarray) -> ValueTables:
        return value_tables(counts)


# ------------------------------------------------------------ stochastic games


class StateHystereticParams(NamedTuple):
    alpha: float
    beta: float
    gamma: float
    max_temperature: float
    decay: float
    initial_value: float


@kernel
def hysteretic_observe(tables, params, states, joints, rewards, t, next_s, terminal) -> None:
    """Every agent's hysteretic step towards ``r + γ max_a Q_i(s', a)``."""
    s = states[t]
    for i in range(joints.shape[1]):
        a = joints[t, i]
        target = td_target(tables, params, i, rewards[t], next_s, terminal, tables.legal.shape[2])
        tables.values[s, i, a] = hysteretic_update(
            tables.values[s, i, a], target, params.alpha, params.beta
        )


@dataclass(frozen=True)
class HystereticStochasticConfig(HystereticConfig, TabularConfig):
    """Hysteretic Q-learners in stochastic games (Matignon, Laurent & Le Fort-Piat,
    2007). [choice] Exploration: the repeated-game Boltzmann schedule counted in visits
    of each state; ``γ = 0.9`` as the paper's DSN settings."""

    kernels: ClassVar[TabularKernels] = TabularKernels(  # type: ignore[assignment]
        init_state_values, boltzmann_state_act, greedy_state_values, hysteretic_observe,
        no_episode_update,
    )  # fmt: skip

    gamma: float = 0.9
    """Discount, in [0, 1] (0: each step's own reward)."""

    def __post_init__(self) -> None:
        super().__post_init__()
        check_discount(self.gamma)

    def params(self) -> StateHystereticParams:  # type: ignore[override]
        return StateHystereticParams(
            self.alpha, self.beta, self.gamma, self.max_temperature, self.decay, 0.0
        )

    def new_tables(self, n_states: int, counts: np.ndarray) -> StateValueTables:  # type: ignore[override]
        return state_value_tables(n_states, counts)
