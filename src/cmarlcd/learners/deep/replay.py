"""The replay ring of B independent seeds, and its sampling with each seed's own stream.

Each seed has its own ring of ``capacity`` transitions (state, joint action, reward, next
state, the next state's legal actions where they are stored per transition, terminal) in
arrays with a leading seed axis. A side's view of its seed (:func:`seed_view`) is what its
compiled ``observe`` writes into (:func:`push` and :func:`push_row`). Integer states and
actions are stored in the smallest integer type that holds them (43 DSN states and 5
actions fit in int8), so the rows stay small.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from numba import njit

from cmarlcd.compiled import kernel


class Replay(NamedTuple):
    """Ring buffers of B seeds (or, as a seed's view, of one seed without the seed axis);
    row ``k`` of seed ``b`` is one transition."""

    state: np.ndarray
    """(B, capacity) integer states, or (B, capacity, n_features) feature vectors."""
    actions: np.ndarray
    reward: np.ndarray
    next_state: np.ndarray
    next_legal: np.ndarray
    """(B, capacity, n_agents, width), or (B, 0, 0, 0) where the learner keeps each
    state's masks itself (integer states)."""
    terminal: np.ndarray
    position: np.ndarray
    """Next row to write, per seed."""
    size: np.ndarray
    """Rows stored, per seed (at most the capacity)."""


def compact_int(largest: int) -> type:
    """The smallest signed integer type holding ``0..largest``."""
    for dtype in (np.int8, np.int16, np.int32):
        if largest <= np.iinfo(dtype).max:
            return dtype
    return np.int64


def new_ring(
    seeds: int,
    capacity: int,
    n_agents: int,
    width: int,
    n_states: int,
    n_features: int = 0,
    masks: bool | None = None,
) -> Replay:
    """Empty rings for ``seeds`` seeds: of feature vectors when ``n_features`` > 0, else
    of integer states in ``[0, n_states)``; with each transition's next masks when
    ``masks`` (default: for feature vectors only)."""
    actions = np.zeros((seeds, capacity, n_agents), compact_int(width - 1))
    if n_features:
        shape, dtype = (seeds, capacity, n_features), np.float32
    else:
        shape, dtype = (seeds, capacity), compact_int(n_states - 1)
    per_row = bool(n_features) if masks is None else masks
    next_legal = np.zeros((seeds, capacity, n_agents, width) if per_row else (seeds, 0, 0, 0), bool)
    return Replay(
        np.zeros(shape, dtype),
        actions,
        np.zeros((seeds, capacity), np.float32),
        np.zeros(shape, dtype),
        next_legal,
        np.zeros((seeds, capacity), np.bool_),
        np.zeros(seeds, np.int64),
        np.zeros(seeds, np.int64),
    )


def seed_view(ring: Replay, b: int) -> Replay:
    """Seed ``b``'s ring, as views (``position`` and ``size`` of one entry)."""
    return Replay(*(array[b] for array in ring[:6]), ring.position[b : b + 1], ring.size[b : b + 1])


@kernel
def push(ring, state: int, joint, reward: float, next_state: int, terminal: bool) -> None:
    """Append one transition of integer states to a seed's ring (the oldest overwritten
    when full)."""
    p = ring.position[0]
    ring.state[p], ring.next_state[p] = state, next_state
    ring.reward[p], ring.terminal[p] = reward, terminal
    for i in range(joint.shape[0]):
        ring.actions[p, i] = joint[i]
    ring.position[0] = (p + 1) % ring.state.shape[0]
    ring.size[0] = min(ring.size[0] + 1, ring.state.shape[0])


@kernel
def push_row(ring, obs, next_obs, next_legal, joint, reward: float, terminal: bool) -> None:
    """Append one transition of feature vectors to a seed's ring. A terminal
    transition's next state is never bootstrapped from: its features are stored as zeros
    and its masks all legal, so the target's maximum stays finite."""
    p = ring.position[0]
    for f in range(obs.shape[0]):
        ring.state[p, f] = obs[f]
        ring.next_state[p, f] = next_obs[f] if not terminal else 0.0
    for i in range(joint.shape[0]):
        ring.actions[p, i] = joint[i]
        for a in range(next_legal.shape[1]):
            ring.next_legal[p, i, a] = next_legal[i, a] if not terminal else True
    ring.reward[p], ring.terminal[p] = reward, terminal
    ring.position[0] = (p + 1) % ring.state.shape[0]
    ring.size[0] = min(ring.size[0] + 1, ring.state.shape[0])


@kernel
def push_visit(ring, state: int, joint, value: float) -> None:
    """Append one visit (integer state, joint action, a value such as its return) to a
    seed's ring; the transition fields are left as they are."""
    p = ring.position[0]
    ring.state[p], ring.reward[p] = state, value
    for i in range(joint.shape[0]):
        ring.actions[p, i] = joint[i]
    ring.position[0] = (p + 1) % ring.state.shape[0]
    ring.size[0] = min(ring.size[0] + 1, ring.state.shape[0])


@kernel
def push_visit_row(ring, obs, joint, value: float) -> None:
    """:func:`push_visit` of a visit given by its feature vector."""
    p = ring.position[0]
    for f in range(obs.shape[0]):
        ring.state[p, f] = obs[f]
    ring.reward[p] = value
    for i in range(joint.shape[0]):
        ring.actions[p, i] = joint[i]
    ring.position[0] = (p + 1) % ring.state.shape[0]
    ring.size[0] = min(ring.size[0] + 1, ring.state.shape[0])


def new_batch(ring: Replay, batch_size: int) -> Replay:
    """Room for one sampled batch of ``batch_size`` transitions per seed of ``ring``, in
    the types the TD step reads (integer states and actions as int64)."""
    seeds = ring.state.shape[0]
    state = (seeds, batch_size, *ring.state.shape[2:])
    integer = ring.state.ndim == 2
    masks = ring.next_legal.shape[2:] if ring.next_legal.shape[1] else (0, 0)
    return Replay(
        np.zeros(state, np.int64 if integer else ring.state.dtype),
        np.zeros((seeds, batch_size, ring.actions.shape[2]), np.int64),
        np.zeros((seeds, batch_size), np.float32),
        np.zeros(state, np.int64 if integer else ring.state.dtype),
        np.zeros((seeds, batch_size if ring.next_legal.shape[1] else 0, *masks), np.bool_),
        np.zeros((seeds, batch_size), np.bool_),
        np.zeros(seeds, np.int64),
        np.zeros(seeds, np.int64),
    )


@njit(cache=True)
def gather(ring, picks, out) -> None:
    """``out[b, n]`` := row ``picks[b, n]`` of seed b's ring, for every field."""
    for b in range(picks.shape[0]):
        rows = picks[b]
        copy_rows(ring.state[b], rows, out.state[b])
        copy_rows(ring.next_state[b], rows, out.next_state[b])
        copy_rows(ring.actions[b], rows, out.actions[b])
        copy_rows(ring.reward[b], rows, out.reward[b])
        copy_rows(ring.terminal[b], rows, out.terminal[b])
        if out.next_legal.shape[1] > 0:
            copy_rows(ring.next_legal[b], rows, out.next_legal[b])


@njit(cache=True)
def copy_rows(source, rows, target) -> None:
    """``target[n]`` := ``source[rows[n]]``, rows of any shape taken as flat runs of
    values: a row view per transition (``target[n] = source[k]``) would cost two atomic
    reference counts each, most of the gather's time."""
    flat_source = source.reshape((source.shape[0], -1))
    flat_target = target.reshape((target.shape[0], -1))
    width = flat_source.shape[1]
    for n in range(rows.shape[0]):
        k = rows[n]
        for f in range(width):
            flat_target[n, f] = flat_source[k, f]


def draw(ring: Replay, rngs: Sequence[np.random.Generator], batch_size: int) -> np.ndarray:
    """``batch_size`` stored rows per seed, uniformly with replacement, with seed b's
    generator ``rngs[b]`` (a seed with nothing stored draws nothing and gets row 0: its
    step is discarded)."""
    picks = np.zeros((len(rngs), batch_size), np.int64)
    for b, rng in enumerate(rngs):
        stored = int(ring.size[b])
        if stored:
            picks[b] = rng.integers(0, stored, batch_size)
    return picks


#: The fields of a sampled batch, as the TD step reads them.
BATCH_FIELDS = ("state", "actions", "reward", "next_state", "next_legal", "terminal")


def sample(ring: Replay, rngs: Sequence[np.random.Generator], batch_size: int) -> dict:
    """A batch of ``batch_size`` stored transitions per seed (:func:`draw`, :func:`gather`),
    keyed as the TD step reads them (``next_legal`` only where the ring stores masks)."""
    return rows_of(ring, draw(ring, rngs, batch_size))


def rows_of(ring: Replay, picks: np.ndarray) -> dict:
    """Rows ``picks`` (B, N) of each seed's ring, keyed as the TD step reads them."""
    out = new_batch(ring, picks.shape[1])
    gather(ring, picks, out)
    batch = dict(zip(BATCH_FIELDS, out[:6], strict=True))
    if not ring.next_legal.shape[1]:
        del batch["next_legal"]
    return batch


@kernel
def recompute_lambda_returns(ring, step_reward, values, gamma: float, lam: float) -> None:
    """Recompute the λ-returns of a seed's ring of visits (``ring.reward``) from the
    estimates ``values`` of each stored visit's state, oldest visit first: an episode's
    visits are pushed together, last step first, so a visit's successor is the visit
    pushed just before it, ``ring.terminal`` marks an episode's last step (its return is
    its reward, ``step_reward``) and ``G_t = r_t + γ ((1 - λ) V(s_{t+1}) + λ G_{t+1})``.
    The oldest visit, whose successor the ring has overwritten, keeps its return."""
    capacity, size = ring.reward.shape[0], ring.size[0]
    start = (ring.position[0] - size) % capacity
    g, successor_value = 0.0, 0.0
    for k in range(size):
        q = (start + k) % capacity
        if ring.terminal[q]:
            g = step_reward[q]
        elif k > 0:
            g = step_reward[q] + gamma * ((1.0 - lam) * successor_value + lam * g)
        else:
            g = ring.reward[q]
        ring.reward[q] = g
        successor_value = values[q]
