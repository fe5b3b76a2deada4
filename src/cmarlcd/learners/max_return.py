"""The max-return indicator shared by CMARL-CD (Algorithm 2) and the LA-OCA stand-in.

Both learners keep ``R_max(s)``, the largest discounted return ever observed from state
``s`` (shared by the agents: the reward is global, so they would all hold the same value).
After each episode the recorded steps are processed backwards ([choice] every
visit): ``G_t = r_{t+1} + γ G_{t+1}`` (eq. 1) is compared with ``R_max(s_t)`` (eq. 16,
equality within a tolerance), and unless it falls below, the learner's per-state rule is
applied to the action each agent took at ``s_t``. The indicator's part of each step of
that pass is :func:`visit`, written once; each learner walks its episode with its rule.

A learner using it keeps ``r_max`` in its tables and ``gamma`` and ``tolerance`` in its
parameters.
"""

from __future__ import annotations

from numba import njit

from cmarlcd.errors import check_discount, check_tolerance

BELOW, TIE, RECORD = 0, 1, 2


def check_gamma_tolerance(gamma: float, tolerance: float) -> None:
    """Validate the discount of eq. (1) and the tie tolerance of eq. (16)."""
    check_discount(gamma)
    check_tolerance(tolerance)


@njit(cache=True)
def compare_return(g: float, best: float, tolerance: float) -> int:
    """Eq. (16) with ties within ``tolerance``: RECORD, TIE or BELOW."""
    if g > best + tolerance:
        return RECORD
    if g >= best - tolerance:
        return TIE
    return BELOW


@njit(cache=True)
def visit(r_max, params, s: int, reward: float, later_return: float) -> tuple[float, int]:
    """One step of the backward pass (Algorithm 2, lines 13-17), for the visit of state
    ``s`` followed by ``reward``: its return ``G_t = r_{t+1} + γ G_{t+1}`` (eq. 1, with
    ``later_return`` = ``G_{t+1}``) and how it compares with ``R_max(s)`` (eq. 16):
    RECORD (``R_max(s)`` is raised to ``G_t``), TIE or BELOW.

    A learner walks its episode backwards, ``g = 0`` after the last step::

        for t in range(length - 1, -1, -1):
            g, outcome = visit(r_max, params, states[t], rewards[t], g)
            if outcome != BELOW: ...its rule for every agent at states[t]...
    """
    g = reward + params.gamma * later_return  # eq. (1)
    outcome = compare_return(g, r_max[s], params.tolerance)
    if outcome == RECORD:
        r_max[s] = g
    return g, outcome
