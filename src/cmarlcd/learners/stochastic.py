"""Tabular learners for stochastic games: CMARL-CD (Algorithm 2) and LA-OCA.

Both keep, per state ``s`` and agent ``i``, a row of action values (the coordination
degrees ``c_i(s)`` for CMARL-CD, the action probabilities ``p_i(s)`` for LA-OCA) and share
``R_max(s)``, the largest discounted return ever observed from ``s`` (the reward is
global, so all agents would hold the same values). After each episode the recorded steps
are processed backwards (SPEC §2, [choice] every visit): ``G_t = r_{t+1} + γ G_{t+1}``
(eq. 1) is compared with ``R_max(s_t)`` (eq. 16, equality within a tolerance) and the
learner's rule is applied to the action each agent took at ``s_t``:

* CMARL-CD, :func:`cmarlcd.learners.coordination.coordination_rule` (eqs. 14-17);
* LA-OCA, :func:`cmarlcd.learners.automata.automaton_rule`.

The compiled pieces (:func:`init_state`, :func:`update_from_episode`) serve both the
object API below and the fast experiment loops in :mod:`cmarlcd.rollouts`.
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numba import njit

from cmarlcd.errors import require
from cmarlcd.learners.automata import automaton_rule, uniform_strategy
from cmarlcd.learners.coordination import coordination_rule, softmax_strategy
from cmarlcd.learners.policy import greedy_actions, sample_joint_action

COORDINATION = 0
AUTOMATON = 1
BELOW, TIE, RECORD = 0, 1, 2


class RuleParams(NamedTuple):
    """Everything the compiled rules read, in one tuple numba can take as an argument."""

    kind: int
    delta: float
    delta_reset: float
    temperature: float
    c_min: float
    c_max: float
    c_init: float
    rate: float
    gamma: float
    tolerance: float


def _check_gamma_tolerance(gamma: float, tolerance: float) -> None:
    require(
        bool(np.isfinite(gamma)) and 0 < gamma <= 1, "gamma", f"must be in (0, 1] (got {gamma})"
    )
    require(tolerance >= 0, "tolerance", f"must be >= 0 (got {tolerance})")


@dataclass(frozen=True)
class StochasticConfig:
    """CMARL-CD for stochastic games (Algorithm 2); defaults are the paper's DSN settings."""

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
    """Discount of eq. (1), in (0, 1]."""
    tolerance: float = 1e-9
    """[choice] Absolute tolerance under which two returns count as equal."""

    def __post_init__(self) -> None:
        for name in ("delta", "delta_reset", "temperature"):
            value = getattr(self, name)
            require(bool(np.isfinite(value)) and value > 0, name, f"must be > 0 (got {value})")
        lo, hi, init = self.c_min, self.c_max, self.c_init
        require(bool(np.isfinite(lo)) and lo > 0, "c_min", f"must be > 0 (got {lo})")
        require(bool(np.isfinite(hi)) and lo <= hi, "c_max", f"must be >= c_min = {lo} (got {hi})")
        require(
            lo <= init <= hi, "c_init", f"must lie in [c_min, c_max] = [{lo}, {hi}] (got {init})"
        )
        _check_gamma_tolerance(self.gamma, self.tolerance)

    def rule_params(self) -> RuleParams:
        return RuleParams(
            COORDINATION,
            self.delta,
            self.delta_reset,
            self.temperature,
            self.c_min,
            self.c_max,
            self.c_init,
            0.0,
            self.gamma,
            self.tolerance,
        )


#: The paper's battlefield settings (Section V-B): c_max = 2.5, T = 0.8, the rest as DSN.
BATTLEFIELD_CMARLCD = StochasticConfig(c_max=2.5, temperature=0.8)


@dataclass(frozen=True)
class AutomatonConfig:
    """LA-OCA stand-in (SPEC §3)."""

    rate: float = 0.1
    """λ of the linear reward-inaction update, in (0, 1)."""
    gamma: float = 0.9
    """Discount of eq. (1), in (0, 1]."""
    tolerance: float = 1e-9
    """[choice] Absolute tolerance under which two returns count as equal."""

    def __post_init__(self) -> None:
        require(0 < self.rate < 1, "rate", f"must be in (0, 1) (got {self.rate})")
        _check_gamma_tolerance(self.gamma, self.tolerance)

    def rule_params(self) -> RuleParams:
        return RuleParams(
            AUTOMATON, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, self.rate, self.gamma, self.tolerance
        )


# --------------------------------------------------------------------- compiled core


@njit(cache=True)
def compare_return(g: float, best: float, tolerance: float) -> int:
    """Eq. (16) with ties within ``tolerance``: RECORD, TIE or BELOW."""
    if g > best + tolerance:
        return RECORD
    if g >= best - tolerance:
        return TIE
    return BELOW


