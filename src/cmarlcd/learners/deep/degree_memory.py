"""Deep CMARL-CD's keyed memory: Algorithm 2's tables, kept for the states met, that the
degree network is regressed to (compiled; no PyTorch here).

The memory holds, for each state it keeps, the record ``R_max(s)`` (a maximum, as in
the table) and the coordination degrees the table would hold there (the *targets*),
with the state's network input. After each episode its visits are folded in backwards
by the table's own rule (:func:`fold_episode`: eqs. 1 and 14-16, Algorithm 2 lines
13-19), once per visit; the degree network is then fitted to the memory, every kept
state alike (:func:`sample_memory`). So a tie moves a state's targets by ``delta`` once,
however often the network is fitted, and a record is a maximum: replaying a visit never
counts as news. (With ``expectile_record`` the record is instead a running expectile of
the state's returns, which one lucky draw does not set: :func:`record_after`.)

A state is found by its **key**: its index for integer states, a 64-bit hash of the
feature vector's 32-bit words otherwise (:func:`features_key`). The memory is a
set-associative table of ``capacity`` slots in sets of ``ways`` (the key's set is key mod
``capacity / ways``; with one way, the default, it is direct-mapped: slot = key mod
capacity). A state enters an empty way of its set, or else replaces the entry of its set
visited least recently (by the episodes folded in). With integer states and a capacity
of at least the number of states every state has its own slot and nothing is ever
replaced: the memory is then the tabular learner's table, and the network its
distillation.

A state not in the memory is compared with an estimate of its record (``estimates``:
``-inf`` under the table's rule, every first visit a new record; or a record network's
estimate), and a tie there (a return within ``tolerance`` of the estimate) starts from
the network's degrees (``bases``). At the default tolerance, the table's 1e-9, a return
ties an estimate only by accident: a state then enters the memory by beating its
estimate, as a new record (a reset), and the network carries over to states never met
through how it acts there.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from numba.extending import overload

from cmarlcd.compiled import kernel
from cmarlcd.learners.degree_rules import degree_step
from cmarlcd.learners.max_return import BELOW, RECORD, TIE, compare_return


class KeyedParams(NamedTuple):
    """The table's constants the fold reads (the deep config's)."""

    delta: float
    delta_reset: float
    c_init: float
    c_min: float
    c_max: float
    gamma: float
    tolerance: float
    estimate_unseen: bool
    """Whether a state not kept is compared with an estimate (else ``-inf``)."""
    keep_below: bool = False
    """Whether a state not kept whose return falls below its estimate still enters the
    memory: with that return as its record and the network's degrees, unmoved."""
    expectile_record: bool = False
    """Whether the record is a running expectile of the returns (else the maximum)."""
    expectile: float = 1.0
    """τ of the expectile record."""
    margin: float = 0.0
    """By how much a return must pass the expectile record to be a new one."""
    record_step: float = 0.0
    """How far a visit moves the expectile record towards its return."""
    estimate_once_kept: bool = False
    """Whether the estimate is read only once the memory keeps any state: an episode
    folded into an empty memory compares every state with ``-inf`` (the table's rule)."""
    unseen_tolerance: float = 0.0
    """Within how many spreads of the returns folded so far a state not kept ties its
    estimate (beyond them above, a new record); 0: ``tolerance``."""
    unseen_range: bool = False
    """Whether that spread is the returns' range (largest minus smallest), else their
    standard deviation."""


def keyed_params(config) -> KeyedParams:
    """The constants of deep CMARL-CD's ``config`` that the fold reads."""
    return KeyedParams(
        config.delta,
        config.delta_reset,
        config.c_init,
        config.c_min,
        config.c_max,
        config.gamma,
        config.tolerance,
        config.estimates_unseen,
        config.unseen_record == "estimate-kept",
        config.record == "expectile",
        config.expectile,
        config.margin,
        config.record_step,
        config.unseen_record == "estimate-once-kept",
        config.unseen_tolerance,
        config.unseen_spread == "range",
    )


