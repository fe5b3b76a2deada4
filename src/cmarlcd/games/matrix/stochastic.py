"""Repeated games with stochastic payoffs: each joint action pays one of several values,
drawn afresh at every play.

The partially and fully stochastic climbing games of Kapetanakis & Kudenko (2002) are the
classic ones: their expected payoffs are the climbing game's, so an optimal joint action
is one of largest *expected* payoff, while a single lucky draw can pay more elsewhere
(14 at ``(1, 1)`` against 11 or 12 at ``(0, 0)``). A learner that trusts the largest
reward it has seen is fooled by such a draw; these games measure how often.

The game's state arrays are ``env = (flat_outcomes, strides, counts, flat_cumulative)``:
per joint action (C order) its possible payoffs and their cumulative probabilities. The
counts sit where the deterministic game's kernels read them, so ``reset``, ``state``,
``done`` and ``legal`` are shared; only ``step`` draws.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from cmarlcd.compiled import kernel
from cmarlcd.errors import require
from cmarlcd.games.matrix import kernels
from cmarlcd.games.matrix.game import check_shape
from cmarlcd.games.spec import GameKernels, GameSpec

#: [choice] Expected payoffs within this of the largest count as optimal (the stochastic
#: climbing games' expectations are exact sums of halves, so equality is exact there).
EXPECTATION_TOLERANCE = 1e-9


@kernel
def stochastic_step(env, joint: np.ndarray, rng, rewards: np.ndarray) -> None:
    """Protocol ``step``: one payoff of ``joint`` drawn by its probabilities (one uniform
    from ``rng`` per play, inverse CDF)."""
    row = kernels.flat_index(joint, env[1])
    u = rng.random()
    outcomes, cumulative = env[0], env[3]
    last = outcomes.shape[1] - 1
    for k in range(last):
        if u < cumulative[row, k]:
            rewards[0] = outcomes[row, k]
            return
    rewards[0] = outcomes[row, last]


#: The compiled protocol of every stochastic repeated game.
STOCHASTIC_KERNELS = GameKernels(
    kernels.env_reset, stochastic_step, kernels.env_state, kernels.env_done, kernels.env_legal
)


@dataclass(frozen=True, eq=False)
class StochasticMatrixGame:
    """A common-payoff repeated game whose joint actions pay random amounts.

    Attributes:
        outcomes: shape ``(|A_1|, ..., |A_n|, K)``: the ``K`` possible payoffs of each
            joint action.
        probabilities: the same shape: their probabilities (each joint action's sum to 1).
        name: a label for reports.
    """

    outcomes: np.ndarray
    probabilities: np.ndarray
    name: str = "custom-stochastic"
    action_counts: tuple[int, ...] = field(init=False)
    expected_payoffs: np.ndarray = field(init=False, repr=False)
    """The expected payoff of each joint action, shape ``(|A_1|, ..., |A_n|)``."""

    def __post_init__(self) -> None:
        outcomes = np.array(self.outcomes, dtype=np.float64)
        probabilities = np.array(self.probabilities, dtype=np.float64)
        require(outcomes.ndim >= 3, "outcomes", "needs one axis per agent and one of outcomes")
        require(
            probabilities.shape == outcomes.shape,
            "probabilities",
            f"needs the outcomes' shape {outcomes.shape} (got {probabilities.shape})",
        )
        check_shape(outcomes.shape[:-1])
        require(bool(np.isfinite(outcomes).all()), "outcomes", "must contain only finite values")
        require(
            bool(((probabilities >= 0) & (probabilities <= 1)).all()),
            "probabilities",
            "must lie in [0, 1]",
        )
        sums = probabilities.sum(axis=-1)
        require(
            bool(np.allclose(sums, 1.0, atol=1e-9)),
            "probabilities",
            "must sum to 1 for every joint action",
        )
        for array in (outcomes, probabilities):
            array.setflags(write=False)
        object.__setattr__(self, "outcomes", outcomes)
        object.__setattr__(self, "probabilities", probabilities)
        object.__setattr__(self, "action_counts", tuple(int(k) for k in outcomes.shape[:-1]))
        expected = (outcomes * probabilities).sum(axis=-1)
        expected.setflags(write=False)
        object.__setattr__(self, "expected_payoffs", expected)

    @property
    def n_agents(self) -> int:
        return len(self.action_counts)

    @property
    def max_payoff(self) -> float:
        """The largest expected payoff."""
        return float(self.expected_payoffs.max())

    @property
    def optimal_joint_actions(self) -> list[tuple[int, ...]]:
        """Every joint action of the largest expected payoff."""
        hits = np.argwhere(self.expected_payoffs >= self.max_payoff - EXPECTATION_TOLERANCE)
        return [tuple(int(a) for a in row) for row in hits]

    def payoff(self, joint_action: Sequence[int]) -> float:
        """The expected payoff of ``joint_action``."""
        return float(self.expected_payoffs[tuple(int(a) for a in joint_action)])

    def is_optimal(self, joint_action: Sequence[int]) -> bool:
        """True when ``joint_action`` attains the largest expected payoff."""
        return self.payoff(joint_action) >= self.max_payoff - EXPECTATION_TOLERANCE

    def new_env(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The state arrays :data:`STOCHASTIC_KERNELS` play on."""
        joint_actions = math.prod(self.action_counts)
        flat = np.ascontiguousarray(self.outcomes.reshape(joint_actions, -1))
        cumulative = np.cumsum(self.probabilities.reshape(joint_actions, -1), axis=1)
        counts = np.array(self.action_counts, dtype=np.int64)
        strides = np.array(
            [math.prod(self.action_counts[i + 1 :]) for i in range(self.n_agents)],
            dtype=np.int64,
        )
        return flat, strides, counts, cumulative

    def spec(self) -> GameSpec:
        """This game as a one-state game of the compiled protocol."""
        return GameSpec(
            name="stochastic_matrix_game_v0",
            kernels=STOCHASTIC_KERNELS,
            new_env=self.new_env,
            agents=tuple(f"agent_{i}" for i in range(self.n_agents)),
            action_counts=np.array(self.action_counts, dtype=np.int64),
            n_states=1,
            max_steps=1,
            teams=(tuple(range(self.n_agents)),),
        )


def _two_outcomes(first: Sequence[Sequence[float]], second: Sequence[Sequence[float]], name: str):
    """A 2-agent game whose cells pay ``first`` or ``second`` with probability 1/2 each."""
    outcomes = np.stack([np.array(first, dtype=float), np.array(second, dtype=float)], axis=-1)
    return StochasticMatrixGame(outcomes, np.full(outcomes.shape, 0.5), name=name)


def partially_stochastic_climbing_game() -> StochasticMatrixGame:
    """Kapetanakis & Kudenko (2002): the climbing game, except that ``(1, 1)`` pays 14 or
    0 with probability 1/2 each (expected 7, as in the climbing game)."""
    deterministic = [[11.0, -30.0, 0.0], [-30.0, 7.0, 6.0], [0.0, 0.0, 5.0]]
    first = [row[:] for row in deterministic]
    second = [row[:] for row in deterministic]
    first[1][1], second[1][1] = 14.0, 0.0
    return _two_outcomes(first, second, "climbing-ps")


def fully_stochastic_climbing_game() -> StochasticMatrixGame:
    """Kapetanakis & Kudenko (2002): every cell of the climbing game pays one of two
    values with probability 1/2 each; the expected payoffs are the climbing game's
    (optimum 11 at ``(0, 0)``, which pays 10 or 12, while ``(1, 1)`` pays 14 or 0)."""
    first = [[10.0, 5.0, 8.0], [5.0, 14.0, 12.0], [5.0, 5.0, 10.0]]
    second = [[12.0, -65.0, -8.0], [-65.0, 0.0, 0.0], [-5.0, -5.0, 0.0]]
    return _two_outcomes(first, second, "climbing-fs")