@njit(cache=True)
def init_state(
    values: np.ndarray, probs: np.ndarray, legal: np.ndarray, counts: np.ndarray, params
) -> None:
    """A state's rows before any update: ``c = c_init`` (CMARL-CD) or uniform ``p`` (LA-OCA)."""
    for i in range(counts.shape[0]):
        if params.kind == COORDINATION:
            values[i, : counts[i]] = params.c_init
            softmax_strategy(values[i], legal[i], counts[i], params.temperature, probs[i])
        else:
            uniform_strategy(legal[i], counts[i], values[i])


@njit(cache=True)
def update_from_episode(
    states: np.ndarray,
    joints: np.ndarray,
    rewards: np.ndarray,
    length: int,
    values: np.ndarray,
    probs: np.ndarray,
    legal: np.ndarray,
    counts: np.ndarray,
    r_max: np.ndarray,
    params,
) -> None:
    """Algorithm 2, lines 13-22: the backward every-visit pass over one episode.

    ``states[t]``, ``joints[t]`` and ``rewards[t]`` are the state, joint action and the
    reward ``r_{t+1}`` that followed, for ``t < length``. For LA-OCA ``probs`` is
    ``values``.
    """
    g = 0.0
    for t in range(length - 1, -1, -1):
        g = rewards[t] + params.gamma * g  # eq. (1)
        s = states[t]
        outcome = compare_return(g, r_max[s], params.tolerance)
        if outcome == BELOW:
            continue
        if outcome == RECORD:
            r_max[s] = g
        for i in range(counts.shape[0]):
            if params.kind == COORDINATION:
                coordination_rule(
                    values[s, i],
                    probs[s, i],
                    legal[s, i],
                    counts[i],
                    joints[t, i],
                    outcome == RECORD,
                    params,
                )
            else:
                automaton_rule(values[s, i], legal[s, i], counts[i], joints[t, i], params.rate)


# ------------------------------------------------------------------------ tables


class TabularTables:
    """The arrays of a tabular learner: ``[state, agent, action]`` rows plus ``R_max``.

    Attributes:
        values: coordination degrees (CMARL-CD) or action probabilities (LA-OCA).
        probs: the sampling strategies (the same array as ``values`` for LA-OCA).
        legal: the legal-action mask of each state, as first seen.
        r_max: ``R_max(s)``, ``-inf`` before any visit.
    """

    def __init__(self, n_states: int, counts: np.ndarray, params: RuleParams) -> None:
        width = int(counts.max())
        self.counts = counts
        self.params = params
        self.values = np.zeros((n_states, counts.shape[0], width))
        self.probs = self.values if params.kind == AUTOMATON else np.zeros_like(self.values)
        self.legal = np.zeros(self.values.shape, dtype=np.bool_)
        self.r_max = np.full(n_states, -np.inf)

    @property
    def n_states(self) -> int:
        return int(self.values.shape[0])

    def init_row(self, row: int, legal: np.ndarray) -> None:
        self.legal[row] = legal
        init_state(self.values[row], self.probs[row], self.legal[row], self.counts, self.params)

    def init_all(self) -> None:
        """Every state with every action legal (games such as the DSN)."""
        full = np.arange(self.values.shape[2])[None, :] < self.counts[:, None]
        for row in range(self.n_states):
            self.init_row(row, full)

    def grow(self, n_states: int) -> None:
        """Enlarge to ``n_states`` rows (new rows uninitialised)."""
        extra = n_states - self.n_states
        pad = ((0, extra), (0, 0), (0, 0))
        self.values = np.pad(self.values, pad)
        self.probs = self.values if self.params.kind == AUTOMATON else np.pad(self.probs, pad)
        self.legal = np.pad(self.legal, pad)
        self.r_max = np.pad(self.r_max, (0, extra), constant_values=-np.inf)


# --------------------------------------------------------------------- object API


