"""CMARL-CD: learning by the coordination degree (Section IV, Algorithms 1 and 2).

Each agent ``i`` keeps a coordination degree ``c_i[a]`` per action and plays the
Boltzmann strategy ``p_i = softmax(c_i / T)`` (eq. 5). After every game the global
reward ``r`` is compared with the largest reward seen so far, ``r_max``; when
``r >= r_max`` (eq. 4) the selected action's degree rises by ``delta`` and every other
action's degree falls by ``delta`` (eqs. 2-3). Every agent observes the same global
reward, so the per-agent maxima ``r_i_max`` of Algorithm 1 are always equal; they are
kept as one shared value.

For stochastic games (Algorithm 2) the same rules apply per state, driven by the
max-return indicator of :mod:`cmarlcd.learners.max_return` (eqs. 14-17).

This file is the whole learner but its rules: its configs (:class:`RepeatedConfig`,
:class:`StochasticConfig`), its tables, its compiled functions and its object APIs
(:class:`CMARLCD`, :class:`CMARLCDStochastic`); the rules both algorithms (and deep
CMARL-CD) share, written once over plain arrays, are :mod:`~.degree_rules`'s.
Agents may have different action counts: per-agent rows are padded to the largest count
and ``counts[i]`` says how many entries of row ``i`` are real.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar, NamedTuple

import numpy as np
from numba import njit

from cmarlcd.compiled import kernel
from cmarlcd.errors import require
from cmarlcd.learners.degree_rules import (
    check_degree_settings,
    degree_step,
    is_pure,
    reinforce,
)
from cmarlcd.learners.max_return import (
    BELOW,
    RECORD,
    check_gamma_tolerance,
    visit,
)
from cmarlcd.learners.policy import (
    greedy_action,
    sample_from_strategies,
    sample_joint_action,
    softmax_strategy,
)
from cmarlcd.learners.tabular.protocol import (
    MaxReturnLearner,
    RepeatedKernels,
    TabularConfig,
    TabularKernels,
    no_step_update,
)
from cmarlcd.limits import MAX_GAMES, check_at_most

# ------------------------------------------------------- Algorithm 1: repeated games


class RepeatedTables(NamedTuple):
    """Algorithm 1's state: per agent, degrees, strategy and legal actions; and r_max."""

    degrees: np.ndarray
    """``c_i[a]``, shape (n_agents, width)."""
    probs: np.ndarray
    """``p_i[a]`` of eq. (5), same shape."""
    legal: np.ndarray
    """Real (not padding) actions, same shape."""
    r_max: np.ndarray
    """One element: the largest reward seen so far (``-inf`` before any game)."""


class RepeatedParams(NamedTuple):
    """Algorithm 1's parameters, as the compiled functions read them."""

    delta: float
    temperature: float
    purity_threshold: float


@njit(cache=True)
def repeated_update(
    c: np.ndarray,
    p: np.ndarray,
    legal: np.ndarray,
    counts: np.ndarray,
    joint: np.ndarray,
    reward: float,
    r_max: np.ndarray,
    delta: float,
    temperature: float,
) -> bool:
    """Algorithm 1, lines 6-12, for every agent at once; returns the indicator of eq. (4).

    ``r_max`` is a one-element array (mutable in compiled code) holding the largest
    reward seen so far.
    """
    if reward < r_max[0]:  # eq. (4): I = 0, nothing changes
        return False
    r_max[0] = reward
    for i in range(counts.shape[0]):
        reinforce(c[i], counts[i], joint[i], delta)
        softmax_strategy(c[i], legal[i], counts[i], temperature, p[i])
    return True


@kernel
def repeated_act(tables, params, counts: np.ndarray, rng, joint: np.ndarray) -> None:
    """Every agent samples ``a_i ~ p_i`` (Algorithm 1, line 4)."""
    sample_joint_action(tables.probs, counts, rng, joint)


@kernel
def repeated_learn(tables, params, counts: np.ndarray, joint: np.ndarray, reward: float) -> bool:
    """Eqs. (2)-(5) after one game; True when the indicator of eq. (4) fired.

    The indicator is read first: most games change nothing, and they then touch only
    ``r_max``."""
    if reward < tables.r_max[0]:  # eq. (4): I = 0
        return False
    return repeated_update(
        tables.degrees,
        tables.probs,
        tables.legal,
        counts,
        joint,
        reward,
        tables.r_max,
        params.delta,
        params.temperature,
    )


