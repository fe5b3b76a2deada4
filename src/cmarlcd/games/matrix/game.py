"""Repeated (one-stage, common-payoff) games: random generators and classic games.

A repeated game is a payoff tensor of shape ``(|A_1|, ..., |A_n|)``; entry ``a`` is the
global reward every agent receives when the joint action ``a`` is played (Section III-B).

The random generators follow Section IV-C of the paper:

* **case 1** -- the component action of every optimal joint action is unique: agent
  ``i``'s component actions across the ``m`` optima are a random permutation of its
  ``m`` actions;
* **case 2** -- ``round(0.1 m^n)`` optimal joint actions drawn uniformly without
  replacement.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path

import numpy as np

from cmarlcd.errors import ConfigError, require
from cmarlcd.games.matrix import kernels
from cmarlcd.games.spec import GameKernels, GameSpec

#: [choice] payoff of every optimal joint action in the random games.
OPTIMAL_PAYOFF = 1.0
#: [choice] non-optimal payoffs are ``SUBOPTIMAL_SCALE * U[0, 1)``, so strictly below optimal.
SUBOPTIMAL_SCALE = 0.9
#: case 2: the fraction of joint actions that are optimal (the paper's 0.1).
CASE2_OPTIMAL_FRACTION = 0.1
#: Largest payoff tensor accepted, in joint actions (entries): about 0.8 GB of float64.
MAX_JOINT_ACTIONS = 100_000_000

#: The compiled protocol of every repeated game (one state, one step per episode).
KERNELS = GameKernels(
    kernels.env_reset, kernels.env_step, kernels.env_state, kernels.env_done, kernels.env_legal
)


@dataclass(frozen=True, eq=False)
class MatrixGame:
    """A common-payoff repeated game.

    Attributes:
        payoffs: read-only float64 array, shape ``(|A_1|, ..., |A_n|)``.
        name: a label for reports.
    """

    payoffs: np.ndarray
    name: str = "custom"
    action_counts: tuple[int, ...] = field(init=False)
    """Actions of each agent."""
    _flat: np.ndarray = field(init=False, repr=False)
    _strides: np.ndarray = field(init=False, repr=False)
    _counts: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        payoffs = validate_payoffs(self.payoffs)
        payoffs.setflags(write=False)
        object.__setattr__(self, "payoffs", payoffs)
        object.__setattr__(self, "action_counts", tuple(int(k) for k in payoffs.shape))
        object.__setattr__(self, "_flat", payoffs.reshape(-1))
        strides = np.array(payoffs.strides, dtype=np.int64) // payoffs.itemsize
        object.__setattr__(self, "_strides", strides)
        object.__setattr__(self, "_counts", np.array(payoffs.shape, dtype=np.int64))

    @property
    def n_agents(self) -> int:
        return self.payoffs.ndim

    @property
    def max_payoff(self) -> float:
        return float(self.payoffs.max())

    @property
    def optimal_joint_actions(self) -> list[tuple[int, ...]]:
        """Every joint action whose payoff equals the game's maximum."""
        hits = np.argwhere(self.payoffs == self.payoffs.max())
        return [tuple(int(a) for a in row) for row in hits]

    @property
    def flat_payoffs(self) -> np.ndarray:
        """The payoffs as a flat C-order vector (what the compiled kernels index)."""
        return self._flat

    @property
    def strides(self) -> np.ndarray:
        """Element strides: ``flat_payoffs[joint @ strides] == payoffs[tuple(joint)]``."""
        return self._strides

    def payoff(self, joint_action: Sequence[int]) -> float:
        """The global reward of ``joint_action``."""
        return float(self.payoffs[tuple(int(a) for a in joint_action)])

    def is_optimal(self, joint_action: Sequence[int]) -> bool:
        """True when ``joint_action`` attains the game's maximal payoff."""
        return self.payoff(joint_action) == self.max_payoff

    def new_env(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The state arrays :data:`KERNELS` play on: (flat payoffs, strides, counts)."""
        return self._flat, self._strides, self._counts

    def spec(self) -> GameSpec:
        """This game as a one-state game of the compiled protocol."""
        return GameSpec(
            name="matrix_game_v0",
            kernels=KERNELS,
            new_env=self.new_env,
            agents=tuple(f"agent_{i}" for i in range(self.n_agents)),
            action_counts=self._counts,
            n_states=1,
            max_steps=1,
            teams=(tuple(range(self.n_agents)),),
        )


def validate_payoffs(payoffs: object) -> np.ndarray:
    """Return ``payoffs`` as a fresh float64 array, or raise :class:`ConfigError`.

    A valid payoff tensor has at least two axes (agents) of at least two entries
    (actions) each, and only finite real values.
    """
    try:
        array = np.array(payoffs, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ConfigError(
            "payoffs", f"must be a rectangular numeric array ({type(exc).__name__})"
        ) from None
    check_shape(array.shape)
    require(bool(np.isfinite(array).all()), "payoffs", "must contain only finite values")
    return np.ascontiguousarray(array)


def check_shape(shape: tuple[int, ...]) -> None:
    """A payoff tensor's shape: at least 2 agents, 2 actions each, at most the size limit."""
    require(len(shape) >= 2, "payoffs", f"needs one axis per agent, at least 2 (got {len(shape)})")
    require(min(shape) >= 2, "payoffs", f"every agent needs at least 2 actions (got shape {shape})")
    require(
        math.prod(shape) <= MAX_JOINT_ACTIONS,
        "payoffs",
        f"shape {shape} has more than {MAX_JOINT_ACTIONS:,} joint actions",
    )


def check_size(n_agents: int, n_actions: int, parameter: str = "agents") -> None:
    """``n_actions ** n_agents`` joint actions fit the size limit, checked in O(1) time
    (the power of two huge numbers is never formed)."""
    require(n_agents >= 2, "agents", f"must be >= 2 (got {n_agents})")
    require(n_actions >= 2, "actions", f"must be >= 2 (got {n_actions})")
    fits = n_agents * math.log(n_actions) <= math.log(MAX_JOINT_ACTIONS) + 1e-9
    require(
        fits and n_actions**n_agents <= MAX_JOINT_ACTIONS,
        parameter,
        f"{n_actions}^{n_agents} joint actions exceed the limit of {MAX_JOINT_ACTIONS:,}",
    )


def _random_background(shape: tuple[int, ...], rng: np.random.Generator) -> np.ndarray:
    return SUBOPTIMAL_SCALE * rng.random(shape)


def random_case1(n_agents: int, n_actions: int, rng: np.random.Generator) -> MatrixGame:
    """Case 1 of Section IV-C: ``m = n_actions`` optima with unique component actions.

    Agent ``i``'s component actions across the ``m`` optima are a random permutation of
    its ``m`` actions, so every action of every agent belongs to exactly one optimum.
    """
    check_size(n_agents, n_actions)
    shape = (n_actions,) * n_agents
    payoffs = _random_background(shape, rng)
    components = np.stack([rng.permutation(n_actions) for _ in range(n_agents)])
    payoffs[tuple(components)] = OPTIMAL_PAYOFF
    return MatrixGame(payoffs, name=f"case1-n{n_agents}-m{n_actions}")


def case2_optimum_count(n_agents: int, n_actions: int) -> int:
    """``round(0.1 m^n)``, rounding halves up, in exact arithmetic.

    [choice] The paper's ``[ ]`` rounds to an integer; for ``m = 5`` every cell is a
    tie (``0.1 * 5^n = x.5``), which we round up. At least one optimum is kept.
    """
    exact = Fraction(str(CASE2_OPTIMAL_FRACTION)) * n_actions**n_agents
    return max(1, int(exact + Fraction(1, 2)))


def random_case2(n_agents: int, n_actions: int, rng: np.random.Generator) -> MatrixGame:
    """Case 2 of Section IV-C: ``round(0.1 m^n)`` optima drawn without replacement."""
    check_size(n_agents, n_actions)
    shape = (n_actions,) * n_agents
    payoffs = _random_background(shape, rng)
    total = n_actions**n_agents
    chosen = rng.choice(total, size=case2_optimum_count(n_agents, n_actions), replace=False)
    payoffs.reshape(-1)[chosen] = OPTIMAL_PAYOFF
    return MatrixGame(payoffs, name=f"case2-n{n_agents}-m{n_actions}")


def random_game(case: int, n_agents: int, n_actions: int, rng: np.random.Generator) -> MatrixGame:
    """Dispatch to :func:`random_case1` or :func:`random_case2`."""
    if case == 1:
        return random_case1(n_agents, n_actions, rng)
    if case == 2:
        return random_case2(n_agents, n_actions, rng)
    raise ConfigError("case", f"must be 1 or 2 (got {case})")


def climbing_game() -> MatrixGame:
    """The climbing game (Claus & Boutilier, 1998): optimum 11 at ``(0, 0)``."""
    payoffs = [[11.0, -30.0, 0.0], [-30.0, 7.0, 6.0], [0.0, 0.0, 5.0]]
    return MatrixGame(np.array(payoffs), name="climbing")


def penalty_game(k: float = -10.0) -> MatrixGame:
    """The penalty game with penalty ``k <= 0``: optima 10 at ``(0, 0)`` and ``(2, 2)``.

    Miscoordinating between the two optima, ``(0, 2)`` or ``(2, 0)``, pays ``k``.
    """
    require(np.isfinite(k) and k <= 0, "k", f"must be a finite number <= 0 (got {k})")
    payoffs = [[10.0, 0.0, k], [0.0, 2.0, 0.0], [k, 0.0, 10.0]]
    return MatrixGame(np.array(payoffs), name=f"penalty(k={k:g})")


def from_payoffs(payoffs: object, name: str = "custom") -> MatrixGame:
    """A game from a user-supplied payoff array (validated: shape, finite values)."""
    return MatrixGame(validate_payoffs(payoffs), name=name)


def load_payoffs(path: str | Path) -> MatrixGame:
    """A game from a file: ``.npy`` (any number of agents), ``.json`` (nested lists) or
    ``.csv`` / ``.txt`` (a 2-agent matrix, comma separated).

    A ``.npy`` file's shape is checked from its header before anything is loaded."""
    path = Path(path)
    require(not path.is_dir(), "payoffs", f"{path} is a directory, not a payoff file")
    require(path.is_file(), "payoffs", f"no such file: {path}")
    suffix = path.suffix.lower()
    require(
        suffix in (".npy", ".json", ".csv", ".txt"),
        "payoffs",
        f"unsupported file type {suffix!r}; use .npy, .json or .csv",
    )
    require(path.stat().st_size > 0, "payoffs", f"{path.name} is empty")
    try:
        if suffix == ".npy":
            data = _load_npy(path)
        elif suffix == ".json":
            data = json.loads(path.read_text())
        else:
            data = np.loadtxt(path, delimiter=",", ndmin=2)
    except (OSError, ValueError, EOFError) as exc:
        if isinstance(exc, ConfigError):
            raise
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise ConfigError("payoffs", f"cannot read {path.name}: {reason}") from None
    return from_payoffs(data, name=path.stem)


def _load_npy(path: Path) -> np.ndarray:
    """An ``.npy`` array whose header promises a numeric payoff tensor of a sane size."""
    with path.open("rb") as file:
        fmt = np.lib.format
        version = fmt.read_magic(file)
        read = fmt.read_array_header_1_0 if version == (1, 0) else fmt.read_array_header_2_0
        shape, _, dtype = read(file)
    require(dtype.kind in "biuf", "payoffs", f"{path.name} holds {dtype} values, not numbers")
    check_shape(tuple(shape))
    return np.load(path, allow_pickle=False)