class TabularLearner:
    """Common object API of the tabular learners for stochastic games.

    States are integers in ``[0, n_states)`` when ``n_states`` is given, otherwise any
    hashable value, mapped to table rows in order of first visit. ``masks`` is one
    legal-action mask per agent (1 = legal); ``None`` means every action is legal. A
    state's mask is recorded on its first visit.

    Use: ``joint = act(state, masks)``, ``observe(state, joint, reward)`` after each step,
    ``end_episode()`` after each episode; ``greedy(state)`` for execution.
    """

    def __init__(
        self,
        action_counts: Sequence[int],
        params: RuleParams,
        n_states: int | None = None,
        seed: int | np.random.SeedSequence | np.random.Generator | None = None,
    ) -> None:
        counts = [int(k) for k in action_counts]
        require(len(counts) >= 1, "agents", "needs at least one agent")
        require(min(counts) >= 1, "actions", f"every agent needs >= 1 action (got {counts})")
        require(n_states is None or n_states >= 1, "n_states", f"must be >= 1 (got {n_states})")
        self.counts = np.array(counts, dtype=np.int64)
        self.rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        self._index: dict[Hashable, int] | None = None if n_states else {}
        self.tables = TabularTables(n_states or 16, self.counts, params)
        if n_states:
            self.tables.init_all()  # every row valid; a first visit's mask re-initialises it
        self._seen = np.zeros(self.tables.n_states, dtype=np.bool_)
        self._episode: list[tuple[int, np.ndarray, float]] = []

    @property
    def n_agents(self) -> int:
        return int(self.counts.shape[0])

    def act(self, state: Hashable, masks: Sequence[np.ndarray] | None = None) -> tuple[int, ...]:
        """Sample a joint action from the strategies at ``state``."""
        row = self._row(state, masks)
        joint = np.zeros(self.n_agents, dtype=np.int64)
        sample_joint_action(self.tables.probs[row], self.counts, self.rng, joint)
        return tuple(int(a) for a in joint)

    def observe(self, state: Hashable, joint_action: Sequence[int], reward: float) -> None:
        """Record one step: ``joint_action`` at ``state`` was followed by ``reward``."""
        joint = np.asarray(joint_action, dtype=np.int64)
        require(joint.shape == (self.n_agents,), "joint_action", f"needs {self.n_agents} actions")
        require(bool(np.isfinite(reward)), "reward", f"must be finite (got {reward})")
        self._episode.append((self._row(state, None), joint, float(reward)))

    def end_episode(self, final_state: Hashable = None, terminated: bool = True) -> None:
        """Learn from the recorded episode (the backward pass) and start a new one.

        The arguments are for learners that bootstrap; Monte-Carlo returns need neither.
        """
        if not self._episode:
            return
        rows, joints, rewards = zip(*self._episode, strict=True)
        t = self.tables
        update_from_episode(
            np.array(rows, dtype=np.int64),
            np.stack(joints),
            np.array(rewards),
            len(rows),
            t.values,
            t.probs,
            t.legal,
            self.counts,
            t.r_max,
            t.params,
        )
        self._episode = []

    def greedy(self, state: Hashable, masks: Sequence[np.ndarray] | None = None) -> tuple[int, ...]:
        """Execution: each agent's legal action with the largest value at ``state``."""
        row = self._row(state, masks)
        t = self.tables
        return tuple(int(a) for a in greedy_actions(t.values[row], t.legal[row], self.counts))

    def max_return(self, state: Hashable) -> float:
        """``R_max(state)``: the best discounted return seen from it (``-inf`` if unseen)."""
        row = self._lookup(state)
        return -np.inf if row is None else float(self.tables.r_max[row])

    def _lookup(self, state: Hashable) -> int | None:
        if self._index is None:
            row = int(state)  # type: ignore[call-overload]
            require(
                0 <= row < self.tables.n_states, "state", f"must be in [0, {self.tables.n_states})"
            )
            return row if self._seen[row] else None
        return self._index.get(state)

    def _row(self, state: Hashable, masks: Sequence[np.ndarray] | None) -> int:
        row = self._lookup(state)
        if row is not None:
            return row
        if self._index is None:
            row = int(state)  # type: ignore[call-overload]
        else:
            row = len(self._index)
            if row == self.tables.n_states:
                self.tables.grow(2 * row)
                self._seen = np.pad(self._seen, (0, row))
            self._index[state] = row
        self._seen[row] = True
        self.tables.init_row(row, self._mask_array(masks))
        return row

    def _mask_array(self, masks: Sequence[np.ndarray] | None) -> np.ndarray:
        width = self.tables.values.shape[2]
        legal = np.arange(width)[None, :] < self.counts[:, None]
        if masks is not None:
            require(len(masks) == self.n_agents, "masks", "needs one mask per agent")
            for i, mask in enumerate(masks):
                mask = np.asarray(mask, dtype=bool)
                require(mask.shape == (self.counts[i],), "masks", f"agent {i}: wrong length")
                require(bool(mask.any()), "masks", f"agent {i} has no legal action")
                legal[i, : self.counts[i]] = mask
        return legal


class CMARLCDStochastic(TabularLearner):
    """CMARL-CD for stochastic games (Algorithm 2)."""

    def __init__(
        self,
        action_counts: Sequence[int],
        config: StochasticConfig | None = None,
        n_states: int | None = None,
        seed: int | np.random.SeedSequence | np.random.Generator | None = None,
    ) -> None:
        self.config = config or StochasticConfig()
        super().__init__(action_counts, self.config.rule_params(), n_states, seed)


class LAOCA(TabularLearner):
    """The LA-OCA stand-in (SPEC §3): per-state reward-inaction automata."""

    def __init__(
        self,
        action_counts: Sequence[int],
        config: AutomatonConfig | None = None,
        n_states: int | None = None,
        seed: int | np.random.SeedSequence | np.random.Generator | None = None,
    ) -> None:
        self.config = config or AutomatonConfig()
        super().__init__(action_counts, self.config.rule_params(), n_states, seed)
