"""LA-OCA, the learning-automata baseline (ref. [23] of the paper), as a documented stand-in.

The paper gives no update rule for LA-OCA and its reference is not openly available.
[choice] Per state, each agent runs a linear reward-inaction automaton driven
by the same max-return indicator as CMARL-CD (:mod:`cmarlcd.learners.max_return`): when
the return from a state reaches the best seen from it, the action taken is rewarded,

    p(s, a_t) += λ (1 - p(s, a_t)),    p(s, a) *= (1 - λ)  for every other legal a,

otherwise nothing changes. Initial strategies are uniform over the legal actions;
execution takes ``argmax p``. Reported beside the paper's published LA-OCA row.

This file is the whole learner: config, tables, compiled functions, object API.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, NamedTuple

import numpy as np
from numba import njit

from cmarlcd.compiled import kernel
from cmarlcd.errors import require
from cmarlcd.learners.max_return import (
    BELOW,
    check_gamma_tolerance,
    visit,
)
from cmarlcd.learners.policy import greedy_action, sample_from_strategies
from cmarlcd.learners.tabular.protocol import (
    MaxReturnLearner,
    TabularConfig,
    TabularKernels,
    no_step_update,
)


class AutomatonTables(NamedTuple):
    """The automata of every state index ``s`` (leading axis) and agent ``i``."""

    probs: np.ndarray
    """``p_i(s, a)``, shape (n_states, n_agents, width)."""
    legal: np.ndarray
    """Legal actions of each state, as first seen, same shape."""
    r_max: np.ndarray
    """``R_max(s)``: the best discounted return seen from ``s``, shape (n_states,)."""


class AutomatonParams(NamedTuple):
    """The stand-in's parameters, as the compiled functions read them."""

    rate: float
    gamma: float
    tolerance: float


@njit(cache=True)
def automaton_rule(
    p_row: np.ndarray, legal_row: np.ndarray, count: int, action: int, rate: float
) -> None:
    """Linear reward-inaction step of rate ``λ`` towards ``action``."""
    for a in range(count):
        if a == action:
            p_row[a] += rate * (1.0 - p_row[a])
        elif legal_row[a]:
            p_row[a] *= 1.0 - rate


@njit(cache=True)
def uniform_strategy(legal_row: np.ndarray, count: int, p_row: np.ndarray) -> None:
    """The automaton's initial strategy: uniform over the legal actions."""
    n_legal = 0
    for a in range(count):
        n_legal += legal_row[a]
    for a in range(count):
        p_row[a] = 1.0 / n_legal if legal_row[a] else 0.0


@kernel
def automaton_init(tables, params, s, legal, counts) -> None:
    """A state before any update: uniform strategies over the legal actions."""
    tables.r_max[s] = -np.inf
    for i in range(counts.shape[0]):
        for a in range(legal.shape[1]):
            tables.legal[s, i, a] = legal[i, a]
        uniform_strategy(tables.legal[s, i], counts[i], tables.probs[s, i])


@kernel
def automaton_greedy(tables, s, counts, joint) -> None:
    """Execution: each agent's most probable legal action (lowest index on ties)."""
    for i in range(counts.shape[0]):
        joint[i] = greedy_action(tables.probs[s, i], tables.legal[s, i], counts[i])


@njit(cache=True)
def automaton_backward(
    probs, legal, r_max, params, states, joints, rewards, length, counts
) -> None:
    """The max-return pass over the tables' arrays, then :func:`automaton_rule` for every
    agent at every visit that reached its state's record (records and ties alike),
    backwards."""
    g = 0.0
    for t in range(length - 1, -1, -1):
        g, outcome = visit(r_max, params, states[t], rewards[t], g)
        if outcome != BELOW:
            s = states[t]
            for i in range(counts.shape[0]):
                automaton_rule(probs[s, i], legal[s, i], counts[i], joints[t, i], params.rate)


@kernel
def automaton_end_episode(tables, params, states, joints, rewards, length, counts) -> None:
    """The stand-in's learning from one episode (:func:`automaton_backward`, on the
    tables' arrays unpacked once)."""
    probs, legal, r_max = tables
    automaton_backward(probs, legal, r_max, params, states, joints, rewards, length, counts)


@dataclass(frozen=True)
class AutomatonConfig(TabularConfig):
    """LA-OCA stand-in."""

    name: ClassVar[str] = "la-oca"
    display_name: ClassVar[str] = "LA-OCA"
    kernels: ClassVar[TabularKernels] = TabularKernels(
        automaton_init,
        sample_from_strategies,
        automaton_greedy,
        no_step_update,
        automaton_end_episode,
    )

    rate: float = 0.1
    """λ of the linear reward-inaction update, in (0, 1)."""
    gamma: float = 0.9
    """Discount of eq. (1), in [0, 1] (0: each step's own reward)."""
    tolerance: float = 1e-9
    """[choice] Absolute tolerance under which two returns count as equal."""

    def __post_init__(self) -> None:
        require(0 < self.rate < 1, "rate", f"must be in (0, 1) (got {self.rate})")
        check_gamma_tolerance(self.gamma, self.tolerance)

    def params(self) -> AutomatonParams:
        return AutomatonParams(self.rate, self.gamma, self.tolerance)

    def new_tables(self, n_states: int, counts: np.ndarray) -> AutomatonTables:
        shape = (n_states, counts.shape[0], int(counts.max()))
        return AutomatonTables(
            np.zeros(shape), np.zeros(shape, dtype=np.bool_), np.full(n_states, -np.inf)
        )


class LAOCA(MaxReturnLearner):
    """The LA-OCA stand-in, step by step (see
    :class:`cmarlcd.learners.tabular.protocol.TabularLearner`)."""

    default_config = AutomatonConfig()
