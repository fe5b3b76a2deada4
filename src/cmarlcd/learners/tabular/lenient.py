"""Lenient learners (Panait, Sullivan & Luke, 2006), in the form of Wei & Luke's LMRL2
(2016), whose defaults are published: independent Q-learners that forgive their
teammates' early exploration.

Each agent keeps per action a value ``Q_i(a)`` and a temperature ``T_i(a)`` (starting
at ``max_temperature``). After a game with reward ``r``:

* lenience: with ``δ = r − Q_i(a_i)``, the update is made if ``δ ≥ 0``, and otherwise
  only with probability ``1 − exp(−1 / (θ T_i(a_i)))``: while the action is hot, bad
  news (most likely a teammate exploring) is mostly ignored;
* ``Q_i(a_i) ← Q_i(a_i) + α δ`` if made; then ``T_i(a_i) ← decay · T_i(a_i)``.

In stochastic games (LMRL2) the target is ``r + γ max_a Q_i(s', a)``, and the played
action cools towards the next state's mean temperature,
``T_i(s, a) ← decay · ((1 − τ) T_i(s, a) + τ T̄_i(s'))`` (``decay · T_i(s, a)`` when the
episode ends).

Acting: with ``T̄_i`` the mean temperature of the agent's actions, greedily once
``T̄_i < min_temperature``, otherwise Boltzmann over ``Q_i / (ω T̄_i)``.

Defaults (LMRL2): ``α = 0.1``, ``decay = 0.995``, ``max_temperature = 50``,
``min_temperature = 2``, ``ω = θ = 1``. [choice] ``Q = 0`` at the start; greedy ties go
to the lowest action (LMRL2 breaks them at random). Each agent's lenience draw is taken
from the learners' stream when it acts (one uniform per agent after the actions), so
``learn`` needs no stream of its own.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar, NamedTuple

import numpy as np
from numba import njit

from cmarlcd.compiled import kernel
from cmarlcd.errors import check_discount, require
from cmarlcd.learners.policy import greedy_action, sample_action, softmax_strategy
from cmarlcd.learners.tabular.independent import (
    ClassicLearner,
    check_positive,
    check_unit,
    greedy_state_values,
    greedy_values,
    no_stopping_rule,
    real_actions,
    td_target,
)
from cmarlcd.learners.tabular.protocol import (
    RepeatedKernels,
    TabularConfig,
    TabularKernels,
    no_episode_update,
)
from cmarlcd.learners.tabular.q_learning import q_update


class LenientTables(NamedTuple):
    values: np.ndarray
    """``Q_i(a)``, shape (n_agents, width)."""
    legal: np.ndarray
    probs: np.ndarray
    temperatures: np.ndarray
    """``T_i(a)``, same shape."""
    draws: np.ndarray
    """Each agent's lenience draw for the game being played, shape (n_agents,)."""


class LenientParams(NamedTuple):
    alpha: float
    decay: float
    min_temperature: float
    action_moderation: float
    lenience_moderation: float


@njit(cache=True)
def mean_temperature(temperatures_row, legal_row, count: int) -> float:
    """The mean temperature of the legal actions."""
    total, legal = 0.0, 0
    for a in range(count):
        if legal_row[a]:
            total += temperatures_row[a]
            legal += 1
    return total / legal


@njit(cache=True)
def lenient_choice(values, temperatures, legal, probs, counts, params, rng, joint, draws) -> None:
    """Every agent: greedy once its mean temperature is below ``min_temperature``, else
    Boltzmann over ``Q / (ω T̄)``; then one lenience draw per agent (rows of one state)."""
    for i in range(counts.shape[0]):
        mean = mean_temperature(temperatures[i], legal[i], counts[i])
        if mean < params.min_temperature:
            joint[i] = greedy_action(values[i], legal[i], counts[i])
        else:
            temperature = params.action_moderation * mean
            softmax_strategy(values[i], legal[i], counts[i], temperature, probs[i])
            joint[i] = sample_action(probs[i], counts[i], rng.random())
    for i in range(counts.shape[0]):
        draws[i] = rng.random()


@kernel
def lenient_act(tables, params, counts, rng, joint) -> None:
    """:func:`lenient_choice` on the agents' rows."""
    lenient_choice(
        tables.values, tables.temperatures, tables.legal, tables.probs, counts, params, rng,
        joint, tables.draws,
    )  # fmt: skip


@njit(cache=True)
def is_lenient(delta: float, temperature: float, moderation: float, draw: float) -> bool:
    """Whether a decrease ``delta < 0`` is ignored: with probability
    ``exp(−1 / (θ T))`` (``draw`` uniform)."""
    return delta < 0.0 and draw >= 1.0 - math.exp(-1.0 / (moderation * temperature))


@kernel
def lenient_learn(tables, params, counts, joint, reward: float) -> bool:
    """Every agent: the lenient Q step on its action, then that action cools down."""
    for i in range(counts.shape[0]):
        a = joint[i]
        value, temperature = tables.values[i, a], tables.temperatures[i, a]
        forgiven = is_lenient(
            reward - value, temperature, params.lenience_moderation, tables.draws[i]
        )
        if not forgiven:
            tables.values[i, a] = q_update(value, reward, params.alpha)
        tables.temperatures[i, a] = params.decay * temperature
    return True


