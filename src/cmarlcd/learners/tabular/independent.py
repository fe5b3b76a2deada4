"""What the classic independent learners share: Boltzmann exploration on a schedule of
plays, greedy execution, no stopping rule, their tables and their object API.

The classic learners (:mod:`~.q_learning`, :mod:`~.distributed_q`, :mod:`~.hysteretic`,
:mod:`~.fmq`, :mod:`~.lenient`, :mod:`~.joint_action`) speak the repeated-game protocol
of :class:`cmarlcd.learners.tabular.protocol.RepeatedKernels`, as CMARL-CD's Algorithm 1 does;
their tables hold per agent a row of ``values`` (what the agent acts on and is greedy
over), the real actions (``legal``), a scratch row of probabilities and a count of the
games played. Unlike CMARL-CD they have no stopping rule: a run plays its budget.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar, NamedTuple

import numpy as np
from numba import njit

from cmarlcd.compiled import kernel
from cmarlcd.errors import require
from cmarlcd.learners.policy import greedy_action, sample_action, softmax_strategy
from cmarlcd.learners.tabular.protocol import RepeatedKernels

#: Kapetanakis & Kudenko (2002)'s Boltzmann schedule, ``T(t) = max_temp · e^(-s t) + 1``.
KK_MAX_TEMPERATURE = 500.0
KK_DECAY = 0.006


def check_positive(**values: float) -> None:
    """Every named value is a finite number > 0."""
    for name, value in values.items():
        require(bool(np.isfinite(value)) and value > 0, name, f"must be > 0 (got {value})")


def check_unit(**values: float) -> None:
    """Every named value lies in (0, 1]."""
    for name, value in values.items():
        require(
            bool(np.isfinite(value)) and 0 < value <= 1, name, f"must be in (0, 1] (got {value})"
        )


@njit(cache=True)
def kk_temperature(plays: int, max_temperature: float, decay: float) -> float:
    """Kapetanakis & Kudenko (2002): ``T(t) = max_temp · e^(-s t) + 1`` after ``t`` plays."""
    return max_temperature * math.exp(-decay * plays) + 1.0


@njit(cache=True)
def boltzmann_joint(values, legal, probs, counts, temperature: float, rng, joint) -> None:
    """Every agent draws from ``softmax(values_i / T)`` over its actions, one uniform
    each, in agent order (``probs`` is scratch)."""
    for i in range(counts.shape[0]):
        softmax_strategy(values[i], legal[i], counts[i], temperature, probs[i])
        joint[i] = sample_action(probs[i], counts[i], rng.random())


@kernel
def greedy_values(tables, counts, joint) -> None:
    """Each agent's action of largest value (lowest index on ties)."""
    for i in range(counts.shape[0]):
        joint[i] = greedy_action(tables.values[i], tables.legal[i], counts[i])


@kernel
def no_stopping_rule(tables, params, counts) -> bool:
    """The classic learners never declare convergence: a run plays its budget."""
    return False


class ValueTables(NamedTuple):
    """The tables of a value-based independent learner in a repeated game."""

    values: np.ndarray
    """``Q_i(a)``, shape (n_agents, width)."""
    legal: np.ndarray
    """Real (not padding) actions, same shape."""
    probs: np.ndarray
    """Scratch: the Boltzmann probabilities of the last draw, same shape."""
    plays: np.ndarray
    """One element: the games played so far."""


def real_actions(counts: np.ndarray) -> np.ndarray:
    """``(n_agents, width)`` masks of each agent's real actions."""
    return np.arange(int(counts.max()))[None, :] < counts[:, None]


def value_tables(counts: np.ndarray, initial: float = 0.0) -> ValueTables:
    """Values at ``initial`` for every agent's actions; no game played."""
    legal = real_actions(counts)
    values = np.where(legal, initial, 0.0)
    return ValueTables(values, legal, np.zeros(legal.shape), np.zeros(1, dtype=np.int64))


class RepeatedLearner:
    """Any repeated-game learner (a config with :class:`RepeatedKernels`), step by step:
    ``act`` samples a joint action, ``update`` learns from its reward, and
    ``greedy_joint_action`` is what the agents would play greedily. The compiled loops
    of :mod:`cmarlcd.training.repeated` call the same functions on the same tables.

    Example:
        >>> from cmarlcd.learners.tabular.hysteretic import HystereticConfig
        >>> learner = RepeatedLearner(HystereticConfig(), [3, 3], seed=0)
        >>> joint = learner.act()
        >>> learner.update(joint, reward=1.0)
        True
    """

    def __init__(
        self,
        config: Any,
        action_counts: Sequence[int],
        seed: int | np.random.SeedSequence | np.random.Generator | None = None,
    ) -> None:
        counts = [int(k) for k in action_counts]
        require(len(counts) >= 2, "agents", f"must be >= 2 (got {len(counts)})")
        require(min(counts) >= 2, "actions", f"every agent needs >= 2 actions (got {counts})")
        self.config = config
        self.kernels: RepeatedKernels = config.kernels
        self.params = config.params()
        self.counts = np.array(counts, dtype=np.int64)
        self.rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        self.tables = config.new_tables(self.counts)

    @property
    def n_agents(self) -> int:
        return int(self.counts.shape[0])

    def act(self) -> tuple[int, ...]:
        """Sample a joint action (each agent by its exploration rule)."""
        joint = np.zeros(self.n_agents, dtype=np.int64)
        self.kernels.act(self.tables, self.params, self.counts, self.rng, joint)
        return tuple(int(a) for a in joint)

    def update(self, joint_action: Sequence[int], reward: float) -> bool:
        """Learn from one game; True when anything the agents act on changed."""
        joint = np.asarray(joint_action, dtype=np.int64)
        require(joint.shape == (self.n_agents,), "joint_action", f"needs {self.n_agents} actions")
        ok = bool(((joint >= 0) & (joint < self.counts)).all())
        require(ok, "joint_action", f"actions must lie in [0, counts) = {tuple(self.counts)}")
        require(bool(np.isfinite(reward)), "reward", f"must be finite (got {reward})")
        return bool(self.kernels.learn(self.tables, self.params, self.counts, joint, float(reward)))

    def greedy_joint_action(self) -> tuple[int, ...]:
        """What the agents would play greedily now."""
        joint = np.zeros(self.n_agents, dtype=np.int64)
        self.kernels.greedy(self.tables, self.counts, joint)
        return tuple(int(a) for a in joint)