@kernel
def repeated_converged(tables, params, counts: np.ndarray) -> bool:
    """Algorithm 1's stopping rule: every strategy is pure."""
    return is_pure(tables.probs, counts, params.purity_threshold)


@kernel
def repeated_greedy(tables, counts: np.ndarray, joint: np.ndarray) -> None:
    """Each agent's action with the largest coordination degree (lowest index on ties)."""
    for i in range(counts.shape[0]):
        joint[i] = greedy_action(tables.degrees[i], tables.legal[i], counts[i])


@dataclass(frozen=True)
class RepeatedConfig:
    """Hyper-parameters of CMARL-CD for repeated games (Section IV-C settings)."""

    name: ClassVar[str] = "cmarl-cd"
    display_name: ClassVar[str] = "CMARL-CD"
    kernels: ClassVar[RepeatedKernels] = RepeatedKernels(
        repeated_act, repeated_learn, repeated_converged, repeated_greedy
    )

    temperature: float = 1.0
    """T of eq. (5), > 0."""
    delta: float = 0.04
    """Learning rate of eqs. (2)-(3), in (0, 1)."""
    purity_threshold: float = 0.999
    """Stop when every agent has an action with probability above this, in (0, 1)."""
    max_games: int = 10_000_000
    """[choice] Cap on games per run; a run that hits it ends unconverged (a failure)."""
    initial_degree: float = 0.0
    """[choice] Initial coordination degree of every action (any constant is equivalent)."""

    def __post_init__(self) -> None:
        t, d = self.temperature, self.delta
        require(bool(np.isfinite(t)) and t > 0, "temperature", f"must be > 0 (got {t})")
        require(bool(np.isfinite(d)) and 0 < d < 1, "delta", f"must be in (0, 1) (got {d})")
        th = self.purity_threshold
        require(0 < th < 1, "purity_threshold", f"must be in (0, 1) (got {th})")
        require(self.max_games >= 1, "max_games", f"must be >= 1 (got {self.max_games})")
        check_at_most(self.max_games, MAX_GAMES, "max_games")
        init = self.initial_degree
        require(bool(np.isfinite(init)), "initial_degree", f"must be finite (got {init})")

    def params(self) -> RepeatedParams:
        return RepeatedParams(self.delta, self.temperature, self.purity_threshold)

    def new_tables(self, counts: np.ndarray) -> RepeatedTables:
        """Degrees at ``initial_degree`` and the uniform strategy of eq. (5)."""
        width = int(counts.max())
        degrees = np.full((counts.shape[0], width), self.initial_degree)
        legal = np.arange(width)[None, :] < counts[:, None]
        probs = np.zeros_like(degrees)
        for i in range(counts.shape[0]):
            softmax_strategy(degrees[i], legal[i], counts[i], self.temperature, probs[i])
        return RepeatedTables(degrees, probs, legal, np.array([-np.inf]))


