"""CMARL-CD: learning by the coordination degree (Section IV, Algorithms 1 and 2).

Each agent ``i`` keeps a coordination degree ``c_i[a]`` per action and plays the
Boltzmann strategy ``p_i = softmax(c_i / T)`` (eq. 5). After every game the global
reward ``r`` is compared with the largest reward seen so far, ``r_max``; when
``r >= r_max`` (eq. 4) the selected action's degree rises by ``delta`` and every other
action's degree falls by ``delta`` (eqs. 2-3).

The rules are numba-compiled functions over plain arrays, written once and used both
by the object API (:class:`CMARLCD`) and by the fast experiment loop
(:func:`play_repeated`). Agents may have different action counts: per-agent rows are
padded to the largest count and ``counts[i]`` says how many entries of row ``i`` are
real.

Every agent observes the same global reward, so the per-agent maxima ``r_i_max`` of
Algorithm 1 are always equal; they are kept as one shared value.

For stochastic games (Algorithm 2) the same rules apply per state; the per-state rule is
:func:`coordination_rule`, driven by the backward pass in :mod:`cmarlcd.learners.stochastic`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numba import njit

from cmarlcd.errors import require
from cmarlcd.games.matrix import MatrixGame
from cmarlcd.learners.policy import greedy_actions, sample_joint_action

# --------------------------------------------------------------------------- rules


@njit(cache=True)
def softmax_strategy(
    c_row: np.ndarray, legal_row: np.ndarray, count: int, temperature: float, p_row: np.ndarray
) -> None:
    """Eqs. (5) and (17): ``p = softmax(c / T)`` over the legal actions (others get 0)."""
    top = -np.inf
    for a in range(count):
        if legal_row[a]:
            top = max(top, c_row[a])
    total = 0.0
    for a in range(count):
        p_row[a] = np.exp((c_row[a] - top) / temperature) if legal_row[a] else 0.0
        total += p_row[a]
    for a in range(count):
        p_row[a] /= total


@njit(cache=True)
def reinforce(c_row: np.ndarray, count: int, action: int, step: float) -> None:
    """Eqs. (2)-(3) and (14)-(15): the selected action ``+step``, every other ``-step``."""
    for a in range(count):
        if a == action:
            c_row[a] += step
        else:
            c_row[a] -= step


@njit(cache=True)
def clip_degrees(c_row: np.ndarray, count: int, c_min: float, c_max: float) -> None:
    """Section IV-D: confine every coordination degree to ``[c_min, c_max]``."""
    for a in range(count):
        c_row[a] = min(max(c_row[a], c_min), c_max)


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
    step = params.delta
    if new_record:
        for a in range(count):
            c_row[a] = params.c_init
        step = params.delta_reset
    reinforce(c_row, count, action, step)
    clip_degrees(c_row, count, params.c_min, params.c_max)
    softmax_strategy(c_row, legal_row, count, params.temperature, p_row)


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


@njit(cache=True)
def is_pure(p: np.ndarray, counts: np.ndarray, threshold: float) -> bool:
    """The stopping rule: every agent has some action with probability above ``threshold``."""
    for i in range(counts.shape[0]):
        pure = False
        for a in range(counts[i]):
            if p[i, a] > threshold:
                pure = True
                break
        if not pure:
            return False
    return True


@njit(cache=True)
def flat_index(joint: np.ndarray, strides: np.ndarray) -> int:
    """Position of ``joint`` in a C-order flattened payoff tensor."""
    index = 0
    for i in range(joint.shape[0]):
        index += joint[i] * strides[i]
    return index


@njit(cache=True)
def play_repeated(
    flat_payoffs: np.ndarray,
    strides: np.ndarray,
    c: np.ndarray,
    p: np.ndarray,
    legal: np.ndarray,
    counts: np.ndarray,
    r_max: np.ndarray,
    delta: float,
    temperature: float,
    threshold: float,
    max_games: int,
    rng,
) -> tuple[int, bool]:
    """Algorithm 1: play until every strategy is pure or ``max_games`` games are played.

    Returns ``(games_played, converged)``. The state arrays are updated in place, so a
    call continues from wherever the learner stands.
    """
    joint = np.zeros(counts.shape[0], dtype=np.int64)
    for game in range(max_games):
        sample_joint_action(p, counts, rng, joint)
        reward = flat_payoffs[flat_index(joint, strides)]
        fired = repeated_update(c, p, legal, counts, joint, reward, r_max, delta, temperature)
        if fired and is_pure(p, counts, threshold):  # p changes only when eq. (4) fires
            return game + 1, True
    return max_games, False


# ---------------------------------------------------------------------- object API


@dataclass(frozen=True)
class RepeatedConfig:
    """Hyper-parameters of CMARL-CD for repeated games (Section IV-C settings)."""

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
        init = self.initial_degree
        require(bool(np.isfinite(init)), "initial_degree", f"must be finite (got {init})")


@dataclass(frozen=True)
class FitResult:
    """Outcome of :meth:`CMARLCD.fit`."""

    games: int
    """Games played in this call."""
    converged: bool
    """Every strategy became pure before the cap."""
    greedy_joint_action: tuple[int, ...]
    """argmax of each agent's coordination degrees."""
    greedy_payoff: float
    """Payoff of the greedy joint action."""
    success: bool
    """Converged and the greedy joint action is optimal (the paper's success)."""


