"""Acting from per-agent tables: sampling a joint action and the greedy joint action.

Shared by every tabular learner. Rows are padded to the largest action count;
``counts[i]`` says how many entries of agent ``i``'s row are real, and a ``legal`` mask
(same shape as the table) marks the actions allowed in the current state. Illegal
actions carry probability 0 and are never chosen.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from cmarlcd.compiled import kernel


@njit(cache=True)
def sample_action(p_row: np.ndarray, count: int, u: float) -> int:
    """Inverse-CDF draw from ``p_row[:count]`` with ``u ~ U[0, 1)``.

    If rounding leaves ``u`` above the last partial sum, the last action with positive
    probability is returned (never a zero-probability, e.g. illegal, action).
    """
    acc = 0.0
    last = 0
    for a in range(count):
        if p_row[a] > 0.0:
            acc += p_row[a]
            last = a
            if u < acc:
                return a
    return last


@njit(cache=True)
def sample_joint_action(p: np.ndarray, counts: np.ndarray, rng, joint: np.ndarray) -> None:
    """Every agent draws ``a_i ~ p_i``, one uniform each, in agent order."""
    for i in range(counts.shape[0]):
        joint[i] = sample_action(p[i], counts[i], rng.random())


@kernel
def sample_from_strategies(
    tables, params, s: int, counts: np.ndarray, rng, joint: np.ndarray
) -> None:
    """The tabular protocol's ``act`` for learners that keep their strategies in
    ``tables.probs``: every agent samples ``a_i ~ p_i(s)``."""
    sample_joint_action(tables.probs[s], counts, rng, joint)


@njit(cache=True)
def softmax_strategy(
    c_row: np.ndarray, legal_row: np.ndarray, count: int, temperature: float, p_row: np.ndarray
) -> None:
    """``p = softmax(c / T)`` over the legal actions (others get 0): CMARL-CD's eqs. (5)
    and (17), and the Boltzmann exploration of the classic learners."""
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
def annealed(start: float, end: float, steps: float, done: float) -> float:
    """A setting annealed linearly from ``start`` to ``end`` over ``steps`` (``done`` of
    them taken), ``end`` after them; ``start`` itself, unchanged, where ``steps`` is 0."""
    if steps <= 0:
        return start
    return start + (end - start) * min(1.0, done / steps)


@njit(cache=True)
def greedy_action(values_row: np.ndarray, legal_row: np.ndarray, count: int) -> int:
    """``argmax`` of ``values_row`` over the legal actions, lowest index on ties."""
    best = -1
    for a in range(count):
        if legal_row[a] and (best < 0 or values_row[a] > values_row[best]):
            best = a
    return best


@njit(cache=True)
def annealed_epsilon(
    episode: int, total: int, start: float, end: float, fraction: float, after: float
) -> float:
    """Eq. (18): ε of the ``episode``-th (1-based) of ``total`` learning episodes.

    Linear from ``start`` towards ``end`` over the first ``fraction · total`` episodes,
    then ``after``.
    """
    anneal = fraction * total
    if episode <= anneal:
        return start - (start - end) * episode / anneal
    return after


@njit(cache=True)
def uniform_legal_action(legal_row: np.ndarray, count: int, u: float) -> int:
    """The ``floor(u * k)``-th of the ``k`` legal actions, ``u ~ U[0, 1)``: a uniform
    draw (with every action legal, simply ``floor(u * count)``)."""
    n_legal = 0
    for a in range(count):
        n_legal += legal_row[a]
    pick = int(u * n_legal)
    for a in range(count):
        if legal_row[a]:
            if pick == 0:
                return a
            pick -= 1
    return -1


@njit(cache=True)
def epsilon_greedy(
    values: np.ndarray,
    legal: np.ndarray,
    counts: np.ndarray,
    epsilon: float,
    rng,
    joint: np.ndarray,
) -> None:
    """Each agent independently: with probability ε a uniform legal action, else its
    greedy legal action (``values[i]``: agent i's action values in the state)."""
    for i in range(counts.shape[0]):
        if rng.random() < epsilon:
            joint[i] = uniform_legal_action(legal[i], counts[i], rng.random())
        else:
            joint[i] = greedy_action(values[i], legal[i], counts[i])
