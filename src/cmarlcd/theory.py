"""Theorem 1 of the paper, checked numerically: every optimal joint action is stable.

Setting (eqs. 5 and 8-13). ``n >= 2`` agents play a common-payoff repeated game with
``m >= 2`` optimal joint actions whose component actions are unique: agent ``i`` has ``m``
actions and optimum ``j`` is the joint action in which every agent plays its action ``j``.
Agent ``i`` plays ``p_i = softmax(c_i / T)`` (eq. 5) and the mean-field learner follows

* eq. (8), coordination degrees:  ``dc_ij/dt = D_j - sum_{w != j} D_w``, where
  ``D_j = prod_l p_lj`` is the probability that optimum ``j`` is played;
* eq. (9), strategies:  ``dp_ij/dt = (2/T) p_ij [D_j (1 - p_ij) - sum_{h != j} p_ih^2
  prod_{l != i} p_lh]``;
* eq. (11), reduced coordinates ``p_bar_ij = p_ij`` for ``j < m`` (``p_im = 1 - sum``), and
  eq. (12), the field (9) for ``j < m`` written in ``p_bar``;
* eq. (13), the claim: at every optimum the Jacobian of (12) is ``-(2/T) I``.

Conventions: arrays are indexed ``[agent, action]``; agents, actions and optima are numbered
from 0 here (the paper counts from 1), so the paper's last action ``m`` is index ``m - 1``.
A reduced state is a flat vector of length ``n (m - 1)`` in agent-major order:
``p_bar[i * (m - 1) + j] = p_ij`` for ``j < m - 1``.

Two facts used below and in the tests, both read off eq. (8):

* its right-hand side does not depend on the agent ``i``, so ``c_i(t) - c_k(t)`` is constant
  along every trajectory (the log-odds differences between agents are invariants);
* for ``n = m = 2`` the reduced field is ``(x', y') = (2/T) (x+y-1) (x(1-x), y(1-y))`` with
  ``x = p_bar_11, y = p_bar_21``, so the whole anti-diagonal ``x + y = 1`` (where
  ``D_1 = D_2``) is a line of equilibria separating the two basins; transversally it repels (at
  ``(x, 1-x)`` the Jacobian has eigenvalues ``0`` and ``(4/T) x (1-x)``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from cmarlcd.errors import require
from cmarlcd.limits import MAX_STARTS, check_at_most

#: a start counts as converged once ``1 - max_j D_j`` drops below this (integration stops).
CONVERGENCE_TOL = 1e-6
#: :func:`classify` accepts a state whose every agent puts at least ``1 - tol`` on one optimum.
CLASSIFY_TOL = 1e-3
#: largest accepted ``|eigenvalue - (-2/T)|`` and Jacobian entry error for Theorem 1.
EIGEN_TOL = 1e-4
#: [choice] default horizon, in units of ``T m^n`` (the escape time from the uniform
#: strategy scales like that because every ``D_j`` starts near ``m^-n``).
T_END_FACTOR = 1e4
#: Largest ``m^n`` checked: from the uniform start every ``D_j`` is about ``m^-n``, and
#: beyond this the integration of eq. (8) falls below the solver's resolution.
MAX_JOINT_ACTIONS = 10**12
#: Random interior starts integrated by default.
DEFAULT_STARTS = 100
#: [choice] RK45 tolerances for eq. (8); ``c`` grows only linearly, so absolute is fine.
RTOL = 1e-8
ATOL = 1e-10


def _require_temperature(temperature: float) -> None:
    require(
        isinstance(temperature, int | float | np.floating)
        and not isinstance(temperature, bool)
        and temperature > 0
        and math.isfinite(temperature),
        "temperature",
        f"must be > 0 and finite (got {temperature!r})",
    )


def _is_int(value: object) -> bool:
    return isinstance(value, int | np.integer) and not isinstance(value, bool)


def strategies(c: np.ndarray, temperature: float) -> np.ndarray:
    """Softmax strategies ``p_i = softmax(c_i / T)`` per agent (row), eq. (5)."""
    z = np.asarray(c, dtype=float) / temperature
    z = np.exp(z - z.max(axis=-1, keepdims=True))
    return z / z.sum(axis=-1, keepdims=True)


def optimum_probabilities(p: np.ndarray) -> np.ndarray:
    """``D_j = prod_l p_lj``: the probability that optimum ``j`` is played (eq. 8)."""
    return np.prod(np.asarray(p, dtype=float), axis=0)


def coordination_field(c: np.ndarray, temperature: float) -> np.ndarray:
    """Eq. (8): ``dc_ij/dt = D_j - sum_{w != j} D_w``, shape ``(n, m)`` like ``c``."""
    d = optimum_probabilities(strategies(c, temperature))
    return np.broadcast_to(2.0 * d - d.sum(), np.shape(c)).copy()


def _others_product(p: np.ndarray) -> np.ndarray:
    """``prod_{l != i} p_lh`` for every ``(i, h)``, without dividing by ``p_ih``."""
    ones = np.ones((1, p.shape[1]))
    before = np.cumprod(np.vstack([ones, p[:-1]]), axis=0)
    after = np.cumprod(np.vstack([ones, p[:0:-1]]), axis=0)[::-1]
    return before * after


def strategy_field(p: np.ndarray, temperature: float) -> np.ndarray:
    """Eq. (9), term by term: ``dp_ij/dt`` for strategies ``p`` of shape ``(n, m)``."""
    p = np.asarray(p, dtype=float)
    d = optimum_probabilities(p)
    weighted = p**2 * _others_product(p)  # p_ih^2 prod_{l != i} p_lh
    others = weighted.sum(axis=1, keepdims=True) - weighted  # the sum over h != j
    return (2.0 / temperature) * p * (d * (1.0 - p) - others)


def expand_reduced(p_bar: np.ndarray, n_agents: int) -> np.ndarray:
    """Eq. (11): full strategies ``(n, m)`` from the agent-major reduced vector."""
    q = np.asarray(p_bar, dtype=float).reshape(n_agents, -1)
    return np.hstack([q, 1.0 - q.sum(axis=1, keepdims=True)])


def reduce_strategies(p: np.ndarray) -> np.ndarray:
    """Eq. (11) inverted: drop each agent's last action, flatten agent-major."""
    return np.asarray(p, dtype=float)[:, :-1].ravel()


