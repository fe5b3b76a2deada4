"""Replay buffers of B independent seeds, stored compactly and sampled in compiled code.

Each seed has its own ring of ``capacity`` transitions (state, joint action, reward, next
state, terminal) in arrays with a leading seed axis. States and actions are stored in
the smallest integer type that holds them (43 DSN states and 5 actions fit in int8), so
the random reads of replay sampling stay in cache.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit


class ReplayBuffers(NamedTuple):
    """Ring buffers of B seeds; row ``k`` of seed ``b`` is one transition."""

    state: np.ndarray
    actions: np.ndarray
    reward: np.ndarray
    next_state: np.ndarray
    terminal: np.ndarray
    position: np.ndarray
    """Next row to write, per seed."""
    size: np.ndarray
    """Rows stored, per seed (at most the capacity)."""


class Batch(NamedTuple):
    """Sampled transitions, ``(B, batch_size, ...)``, as the TD step reads them."""

    state: np.ndarray
    actions: np.ndarray
    reward: np.ndarray
    next_state: np.ndarray
    terminal: np.ndarray


def compact_int(largest: int) -> type:
    """The smallest signed integer type holding ``0..largest``."""
    for dtype in (np.int8, np.int16, np.int32):
        if largest <= np.iinfo(dtype).max:
            return dtype
    return np.int64


def new_buffers(
    seeds: int, capacity: int, n_agents: int, n_states: int, width: int
) -> ReplayBuffers:
    """Empty buffers for ``seeds`` seeds of ``n_agents`` agents."""
    states, actions = compact_int(n_states - 1), compact_int(width - 1)
    return ReplayBuffers(
        np.zeros((seeds, capacity), states),
        np.zeros((seeds, capacity, n_agents), actions),
        np.zeros((seeds, capacity), np.float32),
        np.zeros((seeds, capacity), states),
        np.zeros((seeds, capacity), np.bool_),
        np.zeros(seeds, np.int64),
        np.zeros(seeds, np.int64),
    )


def new_batch(seeds: int, batch_size: int, n_agents: int) -> Batch:
    """Room for one sampled batch per seed."""
    return Batch(
        np.empty((seeds, batch_size), np.int64),
        np.empty((seeds, batch_size, n_agents), np.int64),
        np.empty((seeds, batch_size), np.float32),
        np.empty((seeds, batch_size), np.int64),
        np.empty((seeds, batch_size), np.bool_),
    )


@njit(cache=True)
def store(
    buffer, b: int, state: int, joint, reward: float, next_state: int, terminal: bool
) -> None:
    """Append one transition to seed ``b``'s ring (overwriting the oldest when full)."""
    p = buffer.position[b]
    buffer.state[b, p], buffer.reward[b, p], buffer.terminal[b, p] = state, reward, terminal
    buffer.actions[b, p] = joint
    buffer.next_state[b, p] = next_state
    buffer.position[b] = (p + 1) % buffer.state.shape[1]
    buffer.size[b] = min(buffer.size[b] + 1, buffer.state.shape[1])


@njit(cache=True)
def replay_sample(buffer, rngs, batch_size: int, out) -> None:
    """Draw ``batch_size`` stored transitions per seed, uniformly with replacement, with
    seed b's generator ``rngs[b]`` (the same draws as ``rngs[b].integers(0, size,
    batch_size)`` in NumPy), into ``out`` (a :class:`Batch`)."""
    for b in range(buffer.state.shape[0]):
        picks = rngs[b].integers(0, buffer.size[b], batch_size)
        for n in range(batch_size):
            k = picks[n]
            out.state[b, n], out.next_state[b, n] = buffer.state[b, k], buffer.next_state[b, k]
            out.reward[b, n], out.terminal[b, n] = buffer.reward[b, k], buffer.terminal[b, k]
            out.actions[b, n] = buffer.actions[b, k]