class CMARLCD:
    """CMARL-CD learners for an n-agent repeated game (Algorithm 1), step by step.

    ``act`` samples a joint action, ``update`` learns from its reward (eqs. 2-5);
    :func:`cmarlcd.training.fit` plays a whole run with the compiled loop on the same
    tables and random stream.

    Example:
        >>> from cmarlcd import CMARLCD, fit, games
        >>> game = games.climbing_game()
        >>> learner = CMARLCD(game.action_counts, seed=0)
        >>> fit(learner, game).success
        True
    """

    def __init__(
        self,
        action_counts: Sequence[int],
        config: RepeatedConfig | None = None,
        seed: int | np.random.SeedSequence | np.random.Generator | None = None,
    ) -> None:
        counts = [int(k) for k in action_counts]
        require(len(counts) >= 2, "agents", f"must be >= 2 (got {len(counts)})")
        require(min(counts) >= 2, "actions", f"every agent needs >= 2 actions (got {counts})")
        self.config = config or RepeatedConfig()
        self.params = self.config.params()
        self.counts = np.array(counts, dtype=np.int64)
        self.rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        self.tables = self.config.new_tables(self.counts)

    @property
    def n_agents(self) -> int:
        return int(self.counts.shape[0])

    @property
    def degrees(self) -> np.ndarray:
        """The coordination degrees ``c_i[a]`` (rows padded to the widest agent)."""
        return self.tables.degrees

    @property
    def strategies(self) -> np.ndarray:
        """The strategies ``p_i[a]`` of eq. (5)."""
        return self.tables.probs

    @property
    def max_reward(self) -> float:
        """``r_max``: the largest global reward seen so far (``-inf`` before any game)."""
        return float(self.tables.r_max[0])

    def act(self) -> tuple[int, ...]:
        """Sample a joint action from the current strategies."""
        joint = np.zeros(self.n_agents, dtype=np.int64)
        repeated_act(self.tables, self.params, self.counts, self.rng, joint)
        return tuple(int(a) for a in joint)

    def update(self, joint_action: Sequence[int], reward: float) -> bool:
        """Learn from one game; returns True when the indicator of eq. (4) fired."""
        joint = self._check_joint(joint_action)
        require(bool(np.isfinite(reward)), "reward", f"must be finite (got {reward})")
        return bool(repeated_learn(self.tables, self.params, self.counts, joint, float(reward)))

    def is_pure(self) -> bool:
        """The paper's stopping rule (every agent has an action above the threshold)."""
        return bool(repeated_converged(self.tables, self.params, self.counts))

    def greedy_joint_action(self) -> tuple[int, ...]:
        """Each agent's action with the largest coordination degree."""
        joint = np.zeros(self.n_agents, dtype=np.int64)
        repeated_greedy(self.tables, self.counts, joint)
        return tuple(int(a) for a in joint)

    def strategy(self, agent: int) -> np.ndarray:
        """Agent ``agent``'s current strategy ``p_i`` (a copy)."""
        return self.tables.probs[agent, : self.counts[agent]].copy()

    def _check_joint(self, joint_action: Sequence[int]) -> np.ndarray:
        joint = np.asarray(joint_action, dtype=np.int64)
        require(
            joint.shape == (self.n_agents,),
            "joint_action",
            f"needs one action per agent ({self.n_agents}), got shape {joint.shape}",
        )
        ok = bool(((joint >= 0) & (joint < self.counts)).all())
        require(ok, "joint_action", f"actions must lie in [0, counts) = {tuple(self.counts)}")
        return joint


# --------------------------------------------------- Algorithm 2: stochastic games


class DegreeTables(NamedTuple):
    """Algorithm 2's state, per state index ``s`` (leading axis) and agent ``i``."""

    degrees: np.ndarray
    """``c_i(s, a)``, shape (n_states, n_agents, width)."""
    probs: np.ndarray
    """``p_i(s, a)`` of eq. (17), same shape."""
    legal: np.ndarray
    """Legal actions of each state, as first seen, same shape."""
    r_max: np.ndarray
    """``R_max(s)``: the best discounted return seen from ``s``, shape (n_states,)."""


class CoordinationParams(NamedTuple):
    """Algorithm 2's parameters, as the compiled functions read them."""

    delta: float
    delta_reset: float
    temperature: float
    c_min: float
    c_max: float
    c_init: float
    gamma: float
    tolerance: float


@njit(cache=True)
def coordination_rule(
    c_row: np.ndarray,
    p_row: np.ndarray,
    legal_row: np.ndarray,
    count: int,
    action: int,
    new_record: bool,
    params,
) -> None:
    """Algorithm 2, lines 16-19, for one agent at one visited state (eqs. 14-17).

    On a new record of the return from this state the degrees are first reset to
    ``c_init`` and the large step ``delta_reset`` is used (the paper's "exploration near
    local optima" rule, Section V-A); on a tie the step is ``delta``. Then the degrees are
    clipped to ``[c_min, c_max]`` and the strategy recomputed by eq. (17).
    """
    degree_step(c_row, count, action, new_record, params)
    softmax_strategy(c_row, legal_row, count, params.temperature, p_row)


@kernel
def coordination_init(tables, params, s, legal, counts) -> None:
    """A state before any update: ``c = c_init``, ``p`` uniform over the legal actions."""
    tables.r_max[s] = -np.inf
    for i in range(counts.shape[0]):
        for a in range(legal.shape[1]):
            tables.legal[s, i, a] = legal[i, a]
        tables.degrees[s, i, : counts[i]] = params.c_init
        softmax_strategy(
            tables.degrees[s, i],
            tables.legal[s, i],
            counts[i],
            params.temperature,
            tables.probs[s, i],
        )