def reduced_field(p_bar: np.ndarray, temperature: float, n_agents: int) -> np.ndarray:
    """Eq. (12): the field (9) for actions ``j < m`` at ``p_bar``, flat agent-major."""
    return strategy_field(expand_reduced(p_bar, n_agents), temperature)[:, :-1].ravel()


def optimum_point(n_agents: int, n_optima: int, j: int) -> np.ndarray:
    """Reduced coordinates (eq. 11) of optimum ``j`` (0-based): all agents play action ``j``."""
    require(0 <= j < n_optima, "j", f"must be in [0, {n_optima - 1}] (got {j})")
    p = np.zeros((n_agents, n_optima))
    p[:, j] = 1.0
    return reduce_strategies(p)


def jacobian_fd(
    f: Callable[[np.ndarray], np.ndarray], x: np.ndarray, eps: float = 1e-6
) -> np.ndarray:
    """Central finite-difference Jacobian ``J[a, b] = d f_a / d x_b`` at ``x``."""
    x = np.asarray(x, dtype=float)
    columns = []
    for b in range(x.size):
        step = np.zeros_like(x)
        step[b] = eps
        columns.append((np.asarray(f(x + step)) - np.asarray(f(x - step))) / (2.0 * eps))
    return np.column_stack(columns)


def default_t_end(n_agents: int, n_optima: int, temperature: float) -> float:
    """A generous horizon ``T_END_FACTOR * T * m^n`` for eq. (8) (integration stops early)."""
    return T_END_FACTOR * temperature * float(n_optima) ** n_agents