class CMARLCD:
    """CMARL-CD learners for an n-agent repeated game (Algorithm 1).

    Example:
        >>> from cmarlcd import CMARLCD, games
        >>> game = games.climbing_game()
        >>> learner = CMARLCD(game.action_counts, seed=0)
        >>> learner.fit(game).success
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
        self.counts = np.array(counts, dtype=np.int64)
        self.rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        self.degrees = np.full((len(counts), max(counts)), self.config.initial_degree)
        self.legal = np.arange(max(counts))[None, :] < self.counts[:, None]
        self.strategies = np.zeros_like(self.degrees)
        for i, count in enumerate(counts):
            softmax_strategy(
                self.degrees[i], self.legal[i], count, self.config.temperature, self.strategies[i]
            )
        self._r_max = np.array([-np.inf])

    @property
    def n_agents(self) -> int:
        return int(self.counts.shape[0])

    @property
    def max_reward(self) -> float:
        """``r_max``: the largest global reward seen so far (``-inf`` before any game)."""
        return float(self._r_max[0])

    def act(self) -> tuple[int, ...]:
        """Sample a joint action from the current strategies."""
        joint = np.zeros(self.n_agents, dtype=np.int64)
        sample_joint_action(self.strategies, self.counts, self.rng, joint)
        return tuple(int(a) for a in joint)

    def update(self, joint_action: Sequence[int], reward: float) -> bool:
        """Learn from one game; returns True when the indicator of eq. (4) fired."""
        joint = self._check_joint(joint_action)
        require(bool(np.isfinite(reward)), "reward", f"must be finite (got {reward})")
        cfg = self.config
        return bool(
            repeated_update(
                self.degrees,
                self.strategies,
                self.legal,
                self.counts,
                joint,
                float(reward),
                self._r_max,
                cfg.delta,
                cfg.temperature,
            )
        )

    def is_pure(self) -> bool:
        """The paper's stopping rule (every agent has an action above the threshold)."""
        return bool(is_pure(self.strategies, self.counts, self.config.purity_threshold))

    def greedy_joint_action(self) -> tuple[int, ...]:
        """Each agent's action with the largest coordination degree."""
        return tuple(int(a) for a in greedy_actions(self.degrees, self.legal, self.counts))

    def strategy(self, agent: int) -> np.ndarray:
        """Agent ``agent``'s current strategy ``p_i`` (a copy)."""
        return self.strategies[agent, : self.counts[agent]].copy()

    def fit(self, game: MatrixGame, max_games: int | None = None) -> FitResult:
        """Play ``game`` until every strategy is pure (or the cap), via the compiled loop."""
        require(
            game.action_counts == tuple(int(k) for k in self.counts),
            "game",
            f"has action counts {game.action_counts}, the learners {tuple(self.counts)}",
        )
        cfg = self.config
        cap = cfg.max_games if max_games is None else int(max_games)
        require(cap >= 1, "max_games", f"must be >= 1 (got {cap})")
        games, converged = play_repeated(
            game.flat_payoffs,
            game.strides,
            self.degrees,
            self.strategies,
            self.legal,
            self.counts,
            self._r_max,
            cfg.delta,
            cfg.temperature,
            cfg.purity_threshold,
            cap,
            self.rng,
        )
        greedy = self.greedy_joint_action()
        payoff = game.payoff(greedy)
        success = bool(converged) and payoff == game.max_payoff
        return FitResult(int(games), bool(converged), greedy, payoff, success)

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
