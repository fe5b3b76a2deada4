"""Distributed Q-learning (Lauer & Riedmiller, 2000): optimistic independent learners
for deterministic cooperative games.

Each agent keeps the best reward ever received with each of its actions, and changes
its policy only when that best improves:

* ``q_i(a_i) ← max(q_i(a_i), r)`` (in a repeated game the update's ``γ max q(s')``
  term is absent);
* ``π_i ← a_i`` only when the update raised ``max_a q_i(a)``.

In stochastic games the target is ``r + γ max_a q_i(s', a)``, per state.

In a deterministic game this finds an optimal joint action once it has been played;
with stochastic payoffs its optimism is fooled by a lucky draw.

[choice] ``q = −∞`` at the start (the paper assumes non-negative rewards and 0; −∞ keeps
the rule's meaning, "the best reward seen", for games with negative payoffs), and no
policy until the first reward. [choice] The paper leaves exploration open: ε-greedy
around the policy, ``ε = 0.1``, uniform while an agent has no policy yet.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, NamedTuple

import numpy as np

from cmarlcd.compiled import kernel
from cmarlcd.errors import check_discount
from cmarlcd.learners.policy import greedy_action, uniform_legal_action
from cmarlcd.learners.tabular.independent import (
    ClassicLearner,
    best_value,
    check_unit,
    no_stopping_rule,
    real_actions,
)
from cmarlcd.learners.tabular.protocol import (
    RepeatedKernels,
    TabularConfig,
    TabularKernels,
    no_episode_update,
)


class OptimisticTables(NamedTuple):
    values: np.ndarray
    """``q_i(a)``: the best reward seen with each action, shape (n_agents, width)."""
    legal: np.ndarray
    """Real (not padding) actions, same shape."""
    policy: np.ndarray
    """``π_i``, shape (n_agents,); -1 before the first reward."""


class DistributedQParams(NamedTuple):
    epsilon: float


@kernel
def epsilon_policy_act(tables, params, counts, rng, joint) -> None:
    """Each agent: with probability ε (or while it has no policy) a uniform action, else
    its policy's action (one or two uniforms each, in agent order)."""
    for i in range(counts.shape[0]):
        explore = rng.random() < params.epsilon
        if explore or tables.policy[i] < 0:
            joint[i] = int(rng.random() * counts[i])
        else:
            joint[i] = tables.policy[i]


@kernel
def distributed_learn(tables, params, counts, joint, reward: float) -> bool:
    """``q_i(a_i) ← max(q_i(a_i), r)``; ``π_i ← a_i`` if that raised ``max q_i``.
    True when a policy changed."""
    changed = False
    for i in range(counts.shape[0]):
        a = joint[i]
        best = -np.inf
        for b in range(counts[i]):
            best = max(best, tables.values[i, b])
        if reward > tables.values[i, a]:
            tables.values[i, a] = reward
            if reward > best:
                tables.policy[i] = a
                changed = True
    return changed


@kernel
def policy_greedy(tables, counts, joint) -> None:
    """Execution: each agent's policy (action 0 before its first reward)."""
    for i in range(counts.shape[0]):
        joint[i] = max(tables.policy[i], 0)


@dataclass(frozen=True)
class DistributedQConfig(ClassicLearner):
    """Distributed Q-learners in repeated games (Lauer & Riedmiller, 2000)."""

    name: ClassVar[str] = "distributed-q"
    display_name: ClassVar[str] = "Distributed Q"
    citation: ClassVar[str] = (
        "Lauer & Riedmiller (2000), An algorithm for distributed reinforcement learning in "
        "cooperative multi-agent systems, ICML"
    )
    kernels: ClassVar[RepeatedKernels] = RepeatedKernels(
        epsilon_policy_act, distributed_learn, no_stopping_rule, policy_greedy
    )

    epsilon: float = 0.1
    """[choice] Exploration: probability of a uniform action, in (0, 1]."""

    def __post_init__(self) -> None:
        check_unit(epsilon=self.epsilon)

    def params(self) -> DistributedQParams:
        return DistributedQParams(self.epsilon)

    def new_tables(self, counts: np.ndarray) -> OptimisticTables:
        legal = real_actions(counts)
        values = np.full(legal.shape, -np.inf)
        return OptimisticTables(values, legal, np.full(counts.shape[0], -1, dtype=np.int64))