def _solve(c0: np.ndarray, temperature: float, t_end: float | None) -> Any:
    """Integrate eq. (8) with RK45 until some ``D_j >= 1 - CONVERGENCE_TOL`` or ``t_end``.

    Returns scipy's ``OdeResult``; ``y`` holds the flattened ``c`` at the solver's times.
    """
    c0 = np.asarray(c0, dtype=float)
    shape = c0.shape
    if t_end is None:
        t_end = default_t_end(shape[0], shape[1], temperature)

    def rhs(_t: float, y: np.ndarray) -> np.ndarray:
        return coordination_field(y.reshape(shape), temperature).ravel()

    def converged(_t: float, y: np.ndarray) -> float:
        d = optimum_probabilities(strategies(y.reshape(shape), temperature))
        return 1.0 - d.max() - CONVERGENCE_TOL

    converged.terminal = True  # type: ignore[attr-defined]
    from scipy.integrate import solve_ivp  # imported when used: it slows every command's start

    sol = solve_ivp(rhs, (0.0, t_end), c0.ravel(), rtol=RTOL, atol=ATOL, events=converged)
    if sol.status < 0:
        raise RuntimeError(f"eq. (8) integration failed: {sol.message}")
    return sol


def integrate(c0: np.ndarray, temperature: float, t_end: float | None = None) -> np.ndarray:
    """Integrate eq. (8) from ``c0`` (RK45) and return the final strategies ``p`` (eq. 5).

    Stops as soon as one optimum has probability ``D_j >= 1 - CONVERGENCE_TOL`` (then every
    agent is within ``CONVERGENCE_TOL`` of that vertex), otherwise at ``t_end`` (default
    :func:`default_t_end`).
    """
    _require_temperature(temperature)
    c0 = np.asarray(c0, dtype=float)
    return strategies(_solve(c0, temperature, t_end).y[:, -1].reshape(c0.shape), temperature)