@dataclass(frozen=True)
class LenientConfig(ClassicLearner):
    """Lenient learners in repeated games (Panait, Sullivan & Luke, 2006; LMRL2)."""

    name: ClassVar[str] = "lenient"
    display_name: ClassVar[str] = "Lenient"
    citation: ClassVar[str] = (
        "Panait, Sullivan & Luke (2006), Lenient learners in cooperative multiagent "
        "systems, AAMAS; defaults of Wei & Luke (2016), JMLR 17"
    )
    kernels: ClassVar[RepeatedKernels] = RepeatedKernels(
        lenient_act, lenient_learn, no_stopping_rule, greedy_values
    )

    alpha: float = 0.1
    """Learning rate, in (0, 1]."""
    decay: float = 0.995
    """Factor of an action's temperature each time it is played, in (0, 1]."""
    max_temperature: float = 50.0
    """Every action's temperature at the start, > 0."""
    min_temperature: float = 2.0
    """Below this mean temperature an agent acts greedily, >= 0."""
    action_moderation: float = 1.0
    """``ω``: scales the Boltzmann temperature, > 0."""
    lenience_moderation: float = 1.0
    """``θ``: scales the temperature in the lenience test, > 0."""

    def __post_init__(self) -> None:
        check_unit(alpha=self.alpha, decay=self.decay)
        check_positive(
            max_temperature=self.max_temperature,
            action_moderation=self.action_moderation,
            lenience_moderation=self.lenience_moderation,
        )
        low = self.min_temperature
        require(bool(np.isfinite(low)) and low >= 0, "min_temperature", f"must be >= 0 (got {low})")

    def params(self) -> LenientParams:
        return LenientParams(
            self.alpha,
            self.decay,
            self.min_temperature,
            self.action_moderation,
            self.lenience_moderation,
        )

    def new_tables(self, counts: np.ndarray) -> LenientTables:
        legal = real_actions(counts)
        return LenientTables(
            np.zeros(legal.shape),
            legal,
            np.zeros(legal.shape),
            np.where(legal, self.max_temperature, 0.0),
            np.zeros(counts.shape[0]),
        )


# ------------------------------------------------------------ stochastic games


class StateLenientTables(NamedTuple):
    values: np.ndarray
    """``Q_i(s, a)``, shape (n_states, n_agents, width)."""
    legal: np.ndarray
    probs: np.ndarray
    temperatures: np.ndarray
    """``T_i(s, a)``, same shape."""
    draws: np.ndarray
    """Each agent's lenience draw for its last action in each state, (n_states, n_agents)."""


class StateLenientParams(NamedTuple):
    alpha: float
    decay: float
    min_temperature: float
    action_moderation: float
    lenience_moderation: float
    gamma: float
    diffusion: float
    max_temperature: float


@kernel
def lenient_init(tables, params, s, legal, counts) -> None:
    """A state before any update: ``Q = 0``, every legal action at ``max_temperature``."""
    for i in range(counts.shape[0]):
        for a in range(legal.shape[1]):
            tables.legal[s, i, a] = legal[i, a]
            tables.values[s, i, a] = 0.0
            tables.temperatures[s, i, a] = params.max_temperature if legal[i, a] else 0.0


@kernel
def lenient_state_act(tables, params, s, counts, rng, joint) -> None:
    """:func:`lenient_choice` on the rows of state ``s``."""
    lenient_choice(
        tables.values[s], tables.temperatures[s], tables.legal[s], tables.probs[s], counts,
        params, rng, joint, tables.draws[s],
    )  # fmt: skip


@kernel
def lenient_observe(tables, params, states, joints, rewards, t, next_s, terminal) -> None:
    """LMRL2's step: the lenient Q step towards ``r + γ max_a Q_i(s', a)``, then the
    action cools, ``T ← decay · ((1 − τ) T + τ T̄(s'))`` (``decay · T`` at the end)."""
    s = states[t]
    width = tables.legal.shape[2]
    for i in range(joints.shape[1]):
        a = joints[t, i]
        value, temperature = tables.values[s, i, a], tables.temperatures[s, i, a]
        target = td_target(tables, params, i, rewards[t], next_s, terminal, width)
        forgiven = is_lenient(
            target - value, temperature, params.lenience_moderation, tables.draws[s, i]
        )
        if not forgiven:
            tables.values[s, i, a] = q_update(value, target, params.alpha)
        if not terminal:
            later = mean_temperature(tables.temperatures[next_s, i], tables.legal[next_s, i], width)
            temperature = (1.0 - params.diffusion) * temperature + params.diffusion * later
        tables.temperatures[s, i, a] = params.decay * temperature


@dataclass(frozen=True)
class LenientStochasticConfig(LenientConfig, TabularConfig):
    """Lenient learners in stochastic games: LMRL2 (Wei & Luke, 2016), after Panait,
    Sullivan & Luke (2006). Defaults as :class:`LenientConfig`, with LMRL2's ``γ = 0.9``
    and temperature diffusion ``τ = 0.1``."""

    kernels: ClassVar[TabularKernels] = TabularKernels(  # type: ignore[assignment]
        lenient_init, lenient_state_act, greedy_state_values, lenient_observe,
        no_episode_update,
    )  # fmt: skip

    gamma: float = 0.9
    """Discount, in [0, 1] (0: each step's own reward)."""
    diffusion: float = 0.1
    """``τ``: how much of the next state's mean temperature flows back, in (0, 1]."""

    def __post_init__(self) -> None:
        super().__post_init__()
        check_discount(self.gamma)
        check_unit(diffusion=self.diffusion)

    def params(self) -> StateLenientParams:  # type: ignore[override]
        return StateLenientParams(
            self.alpha,
            self.decay,
            self.min_temperature,
            self.action_moderation,
            self.lenience_moderation,
            self.gamma,
            self.diffusion,
            self.max_temperature,
        )

    def new_tables(self, n_states: int, counts: np.ndarray) -> StateLenientTables:  # type: ignore[override]
        shape = (n_states, counts.shape[0], int(counts.max()))
        return StateLenientTables(
            np.zeros(shape),
            np.zeros(shape, dtype=np.bool_),
            np.zeros(shape),
            np.zeros(shape),
            np.zeros(shape[:2]),
        )