@kernel
def coordination_greedy(tables, s, counts, joint) -> None:
    """Execution: each agent's legal action with the largest degree (lowest index on ties)."""
    for i in range(counts.shape[0]):
        joint[i] = greedy_action(tables.degrees[s, i], tables.legal[s, i], counts[i])


@njit(cache=True)
def coordination_backward(
    degrees, probs, legal, r_max, params, states, joints, rewards, length, counts
) -> None:
    """Algorithm 2, lines 13-22, over the tables' arrays: the max-return pass, then
    :func:`coordination_rule` for every agent at every visit that reached its state's
    record, backwards."""
    g = 0.0
    for t in range(length - 1, -1, -1):
        g, outcome = visit(r_max, params, states[t], rewards[t], g)
        if outcome == BELOW:
            continue
        s = states[t]
        for i in range(counts.shape[0]):
            record = outcome == RECORD
            coordination_rule(
                degrees[s, i], probs[s, i], legal[s, i], counts[i], joints[t, i], record, params
            )


@kernel
def coordination_end_episode(tables, params, states, joints, rewards, length, counts) -> None:
    """Algorithm 2's learning from one episode (:func:`coordination_backward`, on the
    tables' arrays unpacked once)."""
    degrees, probs, legal, r_max = tables
    coordination_backward(
        degrees, probs, legal, r_max, params, states, joints, rewards, length, counts
    )


@dataclass(frozen=True)
class StochasticConfig(TabularConfig):
    """CMARL-CD for stochastic games (Algorithm 2); defaults are the paper's DSN settings."""

    name: ClassVar[str] = "cmarl-cd"
    display_name: ClassVar[str] = "CMARL-CD"
    kernels: ClassVar[TabularKernels] = TabularKernels(
        coordination_init,
        sample_from_strategies,
        coordination_greedy,
        no_step_update,
        coordination_end_episode,
    )

    delta: float = 0.05
    """Step of eqs. (14)-(15) when a return ties the record, > 0."""
    delta_reset: float = 0.5
    """Step used right after a new record resets the degrees to ``c_init`` (Section V-A)."""
    temperature: float = 1.0
    """T of eq. (17), > 0."""
    c_min: float = 0.5
    """Lower clip of the coordination degrees (positive, Section IV-D)."""
    c_max: float = 3.0
    """Upper clip of the coordination degrees."""
    c_init: float = 1.5
    """Initial degree, and the value a new record resets a state's degrees to."""
    gamma: float = 0.9
    """Discount of eq. (1), in [0, 1] (0: each step's own reward)."""
    tolerance: float = 1e-9
    """[choice] Absolute tolerance under which two returns count as equal."""

    def __post_init__(self) -> None:
        check_degree_settings(self)
        check_gamma_tolerance(self.gamma, self.tolerance)

    def params(self) -> CoordinationParams:
        return CoordinationParams(
            self.delta,
            self.delta_reset,
            self.temperature,
            self.c_min,
            self.c_max,
            self.c_init,
            self.gamma,
            self.tolerance,
        )

    def new_tables(self, n_states: int, counts: np.ndarray) -> DegreeTables:
        shape = (n_states, counts.shape[0], int(counts.max()))
        return DegreeTables(
            np.zeros(shape),
            np.zeros(shape),
            np.zeros(shape, dtype=np.bool_),
            np.full(n_states, -np.inf),
        )


#: The paper's battlefield settings (Section V-B): c_max = 2.5, T = 0.8, the rest as DSN.
BATTLEFIELD_CMARLCD = StochasticConfig(c_max=2.5, temperature=0.8)


class CMARLCDStochastic(MaxReturnLearner):
    """CMARL-CD for stochastic games (Algorithm 2), step by step (see
    :class:`cmarlcd.learners.tabular.protocol.TabularLearner`)."""

    default_config = StochasticConfig()

    def degrees(self, state, masks=None) -> np.ndarray:
        """Each agent's coordination degrees ``c_i(state, ·)``, shape (n_agents, width):
        a copy; ``c_init`` everywhere for a state never visited (``masks`` unused: the
        degrees of illegal actions are kept as they were initialised)."""
        row = self._lookup(state)
        if row is None:
            return np.full(self.tables.degrees.shape[1:], self.config.c_init)
        return self.tables.degrees[row].copy()
