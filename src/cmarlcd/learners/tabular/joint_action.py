"""Joint-action learners, JAL (Claus & Boutilier, 1998), and the centralised reference
:class:`CentralQConfig`, for games whose joint action space is small.

Every agent observes the joint action and learns its value, ``Q(a) ← Q(a) + α (r − Q(a))``
for the joint action ``a`` played, and counts how often each other agent played each of
its actions. It acts by Boltzmann over the expected value of its own actions against
those empirical frequencies:

    ``EV_i(a_i) = Σ_{a_-i} Q(a_i, a_-i) Π_{j≠i} Pr_j(a_j)``.

All agents see the same history, so their joint-action values and counts are equal: the
tables hold them once. Each game costs ``O(n |A|)`` (``|A|`` joint actions), so the
learner refuses games of more than :data:`MAX_JOINT_ACTIONS`.

[choice] The counts start at 1 (a uniform prior; the paper leaves it open), ``Q = 0``,
``α = 0.1``, and the Boltzmann schedule is Kapetanakis & Kudenko's
``T(t) = 500 e^(-0.006 t) + 1``, as for the independent learners here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar, NamedTuple

import numpy as np
from numba import njit

from cmarlcd.compiled import kernel
from cmarlcd.errors import require
from cmarlcd.learners.tabular.independent import (
    ClassicLearner,
    greedy_values,
    kk_temperature,
    no_stopping_rule,
    real_actions,
)
from cmarlcd.learners.tabular.protocol import RepeatedKernels
from cmarlcd.learners.tabular.q_learning import BoltzmannQSettings, boltzmann_act, q_update

#: [choice] The largest joint action space a JAL plays (the Q table and every game's
#: expected values scale with it).
MAX_JOINT_ACTIONS = 1_024


def joint_action_count(counts: np.ndarray, learner: str) -> int:
    """``|A|``, refused above :data:`MAX_JOINT_ACTIONS`."""
    size = math.prod(int(k) for k in counts)
    require(
        size <= MAX_JOINT_ACTIONS,
        "agents",
        f"{learner} plays games of at most {MAX_JOINT_ACTIONS:,} joint actions (got {size:,})",
    )
    return size


class JointActionTables(NamedTuple):
    values: np.ndarray
    """``EV_i(a)``, what the agents act on, shape (n_agents, width)."""
    legal: np.ndarray
    probs: np.ndarray
    plays: np.ndarray
    q: np.ndarray
    """``Q(a)`` per joint action, flattened in C order, shape (|A|,)."""
    seen: np.ndarray
    """How often each agent played each action (from 1), shape (n_agents, width)."""
    strides: np.ndarray
    """C-order strides of the flattened joint actions, shape (n_agents,)."""


@njit(cache=True)
def expected_values(q, seen, counts, values) -> None:
    """``values[i, a] := EV_i(a)`` against the empirical frequencies ``seen``: one pass
    over the joint actions, each adding ``Q(a) Π_{j≠i} Pr_j(a_j)`` to every agent."""
    n_agents = counts.shape[0]
    for i in range(n_agents):
        values[i, : counts[i]] = 0.0
    totals = np.zeros(n_agents)
    for i in range(n_agents):
        totals[i] = seen[i, : counts[i]].sum()
    digits = np.zeros(n_agents, dtype=np.int64)
    for flat in range(q.shape[0]):
        remainder = flat
        product = 1.0
        for i in range(n_agents - 1, -1, -1):
            digits[i] = remainder % counts[i]
            remainder //= counts[i]
            product *= seen[i, digits[i]] / totals[i]
        for i in range(n_agents):
            own = seen[i, digits[i]] / totals[i]
            values[i, digits[i]] += q[flat] * product / own


@kernel
def jal_learn(tables, params, counts, joint, reward: float) -> bool:
    """The joint action's value steps towards ``r``, the counts grow, ``EV`` follows."""
    tables.plays[0] += 1
    flat = 0
    for i in range(counts.shape[0]):
        flat += joint[i] * tables.strides[i]
        tables.seen[i, joint[i]] += 1.0
    tables.q[flat] = q_update(tables.q[flat], reward, params.alpha)
    return True


@njit(cache=True)
def jal_learn_and_evaluate(tables, params, counts, joint, reward: float) -> bool:
    """:func:`jal_learn`, then every agent's expected values (this allocates, so it is
    compiled with reference counting, unlike a kernel)."""
    jal_learn(tables, params, counts, joint, reward)
    expected_values(tables.q, tables.seen, counts, tables.values)
    return True