def trajectory(
    c0: np.ndarray, temperature: float, t_end: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Solver times ``t`` and strategies ``p(t)``, shape ``(len(t), n, m)``, along eq. (8).

    Same stopping rule as :func:`integrate`.
    """
    _require_temperature(temperature)
    c0 = np.asarray(c0, dtype=float)
    sol = _solve(c0, temperature, t_end)
    return sol.t, strategies(sol.y.T.reshape(-1, *c0.shape), temperature)


def classify(p: np.ndarray, tol: float = CLASSIFY_TOL) -> int | None:
    """The optimum ``j`` (0-based) that strategies ``p`` (shape ``(n, m)``) sit at, or ``None``.

    ``p`` sits at optimum ``j`` when every agent's most likely action is ``j`` and has
    probability at least ``1 - tol``.
    """
    p = np.asarray(p, dtype=float)
    best = p.argmax(axis=1)
    if np.all(best == best[0]) and np.all(p.max(axis=1) >= 1.0 - tol):
        return int(best[0])
    return None


def random_start(
    rng: np.random.Generator, n_agents: int, n_optima: int, temperature: float
) -> np.ndarray:
    """A uniformly random interior start: ``p_i ~ Dirichlet(1)``, ``c_i = T log p_i``."""
    p0 = rng.dirichlet(np.ones(n_optima), size=n_agents)
    return temperature * np.log(np.maximum(p0, np.finfo(float).tiny))


@dataclass(frozen=True)
class StabilityReport:
    """Outcome of :func:`check_theorem1`.

    Attributes:
        n_agents, n_optima, temperature, starts, seed, t_end: the inputs (``t_end`` resolved).
        converged_to: per optimum, how many random starts ended at it (:func:`classify`).
        unconverged: starts that ended at no optimum by ``t_end`` (e.g. stuck near the
            non-optimal equilibria, where the ``D_j`` tie).
        max_integration_time: the latest time at which a start's integration stopped.
        eigenvalues: per optimum, the eigenvalues of the finite-difference Jacobian of eq. (12),
            sorted (complex; the imaginary parts should be ~0).
        expected_eigenvalue: ``-2/T``, the paper's eq. (13).
        max_eigen_error: ``max |eigenvalue - (-2/T)|`` over all optima.
        max_jacobian_error: ``max |J - (-2/T) I|`` entrywise over all optima.
    """

    n_agents: int
    n_optima: int
    temperature: float
    starts: int
    seed: int
    t_end: float
    converged_to: tuple[int, ...]
    unconverged: int
    max_integration_time: float
    eigenvalues: tuple[tuple[complex, ...], ...]
    expected_eigenvalue: float
    max_eigen_error: float
    max_jacobian_error: float

    @property
    def jacobian_confirmed(self) -> bool:
        """Eq. (13) holds numerically: every optimum's Jacobian is ``-(2/T) I``."""
        return max(self.max_eigen_error, self.max_jacobian_error) <= EIGEN_TOL

    @property
    def confirmed(self) -> bool:
        """Eq. (13) holds and every random start converged to some optimum."""
        return self.jacobian_confirmed and self.unconverged == 0

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary; eigenvalues are given as real parts plus the largest |imag|."""
        imag = [abs(v.imag) for row in self.eigenvalues for v in row]
        return {
            "n_agents": self.n_agents,
            "n_optima": self.n_optima,
            "temperature": self.temperature,
            "starts": self.starts,
            "seed": self.seed,
            "t_end": self.t_end,
            "converged_to": list(self.converged_to),
            "unconverged": self.unconverged,
            "max_integration_time": self.max_integration_time,
            "eigenvalues_real": [[v.real for v in row] for row in self.eigenvalues],
            "eigenvalues_max_abs_imag": max(imag, default=0.0),
            "expected_eigenvalue": self.expected_eigenvalue,
            "max_eigen_error": self.max_eigen_error,
            "max_jacobian_error": self.max_jacobian_error,
            "jacobian_confirmed": self.jacobian_confirmed,
            "confirmed": self.confirmed,
        }


def _validate(n_agents: int, n_optima: int, temperature: float, starts: int, seed: int) -> None:
    require(
        _is_int(n_agents) and n_agents >= 2,
        "agents",
        f"must be an integer >= 2 (got {n_agents!r})",
    )
    require(
        _is_int(n_optima) and n_optima >= 2,
        "optima",
        f"must be an integer >= 2 (got {n_optima!r})",
    )
    fits = n_agents * math.log(n_optima) <= math.log(MAX_JOINT_ACTIONS) + 1e-9
    require(
        fits,
        "agents",
        f"{n_optima}^{n_agents} joint actions exceed the {MAX_JOINT_ACTIONS:.0e} the ODE check "
        "can resolve",
    )
    _require_temperature(temperature)
    require(_is_int(starts) and starts >= 1, "starts", f"must be an integer >= 1 (got {starts!r})")
    check_at_most(starts, MAX_STARTS, "starts")
    require(_is_int(seed) and seed >= 0, "seed", f"must be an integer >= 0 (got {seed!r})")


def check_theorem1(
    n_agents: int,
    n_optima: int,
    temperature: float,
    starts: int = DEFAULT_STARTS,
    t_end: float | None = None,
    seed: int = 0,
) -> StabilityReport:
    """Check Theorem 1 numerically for ``n_agents`` agents and ``n_optima`` optima.

    Local part (eq. 13): the central finite-difference Jacobian of the reduced field (12) at
    every optimum, its eigenvalues, and their distance to ``-2/T``. Global evidence (not
    claimed by the theorem): ``starts`` random interior starts (:func:`random_start`, from
    ``numpy.random.default_rng(seed)``) integrated along eq. (8); where each one ends is
    counted per optimum, or as unconverged.
    """
    _validate(n_agents, n_optima, temperature, starts, seed)
    temperature = float(temperature)
    horizon = default_t_end(n_agents, n_optima, temperature) if t_end is None else float(t_end)
    require(horizon > 0, "t_end", f"must be > 0 (got {t_end!r})")

    rng = np.random.default_rng(seed)
    counts = [0] * n_optima
    unconverged = 0
    latest = 0.0
    for _ in range(starts):
        c0 = random_start(rng, n_agents, n_optima, temperature)
        sol = _solve(c0, temperature, horizon)
        latest = max(latest, float(sol.t[-1]))
        j = classify(strategies(sol.y[:, -1].reshape(c0.shape), temperature))
        if j is None:
            unconverged += 1
        else:
            counts[j] += 1

    expected = -2.0 / temperature
    eigenvalues = []
    eigen_error = jacobian_error = 0.0
    size = n_agents * (n_optima - 1)
    for j in range(n_optima):
        jac = jacobian_fd(
            lambda x: reduced_field(x, temperature, n_agents),
            optimum_point(n_agents, n_optima, j),
        )
        values = np.sort_complex(np.linalg.eigvals(jac))
        eigenvalues.append(tuple(complex(v) for v in values))
        eigen_error = max(eigen_error, float(np.max(np.abs(values - expected))))
        jacobian_error = max(jacobian_error, float(np.max(np.abs(jac - expected * np.eye(size)))))

    return StabilityReport(
        n_agents=int(n_agents),
        n_optima=int(n_optima),
        temperature=temperature,
        starts=int(starts),
        seed=int(seed),
        t_end=horizon,
        converged_to=tuple(counts),
        unconverged=unconverged,
        max_integration_time=latest,
        eigenvalues=tuple(eigenvalues),
        expected_eigenvalue=expected,
        max_eigen_error=eigen_error,
        max_jacobian_error=jacobian_error,
    )


@dataclass(frozen=True)
class PhasePortrait:
    """What the phase portrait of the reduced system (12) shows, for 2 agents and 2
    optima (drawn by :func:`cmarlcd.reports.figures.phase_portrait`)."""

    temperature: float
    grid: np.ndarray
    """Points of each axis, ``(p_bar_11, p_bar_21)`` in ``[0, 1]``."""
    u: np.ndarray
    """The field's first component at ``(grid[k], grid[r])``, indexed ``[r, k]`` ..."""
    v: np.ndarray
    """... and its second."""
    trajectories: list[np.ndarray]
    """Random starts integrated along eq. (8) in c-space, as ``(p_bar_11, p_bar_21)``."""


def phase_portrait(
    temperature: float = 1.0, seed: int = 0, trajectories: int = 12
) -> PhasePortrait:
    """The field of the reduced system (12) for 2 agents and 2 optima on a 51 x 51 grid,
    and ``trajectories`` random starts integrated along eq. (8) in c-space."""
    _require_temperature(temperature)
    require(
        _is_int(trajectories) and trajectories >= 0,
        "trajectories",
        f"must be an integer >= 0 (got {trajectories!r})",
    )
    require(_is_int(seed) and seed >= 0, "seed", f"must be an integer >= 0 (got {seed!r})")
    grid = np.linspace(0.0, 1.0, 51)
    u = np.empty((grid.size, grid.size))
    v = np.empty_like(u)
    for r, y in enumerate(grid):
        for k, x in enumerate(grid):
            u[r, k], v[r, k] = reduced_field(np.array([x, y]), temperature, 2)
    rng = np.random.default_rng(seed)
    paths = []
    for _ in range(trajectories):
        _, ps = trajectory(random_start(rng, 2, 2, temperature), temperature)
        paths.append(np.stack([ps[:, 0, 0], ps[:, 1, 0]], axis=1))
    return PhasePortrait(float(temperature), grid, u, v, paths)
