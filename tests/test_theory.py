"""Tests for cmarlcd.theory: the mean-field dynamics (eqs. 5, 8-12) and Theorem 1 (eq. 13)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from cmarlcd.reports.figures import phase_portrait
from cmarlcd.theory import (
    StabilityReport,
    check_theorem1,
    classify,
    coordination_field,
    expand_reduced,
    integrate,
    jacobian_fd,
    optimum_point,
    random_start,
    reduce_strategies,
    reduced_field,
    strategies,
    strategy_field,
    trajectory,
)

SHAPES = [(2, 2), (2, 3), (3, 2), (3, 3), (4, 3), (5, 4)]
TEMPERATURES = [0.5, 1.0, 2.0]


def test_strategies_are_a_stable_softmax() -> None:
    # softmax(c/T) with c/T = (ln 3, 0) gives (3/4, 1/4); shifting c changes nothing; huge
    # values must not overflow.
    p = strategies(np.array([[2 * math.log(3), 0.0], [1e4, 1e4 - 2 * math.log(3)]]), 2.0)
    np.testing.assert_allclose(p, [[0.75, 0.25], [0.75, 0.25]], rtol=1e-12)
    assert np.all(np.isfinite(strategies(np.array([[1e6, -1e6, 0.0]]), 1e-3)))


def test_coordination_field_by_hand() -> None:
    # c = 0: every p_ij = 1/2, D_1 = D_2 = 1/4, so dc_ij/dt = 1/4 - 1/4 = 0.
    np.testing.assert_allclose(coordination_field(np.zeros((2, 2)), 1.0), 0.0, atol=1e-15)
    # T = 1, c_1 = (ln 3, 0), c_2 = (0, 0): p_1 = (3/4, 1/4), p_2 = (1/2, 1/2),
    # D_1 = 3/8, D_2 = 1/8 -> dc_.1/dt = 3/8 - 1/8 = 1/4 and dc_.2/dt = -1/4 for both agents.
    c = np.array([[math.log(3), 0.0], [0.0, 0.0]])
    np.testing.assert_allclose(coordination_field(c, 1.0), [[0.25, -0.25]] * 2, rtol=1e-12)
    # three optima, c = 0, n = 2: D_j = 1/9 each, dc/dt = 1/9 - 2/9 = -1/9 everywhere.
    np.testing.assert_allclose(coordination_field(np.zeros((2, 3)), 0.7), -1 / 9, rtol=1e-12)


def test_strategy_field_by_hand() -> None:
    # Same state, eq. (9) for agent 1, action 1 with T = 1:
    # 2 * 3/4 * [D_1 (1 - 3/4) - p_12^2 p_22] = 3/2 * [3/8 * 1/4 - 1/16 * 1/2] = 3/32.
    p = np.array([[0.75, 0.25], [0.5, 0.5]])
    dp = strategy_field(p, 1.0)
    assert dp[0, 0] == pytest.approx(3 / 32)
    np.testing.assert_allclose(dp.sum(axis=1), 0.0, atol=1e-15)  # probabilities stay summed


@pytest.mark.parametrize(("n", "m"), SHAPES)
@pytest.mark.parametrize("temperature", TEMPERATURES)
def test_eq9_is_eq8_pushed_through_softmax(n: int, m: int, temperature: float) -> None:
    # Independent check of the paper's derivation: the rate of change of p = softmax(c/T)
    # when c moves along eq. (8), by central differences of the softmax, equals eq. (9).
    rng = np.random.default_rng(n * 10 + m)
    for _ in range(5):
        c = rng.normal(scale=2.0, size=(n, m))
        c_dot = coordination_field(c, temperature)
        h = 1e-6
        numeric = strategies(c + h * c_dot, temperature) - strategies(c - h * c_dot, temperature)
        numeric /= 2 * h
        np.testing.assert_allclose(
            strategy_field(strategies(c, temperature), temperature), numeric, atol=1e-9
        )


def test_reduced_coordinates_round_trip() -> None:
    p = np.random.default_rng(1).dirichlet(np.ones(4), size=3)
    p_bar = reduce_strategies(p)
    assert p_bar.shape == (9,)
    np.testing.assert_allclose(p_bar[3:6], p[1, :3])  # agent-major order
    np.testing.assert_allclose(expand_reduced(p_bar, 3), p, atol=1e-15)
    np.testing.assert_array_equal(optimum_point(3, 4, 1), [0, 1, 0] * 3)
    np.testing.assert_array_equal(optimum_point(3, 4, 3), [0, 0, 0] * 3)  # the last action


def test_jacobian_fd_on_a_known_function() -> None:
    # f(x, y) = (x^2 y, sin x + y) has Jacobian [[2xy, x^2], [cos x, 1]].
    def f(v: np.ndarray) -> np.ndarray:
        return np.array([v[0] ** 2 * v[1], math.sin(v[0]) + v[1]])

    x, y = 0.3, -1.2
    expected = [[2 * x * y, x**2], [math.cos(x), 1.0]]
    np.testing.assert_allclose(jacobian_fd(f, np.array([x, y])), expected, atol=1e-8)


@pytest.mark.parametrize(("n", "m"), SHAPES)
@pytest.mark.parametrize("temperature", TEMPERATURES)
def test_every_optimum_is_a_rest_point_with_jacobian_minus_two_over_t(
    n: int, m: int, temperature: float
) -> None:
    # Eq. (13), rederived by hand: near optimum k, for j != k the field is
    # (2/T) p_ij [-(p_ik^2 prod_{l != i} p_lk) + O(small)] ~ -(2/T) p_ij, and for j = k it is
    # (2/T) p_ik D_k (1 - p_ik) + O(2nd order) ~ (2/T)(1 - p_bar_ik), whose derivative in
    # p_bar_ik is -(2/T). Off-diagonal terms all carry a factor that vanishes at the vertex.
    for j in range(m):
        x = optimum_point(n, m, j)
        np.testing.assert_allclose(reduced_field(x, temperature, n), 0.0, atol=1e-15)
        jac = jacobian_fd(lambda v: reduced_field(v, temperature, n), x)
        np.testing.assert_allclose(jac, -(2 / temperature) * np.eye(n * (m - 1)), atol=1e-7)


def test_two_by_two_closed_form_and_line_of_equilibria() -> None:
    # For n = m = 2, eq. (9) simplifies by hand (x = p_bar_11, y = p_bar_21):
    # x' = (2/T) x (1-x) [xy - (1-x)(1-y)] = (2/T) x (1-x) (x + y - 1), same for y.
    temperature = 1.5
    rng = np.random.default_rng(3)
    for x, y in rng.uniform(size=(20, 2)):
        expected = (2 / temperature) * (x + y - 1) * np.array([x * (1 - x), y * (1 - y)])
        np.testing.assert_allclose(
            reduced_field(np.array([x, y]), temperature, 2), expected, atol=1e-14
        )
    # ... hence every point of x + y = 1 is an equilibrium, repelling transversally: the
    # Jacobian there is rank one, (2/T) (x(1-x), y(1-y))^T (1, 1), eigenvalues 0, (4/T) x (1-x).
    for x in (0.2, 0.5, 0.9):
        point = np.array([x, 1 - x])
        np.testing.assert_allclose(reduced_field(point, temperature, 2), 0.0, atol=1e-15)
        eig = np.sort(
            np.linalg.eigvals(jacobian_fd(lambda v: reduced_field(v, temperature, 2), point))
        )
        np.testing.assert_allclose(eig.real, [0.0, 4 / temperature * x * (1 - x)], atol=1e-7)


def test_two_by_two_basins_are_split_by_the_anti_diagonal() -> None:
    # The line x + y = 1 is invariant, so a start with x + y > 1 ends at optimum 0 (both play
    # action 1) and one with x + y < 1 at optimum 1.
    rng = np.random.default_rng(7)
    for _ in range(15):
        c0 = random_start(rng, 2, 2, 1.0)
        p0 = strategies(c0, 1.0)
        side = p0[0, 0] + p0[1, 0] - 1
        if abs(side) < 1e-3:
            continue
        assert classify(integrate(c0, 1.0)) == (0 if side > 0 else 1)


def test_agent_differences_in_c_are_invariant() -> None:
    # The right-hand side of eq. (8) does not depend on the agent, so c_i(t) - c_1(t) is
    # constant; in p-space, log(p_ij / p_im) - log(p_1j / p_1m) stays at its initial value.
    temperature = 0.8
    c0 = random_start(np.random.default_rng(5), 3, 3, temperature)
    _, ps = trajectory(c0, temperature)
    log_odds = np.log(ps[:, :, :-1] / ps[:, :, -1:])
    differences = log_odds - log_odds[:, :1, :]
    np.testing.assert_allclose(
        differences, np.broadcast_to(differences[0], differences.shape), atol=1e-6
    )
    assert classify(ps[-1]) is not None


def test_classify() -> None:
    assert classify(np.array([[0.9995, 0.0005], [0.9999, 0.0001]])) == 0
    assert classify(np.array([[0.0, 0.0, 1.0]] * 4)) == 2
    assert classify(np.array([[0.99, 0.01], [0.9999, 0.0001]])) is None  # not close enough
    assert classify(np.array([[1.0, 0.0], [0.0, 1.0]])) is None  # mismatched corner
    assert classify(np.array([[0.99, 0.01], [0.98, 0.02]]), tol=0.05) == 0


@pytest.mark.parametrize(("n", "m", "starts"), [(2, 2, 40), (3, 3, 30)])
def test_random_starts_reach_optima(n: int, m: int, starts: int) -> None:
    report = check_theorem1(n, m, 1.0, starts=starts, seed=11)
    assert sum(report.converged_to) + report.unconverged == starts
    assert len(report.converged_to) == m
    assert report.unconverged == 0  # reaching a non-optimal equilibrium has probability 0
    assert all(k > 0 for k in report.converged_to)  # by symmetry every basin is hit
    assert report.expected_eigenvalue == -2.0
    assert report.max_eigen_error < 1e-6
    assert report.jacobian_confirmed
    assert report.confirmed
    assert len(report.eigenvalues) == m
    assert all(len(row) == n * (m - 1) for row in report.eigenvalues)


def test_report_with_too_short_horizon_is_honest() -> None:
    # Starting near the uniform strategy, nothing reaches a vertex by t = 1e-3.
    report = check_theorem1(3, 3, 1.0, starts=5, t_end=1e-3)
    assert report.unconverged == 5
    assert report.converged_to == (0, 0, 0)
    assert report.jacobian_confirmed
    assert not report.confirmed


def test_same_seed_same_report_and_json() -> None:
    first = check_theorem1(3, 2, 2.0, starts=10, seed=4)
    second = check_theorem1(3, 2, 2.0, starts=10, seed=4)
    assert isinstance(first, StabilityReport)
    assert first == second
    data = json.loads(json.dumps(first.to_dict()))
    assert data["expected_eigenvalue"] == -1.0
    assert data["starts"] == 10
    assert data["confirmed"] is True
    assert sum(data["converged_to"]) + data["unconverged"] == 10
    with pytest.raises(AttributeError):
        first.starts = 3  # type: ignore[misc]


@pytest.mark.parametrize(
    ("kwargs", "parameter"),
    [
        ({"n_agents": 1}, "agents"),
        ({"n_agents": 2.5}, "agents"),
        ({"n_optima": 1}, "optima"),
        ({"temperature": -1.0}, "temperature"),
        ({"temperature": 0.0}, "temperature"),
        ({"temperature": math.inf}, "temperature"),
        ({"temperature": math.nan}, "temperature"),
        ({"starts": 0}, "starts"),
        ({"seed": -1}, "seed"),
        ({"t_end": 0.0}, "t_end"),
    ],
)
def test_bad_input_names_the_parameter(kwargs: dict[str, object], parameter: str) -> None:
    arguments: dict[str, object] = {"n_agents": 2, "n_optima": 2, "temperature": 1.0}
    arguments.update(kwargs)
    with pytest.raises(ValueError, match=parameter) as info:
        check_theorem1(**arguments)  # type: ignore[arg-type]
    assert "\n" not in str(info.value)
    assert info.value.parameter == parameter


def test_phase_portrait_writes_png(tmp_path) -> None:
    path = phase_portrait(tmp_path / "figures" / "phase.png", temperature=0.5, trajectories=4)
    assert path == tmp_path / "figures" / "phase.png"
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert path.stat().st_size > 10_000