@dataclass(frozen=True)
class JointActionConfig(BoltzmannQSettings, ClassicLearner):
    """Joint-action learners in repeated games (Claus & Boutilier, 1998)."""

    name: ClassVar[str] = "jal"
    display_name: ClassVar[str] = "JAL"
    citation: ClassVar[str] = (
        "Claus & Boutilier (1998), The dynamics of reinforcement learning in cooperative "
        "multiagent systems, AAAI"
    )
    kernels: ClassVar[RepeatedKernels] = RepeatedKernels(
        boltzmann_act, jal_learn_and_evaluate, no_stopping_rule, greedy_values
    )

    def new_tables(self, counts: np.ndarray) -> JointActionTables:
        size = joint_action_count(counts, "JAL")
        legal = real_actions(counts)
        strides = np.array(
            [math.prod(int(k) for k in counts[i + 1 :]) for i in range(counts.shape[0])],
            dtype=np.int64,
        )
        seen = np.where(legal, 1.0, 0.0)
        values = np.zeros(legal.shape)
        q = np.zeros(size)
        expected_values(q, seen, counts, values)
        return JointActionTables(
            values, legal, np.zeros(legal.shape), np.zeros(1, dtype=np.int64), q, seen, strides
        )


# ------------------------------------------------- the centralised reference


class CentralTables(NamedTuple):
    values: np.ndarray
    """``Q(a)`` per joint action, flattened in C order, shape (|A|,)."""
    probs: np.ndarray
    """Scratch: the Boltzmann probabilities of the last draw, same shape."""
    plays: np.ndarray
    """One element: the games played so far."""


@kernel
def central_act(tables, params, counts, rng, joint) -> None:
    """One Boltzmann draw over the joint actions, ``softmax(Q / T(t))``, decoded into
    every agent's action (the agents act as one)."""
    temperature = kk_temperature(tables.plays[0], params.max_temperature, params.decay)
    q, p = tables.values, tables.probs
    top = q[largest(q)]
    total = 0.0
    for flat in range(q.shape[0]):
        p[flat] = math.exp((q[flat] - top) / temperature)
        total += p[flat]
    u, flat = rng.random() * total, q.shape[0] - 1
    for k in range(q.shape[0]):
        u -= p[k]
        if u < 0.0:
            flat = k
            break
    decode(flat, counts, joint)


@njit(cache=True)
def largest(values) -> int:
    """The position of the largest value (the first on ties)."""
    best = 0
    for k in range(1, values.shape[0]):
        if values[k] > values[best]:
            best = k
    return best


@njit(cache=True)
def decode(flat: int, counts, joint) -> None:
    """The joint action at position ``flat`` of the C-order flattening."""
    for i in range(counts.shape[0] - 1, -1, -1):
        joint[i] = flat % counts[i]
        flat //= counts[i]


@kernel
def central_learn(tables, params, counts, joint, reward: float) -> bool:
    """``Q(a) ← Q(a) + α (r − Q(a))`` for the joint action played."""
    tables.plays[0] += 1
    flat = 0
    for i in range(counts.shape[0]):
        flat = flat * counts[i] + joint[i]
    tables.values[flat] = q_update(tables.values[flat], reward, params.alpha)
    return True


@kernel
def central_greedy(tables, counts, joint) -> None:
    """The joint action of largest ``Q`` (the first in C order on ties)."""
    decode(largest(tables.values), counts, joint)


@dataclass(frozen=True)
class CentralQConfig(BoltzmannQSettings, ClassicLearner):
    """One Q-learner over the joint actions, whose choice every agent plays: the
    coordinated reference (what independent learners could reach if they acted as one).

    [choice] Not from a paper of its own: Q-learning over joint actions (as JAL's values,
    Claus & Boutilier 1998) with the agents' choice made centrally, ``α = 0.1``,
    Kapetanakis & Kudenko's Boltzmann schedule over the joint actions. Its tables and
    every game scale with ``|A|``: at most :data:`MAX_JOINT_ACTIONS`.
    """

    name: ClassVar[str] = "central-q"
    display_name: ClassVar[str] = "Central Q"
    citation: ClassVar[str] = (
        "Q-learning over joint actions, acting as one (the coordinated reference; cf. "
        "Claus & Boutilier 1998)"
    )
    kernels: ClassVar[RepeatedKernels] = RepeatedKernels(
        central_act, central_learn, no_stopping_rule, central_greedy
    )

    def new_tables(self, counts: np.ndarray) -> CentralTables:
        size = joint_action_count(counts, "Central Q")
        return CentralTables(np.zeros(size), np.zeros(size), np.zeros(1, dtype=np.int64))
