"""LA-OCA, the learning-automata baseline (ref. [23] of the paper), as a documented stand-in.

The paper gives no update rule for LA-OCA and its reference is not openly available.
[choice] (SPEC §3) Per state, each agent runs a linear reward-inaction automaton driven
by the same max-return indicator as CMARL-CD: when the return from a state reaches the
best seen from it, the action taken is rewarded,

    p(s, a_t) += λ (1 - p(s, a_t)),    p(s, a) *= (1 - λ)  for every other legal a,

otherwise nothing changes. Initial strategies are uniform over the legal actions;
execution takes ``argmax p``. Reported beside the paper's published LA-OCA row.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def automaton_rule(
    p_row: np.ndarray, legal_row: np.ndarray, count: int, action: int, rate: float
) -> None:
    """Linear reward-inaction step of rate ``λ`` towards ``action`` (SPEC §3)."""
    for a in range(count):
        if a == action:
            p_row[a] += rate * (1.0 - p_row[a])
        elif legal_row[a]:
            p_row[a] *= 1.0 - rate


@njit(cache=True)
def uniform_strategy(legal_row: np.ndarray, count: int, p_row: np.ndarray) -> None:
    """The automaton's initial strategy: uniform over the legal actions."""
    n_legal = 0
    for a in range(count):
        n_legal += legal_row[a]
    for a in range(count):
        p_row[a] = 1.0 / n_legal if legal_row[a] else 0.0