@dataclass(frozen=True)
class BoltzmannSchedule:
    """The settings of Kapetanakis & Kudenko's Boltzmann schedule,
    ``T(t) = max_temperature · e^(-decay t) + 1`` after ``t`` plays (in stochastic games,
    visits of the state)."""

    max_temperature: float = KK_MAX_TEMPERATURE
    """See the class docstring, > 0."""
    decay: float = KK_DECAY
    """See the class docstring, > 0."""

    def __post_init__(self) -> None:
        check_positive(max_temperature=self.max_temperature, decay=self.decay)


class ClassicLearner:
    """Class-level description every classic learner's config carries."""

    name: ClassVar[str]
    display_name: ClassVar[str]
    citation: ClassVar[str]
    """The paper the rule comes from."""
    kernels: ClassVar[RepeatedKernels]


# ------------------------------------------------------------ stochastic games


class StateValueTables(NamedTuple):
    """The tables of a value-based independent learner in a stochastic game, per state
    index ``s`` (leading axis) and agent ``i``."""

    values: np.ndarray
    """``Q_i(s, a)``, shape (n_states, n_agents, width)."""
    legal: np.ndarray
    """Legal actions of each state, as first seen, same shape."""
    probs: np.ndarray
    """Scratch: the Boltzmann probabilities of the last draw in each state, same shape."""
    visits: np.ndarray
    """How often each state was acted in, shape (n_states,)."""


def state_value_tables(n_states: int, counts: np.ndarray) -> StateValueTables:
    shape = (n_states, counts.shape[0], int(counts.max()))
    return StateValueTables(
        np.zeros(shape),
        np.zeros(shape, dtype=np.bool_),
        np.zeros(shape),
        np.zeros(n_states, dtype=np.int64),
    )


@njit(cache=True)
def copy_legal(tables, s: int, legal, counts) -> None:
    """Record state ``s``'s legal actions; no visit yet."""
    for i in range(counts.shape[0]):
        for a in range(legal.shape[1]):
            tables.legal[s, i, a] = legal[i, a]
    tables.visits[s] = 0


@kernel
def init_state_values(tables, params, s, legal, counts) -> None:
    """Protocol ``init_state``: ``Q = params.initial_value`` over the legal actions."""
    copy_legal(tables, s, legal, counts)
    for i in range(counts.shape[0]):
        for a in range(legal.shape[1]):
            tables.values[s, i, a] = params.initial_value if legal[i, a] else 0.0


@kernel
def greedy_state_values(tables, s, counts, joint) -> None:
    """Protocol ``greedy``: each agent's legal action of largest ``Q_i(s, ·)``."""
    for i in range(counts.shape[0]):
        joint[i] = greedy_action(tables.values[s, i], tables.legal[s, i], counts[i])


@kernel
def boltzmann_state_act(tables, params, s, counts, rng, joint) -> None:
    """Protocol ``act``: Boltzmann over ``Q_i(s, ·)`` at Kapetanakis & Kudenko's
    temperature of the state's visits so far (the repeated-game schedule, per state)."""
    temperature = kk_temperature(tables.visits[s], params.max_temperature, params.decay)
    tables.visits[s] += 1
    boltzmann_joint(
        tables.values[s], tables.legal[s], tables.probs[s], counts, temperature, rng, joint
    )


@njit(cache=True)
def best_value(values_row, legal_row, count: int) -> float:
    """``max_a Q(s', a)`` over the legal actions."""
    best = -np.inf
    for a in range(count):
        if legal_row[a]:
            best = max(best, values_row[a])
    return best


@njit(cache=True)
def td_target(tables, params, i: int, reward: float, next_s: int, terminal: bool, count) -> float:
    """``r + γ max_a Q_i(s', a)``, or ``r`` when ``s'`` is terminal."""
    if terminal:
        return reward
    return reward + params.gamma * best_value(
        tables.values[next_s, i], tables.legal[next_s, i], count
    )