class DegreeMemory(NamedTuple):
    """The keyed memory of B seeds (or, as a seed's view, of one seed without the seed
    axis); slot ``k`` of seed ``b`` is one state's entry."""

    key: np.ndarray
    """(B, capacity) uint64: the state's key (meaningful where ``filled``)."""
    filled: np.ndarray
    """(B, capacity) bool."""
    record: np.ndarray
    """(B, capacity) float64: ``R_max`` of the state."""
    target: np.ndarray
    """(B, capacity, n_agents, width) float32: the degrees the table would hold."""
    state: np.ndarray
    """(B, capacity) int64 state indices, or (B, capacity, n_features) float32 features:
    the network's input for the entry."""
    order: np.ndarray
    """(B, capacity) int64: the filled slots, in the order they were first filled."""
    visited: np.ndarray
    """(B, capacity) int64: the episode (of ``clock``) that last visited the entry; (B, 0)
    when direct-mapped, where nothing is chosen between ways."""
    size: np.ndarray
    """(B,) int64: slots filled."""
    clock: np.ndarray
    """(B,) int64: episodes folded in."""
    ways: np.ndarray
    """(B,) int64: slots per set (1: direct-mapped)."""
    returns: np.ndarray
    """(B, 5) float64: the count, mean and sum of squared deviations of the returns folded
    in (Welford's running moments), their smallest and largest: the spread that scales
    ``unseen_tolerance``."""


