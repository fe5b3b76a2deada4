"""Repeated games as one-state games of the compiled protocol (:mod:`cmarlcd.games.spec`).

A repeated game is a single step: every agent acts, all receive the payoff of the joint
action, and the episode ends. Its state arrays are ``env = (flat_payoffs, strides,
counts)``: the payoff tensor flattened in C order, the element strides that address it
and each agent's action count. There is one state (index 0) and every action is legal.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from cmarlcd.compiled import kernel


@njit(cache=True)
def flat_index(joint: np.ndarray, strides: np.ndarray) -> int:
    """Position of ``joint`` in a C-order flattened payoff tensor."""
    index = 0
    for i in range(joint.shape[0]):
        index += joint[i] * strides[i]
    return index


@kernel
def env_reset(env, rng) -> None:
    """Protocol ``reset``: a repeated game has nothing to reset."""


@kernel
def env_step(env, joint: np.ndarray, rng, rewards: np.ndarray) -> None:
    """Protocol ``step``: the payoff of ``joint``, the global reward of the one team."""
    rewards[0] = env[0][flat_index(joint, env[1])]


@kernel
def env_state(env, team: int) -> int:
    """Protocol ``state``: the one state."""
    return 0


@kernel
def env_done(env) -> bool:
    """Protocol ``done``: every play is a whole episode."""
    return True


@kernel
def env_legal(env, masks: np.ndarray) -> None:
    """Protocol ``legal``: every action is legal."""
    counts = env[2]
    for i in range(counts.shape[0]):
        for a in range(masks.shape[1]):
            masks[i, a] = a < counts[i]