# ------------------------------------------------------------ stochastic games


class StateOptimisticTables(NamedTuple):
    values: np.ndarray
    """``q_i(s, a)``, shape (n_states, n_agents, width); -inf until a target reaches it."""
    legal: np.ndarray
    """Legal actions of each state, as first seen, same shape."""
    policy: np.ndarray
    """``π_i(s)``, shape (n_states, n_agents); -1 before the first update."""


class StateDistributedQParams(NamedTuple):
    epsilon: float
    gamma: float


@kernel
def distributed_init(tables, params, s, legal, counts) -> None:
    """A state before any update: ``q = −∞`` and no policy."""
    for i in range(counts.shape[0]):
        tables.policy[s, i] = -1
        for a in range(legal.shape[1]):
            tables.legal[s, i, a] = legal[i, a]
            tables.values[s, i, a] = -np.inf


@kernel
def distributed_state_act(tables, params, s, counts, rng, joint) -> None:
    """ε-greedy around ``π_i(s)``, uniform over the legal actions while it is unset."""
    for i in range(counts.shape[0]):
        explore = rng.random() < params.epsilon
        if explore or tables.policy[s, i] < 0:
            joint[i] = uniform_legal_action(tables.legal[s, i], counts[i], rng.random())
        else:
            joint[i] = tables.policy[s, i]


@kernel
def distributed_observe(tables, params, states, joints, rewards, t, next_s, terminal) -> None:
    """``q_i(s, a_i) ← max(q_i(s, a_i), r + γ max_a q_i(s', a))``; ``π_i(s) ← a_i`` when
    that raised ``max_a q_i(s, a)``."""
    s = states[t]
    width = tables.legal.shape[2]
    for i in range(joints.shape[1]):
        a = joints[t, i]
        target = rewards[t]
        if not terminal:
            later = best_value(tables.values[next_s, i], tables.legal[next_s, i], width)
            target += params.gamma * later
        if target > tables.values[s, i, a]:
            best = best_value(tables.values[s, i], tables.legal[s, i], width)
            tables.values[s, i, a] = target
            if target > best:
                tables.policy[s, i] = a


@kernel
def distributed_state_greedy(tables, s, counts, joint) -> None:
    """Execution: ``π_i(s)`` (the lowest legal action before any update)."""
    for i in range(counts.shape[0]):
        chosen = tables.policy[s, i]
        if chosen < 0:
            chosen = greedy_action(tables.values[s, i], tables.legal[s, i], counts[i])
        joint[i] = chosen


@dataclass(frozen=True)
class DistributedQStochasticConfig(DistributedQConfig, TabularConfig):
    """Distributed Q-learners in stochastic games (Lauer & Riedmiller, 2000), whose
    optimality the paper proves for deterministic games only. [choice] ε-greedy, as in
    repeated games; ``γ = 0.9`` as the paper's DSN settings."""

    kernels: ClassVar[TabularKernels] = TabularKernels(  # type: ignore[assignment]
        distributed_init, distributed_state_act, distributed_state_greedy,
        distributed_observe, no_episode_update,
    )  # fmt: skip

    gamma: float = 0.9
    """Discount, in [0, 1] (0: each step's own reward)."""

    def __post_init__(self) -> None:
        super().__post_init__()
        check_discount(self.gamma)

    def params(self) -> StateDistributedQParams:  # type: ignore[override]
        return StateDistributedQParams(self.epsilon, self.gamma)

    def new_tables(self, n_states: int, counts: np.ndarray) -> StateOptimisticTables:  # type: ignore[override]
        shape = (n_states, counts.shape[0], int(counts.max()))
        return StateOptimisticTables(
            np.full(shape, -np.inf),
            np.zeros(shape, dtype=np.bool_),
            np.full(shape[:2], -1, dtype=np.int64),
        )