def new_memory(
    seeds: int, capacity: int, n_agents: int, width: int, n_features: int = 0, ways: int = 1
) -> DegreeMemory:
    """Empty memories of ``capacity`` slots (rounded up to a whole number of sets of
    ``ways``) for ``seeds`` seeds, of feature vectors when ``n_features`` > 0, else of
    state indices."""
    capacity = -(-capacity // ways) * ways
    state_shape = (seeds, capacity, n_features) if n_features else (seeds, capacity)
    return DegreeMemory(
        np.zeros((seeds, capacity), np.uint64),
        np.zeros((seeds, capacity), np.bool_),
        np.full((seeds, capacity), -np.inf),
        np.zeros((seeds, capacity, n_agents, width), np.float32),
        np.zeros(state_shape, np.float32 if n_features else np.int64),
        np.zeros((seeds, capacity), np.int64),
        np.zeros((seeds, capacity if ways > 1 else 0), np.int64),
        np.zeros(seeds, np.int64),
        np.zeros(seeds, np.int64),
        np.full(seeds, ways, np.int64),
        np.zeros((seeds, 5)),
    )


#: DegreeMemory's per-slot arrays (the rest are one entry per seed).
_SLOT_ARRAYS = 7


def memory_view(memory: DegreeMemory, b: int) -> DegreeMemory:
    """Seed ``b``'s memory, as views (``size``, ``clock`` and ``ways`` of one entry)."""
    return DegreeMemory(
        *(array[b] for array in memory[:_SLOT_ARRAYS]),
        *(array[b : b + 1] for array in memory[_SLOT_ARRAYS:]),
    )


@kernel
def features_key(x) -> np.uint64:
    """A float32 feature vector's key: FNV-1a over its 32-bit words, then MurmurHash3's
    64-bit finaliser. The finaliser matters: the slot is the key modulo the capacity, and
    without it the key's low bits depend only on the words' low bits, which are zero for
    features such as 0 and 1 (65,536 distinct 0/1-like vectors fell into 625 slots of
    40,000)."""
    h = np.uint64(14695981039346656037)
    prime = np.uint64(1099511628211)
    bits = x.view(np.uint32)
    for f in range(bits.shape[0]):
        h = (h ^ np.uint64(bits[f])) * prime
    h ^= h >> np.uint64(33)
    h *= np.uint64(0xFF51AFD7ED558CCD)
    h ^= h >> np.uint64(33)
    h *= np.uint64(0xC4CEB9FE1A85EC53)
    h ^= h >> np.uint64(33)
    return h


def put_input(state: np.ndarray, slot: int, inputs: np.ndarray, t: int) -> None:
    """``state[slot]`` := ``inputs[t]``: a state index, or a feature vector copied entry
    by entry (compiled kernels copy no array slices)."""
    state[slot] = inputs[t]


@overload(put_input, jit_options={"cache": True})
def _put_input(state, slot, inputs, t):
    if state.ndim == 1:
        return lambda state, slot, inputs, t: _put_scalar(state, slot, inputs, t)
    return lambda state, slot, inputs, t: _put_row(state, slot, inputs, t)


@kernel
def _put_scalar(state, slot, inputs, t) -> None:
    state[slot] = inputs[t]


@kernel
def _put_row(state, slot, inputs, t) -> None:
    for f in range(state.shape[1]):
        state[slot, f] = inputs[t, f]


@kernel
def key_set(memory, key) -> np.uint64:
    """The set ``key``'s entry lives in (key mod the number of sets)."""
    return key % np.uint64(memory.key.shape[0] // memory.ways[0])


@kernel
def find(memory, key) -> int:
    """The slot holding ``key``'s entry, or -1."""
    ways = memory.ways[0]
    first = np.int64(key_set(memory, key)) * ways
    for slot in range(first, first + ways):
        if memory.filled[slot] and memory.key[slot] == key:
            return slot
    return -1


@kernel
def claim(memory, key) -> int:
    """A slot of ``key``'s set given to it (``key`` not kept): the first empty way, else
    the way visited least recently (first of them on a tie), whose entry is dropped."""
    ways = memory.ways[0]
    first = np.int64(key_set(memory, key)) * ways
    slot = first
    for way in range(first, first + ways):
        if not memory.filled[way]:
            slot = way
            break
        if ways > 1 and memory.visited[way] < memory.visited[slot]:
            slot = way
    if not memory.filled[slot]:
        memory.filled[slot] = True
        memory.order[memory.size[0]] = slot
        memory.size[0] += 1
    memory.key[slot] = key
    return slot


@kernel
def mark_visited(memory, slot: int) -> None:
    """Stamp ``slot``'s entry with the present episode (sets of several ways only)."""
    if memory.ways[0] > 1:
        memory.visited[slot] = memory.clock[0]


@kernel
def may_be_missing(memory, keys, length: int, t: int) -> bool:
    """Whether visit ``t``'s state (of an episode of ``length`` visits keyed ``keys``)
    may be missing from the memory when :func:`fold_episode` reaches it: it is not kept
    now, or another state of the episode shares its set (the fold's claims are the only
    changes it makes to which states are kept). Only such visits need the network's
    degrees and record estimate."""
    if find(memory, keys[t]) < 0:
        return True
    home = key_set(memory, keys[t])
    for u in range(length):  # noqa: SIM110 (compiled: a loop, not any() of a generator)
        if keys[u] != keys[t] and key_set(memory, keys[u]) == home:
            return True
    return False


@kernel
def classify_return(g: float, best: float, params) -> int:
    """Eq. (16) against a state's record ``best``: with the maximum, RECORD above it by
    more than ``tolerance``, TIE within it, else BELOW (the table's
    :func:`~cmarlcd.learners.max_return.compare_return`); with the expectile record a
    new record must pass it by more than ``margin``."""
    if not params.expectile_record:
        return compare_return(g, best, params.tolerance)
    if g > best + params.margin:
        return RECORD
    if abs(g - best) <= params.tolerance:
        return TIE
    return BELOW


@kernel
def count_return(moments, g: float) -> None:
    """Fold return ``g`` into the running ``(count, mean, M2, smallest, largest)``
    (Welford's moments)."""
    moments[3] = g if moments[0] == 0.0 else min(moments[3], g)
    moments[4] = g if moments[0] == 0.0 else max(moments[4], g)
    moments[0] += 1.0
    shift = g - moments[1]
    moments[1] += shift / moments[0]
    moments[2] += shift * (g - moments[1])


@kernel
def unseen_tolerance(memory, params) -> float:
    """The tolerance a state not kept is compared with its estimate by: ``tolerance``,
    or ``unseen_tolerance`` spreads of the returns folded so far (their standard
    deviation, or with ``unseen_range`` their range) where that is larger."""
    moments = memory.returns[0]
    if params.unseen_range:
        spread = moments[4] - moments[3]
    else:
        spread = np.sqrt(moments[2] / moments[0]) if moments[0] > 1.0 else 0.0
    return max(params.tolerance, params.unseen_tolerance * spread)


@kernel
def classify_unseen(g: float, estimate: float, memory, params) -> int:
    """Eq. (16) for a state not kept, against ``estimate``: as :func:`classify_return`,
    or, with ``unseen_tolerance``, a tie within that many spreads of the returns folded
    so far and a new record beyond them above."""
    if params.unseen_tolerance <= 0.0:
        return classify_return(g, estimate, params)
    return compare_return(g, estimate, unseen_tolerance(memory, params))


@kernel
def record_after(best: float, g: float, outcome: int, params) -> float:
    """A state's record after a visit of return ``g`` classified ``outcome`` against its
    record ``best``: the maximum becomes ``g`` on a new record and stays otherwise; the
    expectile record (``-inf`` before the first visit: then ``g``) moves towards ``g`` by
    ``record_step * w * (g - best)``, ``w = expectile`` above it, ``1 - expectile``
    below."""
    if not params.expectile_record:
        return g if outcome == RECORD else best
    if best == -np.inf:
        return g
    weight = params.expectile if g > best else 1.0 - params.expectile
    return best + params.record_step * weight * (g - best)


@kernel
def fold_episode(
    memory, keys, inputs, bases, estimates, joints, rewards, counts, length: int, params
) -> None:
    """Fold an episode of ``length`` visits into the memory, backwards (Algorithm 2,
    lines 13-19): visit ``t`` (key ``keys[t]``, network input ``inputs[t]``, joint action
    ``joints[t]``, followed by ``rewards[t]``) has return ``G_t = r + γ G_{t+1}`` (eq. 1),
    compared (eq. 16, :func:`classify_return`) with the state's record, or with
    ``estimates[t]`` for a state not in the memory. A new record resets the targets; a
    tie moves them by ``delta`` (eqs. 14-15); a lower return leaves them. The record
    then follows :func:`record_after` (the maximum is raised by a new record only; the
    expectile record moves at every visit). A state entering the memory starts from the
    network's degrees at the visit, ``bases[t]`` (n_agents, width), clipped to
    ``[c_min, c_max]``; with
    ``keep_below`` a state not kept whose return falls below its estimate enters too,
    with that return as its record and those degrees unmoved. With
    ``estimate_once_kept`` an episode folded into an empty memory reads no estimate:
    each of its states is compared with ``-inf``, as the table's first visit is. With
    ``unseen_tolerance`` a state not kept ties its estimate within that many standard
    deviations of the returns folded before the visit (:func:`classify_unseen`)."""
    g = 0.0
    memory.clock[0] += 1
    unseen_floor = params.estimate_once_kept and memory.size[0] == 0
    for t in range(length - 1, -1, -1):
        g = rewards[t] + params.gamma * g
        slot = find(memory, keys[t])
        if slot >= 0:
            mark_visited(memory, slot)
        estimate = -np.inf if unseen_floor else estimates[t]
        best = memory.record[slot] if slot >= 0 else estimate
        if slot >= 0:
            outcome = classify_return(g, best, params)
        else:
            outcome = classify_unseen(g, best, memory, params)
        count_return(memory.returns[0], g)
        if slot >= 0:
            memory.record[slot] = record_after(best, g, outcome, params)
        if outcome == BELOW and (slot >= 0 or not params.keep_below):
            continue
        if slot < 0:
            slot = claim(memory, keys[t])
            mark_visited(memory, slot)
            put_input(memory.state, slot, inputs, t)
            memory.record[slot] = g if outcome == BELOW else record_after(best, g, outcome, params)
            for i in range(counts.shape[0]):
                for a in range(counts[i]):
                    memory.target[slot, i, a] = min(max(bases[t, i, a], params.c_min), params.c_max)
        if outcome == BELOW:
            continue
        for i in range(counts.shape[0]):
            degree_step(memory.target[slot, i], counts[i], joints[t, i], outcome == RECORD, params)


def sample_memory(
    memory: DegreeMemory, rngs: Sequence[np.random.Generator], batch_size: int
) -> dict[str, np.ndarray]:
    """``batch_size`` kept states per seed, uniformly with replacement over the filled
    slots, with seed b's generator ``rngs[b]``: ``state``, ``target`` (their degrees) and
    ``record`` (float32). A seed with nothing kept draws nothing and gets slot 0."""
    picks = np.zeros((len(rngs), batch_size), np.int64)
    for b, rng in enumerate(rngs):
        kept = int(memory.size[b])
        if kept:
            picks[b] = memory.order[b, rng.integers(0, kept, batch_size)]
    seeds = np.arange(len(rngs))[:, None]
    return {
        "state": memory.state[seeds, picks],
        "target": memory.target[seeds, picks],
        "record": np.where(memory.filled[seeds, picks], memory.record[seeds, picks], 0.0).astype(
            np.float32
        ),
    }
