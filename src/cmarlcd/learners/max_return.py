"""The max-return indicator shared by CMARL-CD (Algorithm 2) and the LA-OCA stand-in.

Both learners keep ``R_max(s)``, the largest discounted return ever observed from state
``s`` (shared by the agents: the reward is global, so they would all hold the same value).
After each episode the recorded steps are processed backwards (SPEC §2, [choice] every
visit): ``G_t = r_{t+1} + γ G_{t+1}`` (eq. 1) is compared with ``R_max(s_t)`` (eq. 16,
equality within a tolerance), and unless it falls below, the learner's per-state rule is
applied to the action each agent took at ``s_t``. The indicator's part of that pass is
:func:`record_outcomes`, written once; each learner walks the outcomes with its own rule.

A learner using it keeps ``r_max`` in its tables and ``gamma`` and ``tolerance`` in its
parameters.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from cmarlcd.errors import require
from cmarlcd.learners.tabular import TabularLearner

BELOW, TIE, RECORD = 0, 1, 2


def check_gamma_tolerance(gamma: float, tolerance: float) -> None:
    """Validate the discount of eq. (1) and the tie tolerance of eq. (16)."""
    require(
        bool(np.isfinite(gamma)) and 0 < gamma <= 1, "gamma", f"must be in (0, 1] (got {gamma})"
    )
    require(tolerance >= 0, "tolerance", f"must be >= 0 (got {tolerance})")


@njit(cache=True)
def compare_return(g: float, best: float, tolerance: float) -> int:
    """Eq. (16) with ties within ``tolerance``: RECORD, TIE or BELOW."""
    if g > best + tolerance:
        return RECORD
    if g >= best - tolerance:
        return TIE
    return BELOW


@njit(cache=True)
def record_outcomes(r_max, params, states, rewards, length, outcomes) -> None:
    """Algorithm 2, lines 13-17: the backward every-visit pass over one episode.

    ``states[t]`` and ``rewards[t]`` are the state and the reward ``r_{t+1}`` that
    followed, for ``t < length``. Going backwards, ``G_t = r_{t+1} + γ G_{t+1}`` (eq. 1)
    is compared with ``R_max(s_t)`` (eq. 16): ``outcomes[t]`` is RECORD (``R_max(s_t)``
    is raised to ``G_t``), TIE or BELOW. The learner then applies its rule to every
    visit that is not BELOW, in the same backward order (its rule never changes
    ``R_max``, so the outcomes do not depend on it).
    """
    g = 0.0
    for t in range(length - 1, -1, -1):
        g = rewards[t] + params.gamma * g  # eq. (1)
        s = states[t]
        outcomes[t] = compare_return(g, r_max[s], params.tolerance)
        if outcomes[t] == RECORD:
            r_max[s] = g


class MaxReturnLearner(TabularLearner):
    """The object API of a learner driven by the max-return indicator."""

    def max_return(self, state) -> float:
        """``R_max(state)``: the best discounted return seen from it (``-inf`` if unseen)."""
        row = self._lookup(state)
        return -np.inf if row is None else float(self.tables.r_max[row])
