"""The compiled side kernels of VDN and QMIX (``[deep]`` extra, no PyTorch here): what the
loop of :mod:`cmarlcd.training.loop` calls on a deep side
(:mod:`cmarlcd.training.deep_side`), for its two kinds of input.

* **features**: the agent networks' forward pass, compiled over a copy of their weights
  (:func:`greedy_agent`), on the game's feature vector of each turn;
* **index**: a copy of the networks' Q-values of every state, looked up by state index.

Either way the side acts ε-greedily (eq. 18, annealed over its learning episodes),
appends each turn to its replay ring, and pauses the loop every ``train_every`` turns.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from cmarlcd.compiled import Unbound, kernel, specialise_kernel
from cmarlcd.errors import require
from cmarlcd.games.spec import GameSpec
from cmarlcd.learners.deep.config import STEPS_UNIT, TRAIN_EVERY_ENTRY
from cmarlcd.learners.deep.replay import Replay, push, push_row
from cmarlcd.learners.policy import (
    annealed_epsilon,
    epsilon_greedy,
    greedy_action,
    uniform_legal_action,
)
from cmarlcd.training.protocol import SideKernels

game = Unbound("game")

#: Entries of a deep side's ``counters``: turns observed, episodes finished, the turns
#: observed when the loop last paused for it, whether it met a state for the first time
#: since its group last looked (index inputs), and how many times its weights have been
#: copied from the networks (the generation its greedy cache is valid for), and whether
#: the last turn it observed ended in a terminal state (1) or not (0: an episode that
#: ended there was cut at ``max_steps``; deep CMARL-CD's sides keep it).
TURNS, EPISODES, PAUSED_AT, NEW_STATES, GENERATION, ENDED_TERMINAL = range(6)
#: Slots of a deep side's cache of greedy actions (:class:`GreedyCache`; a power of 2,
#: 0.6 MB a side). A cache changes no action, only how often the networks are
#: evaluated: fixed greedy strategies meet the same few thousand battlefield states over
#: and over (every episode starts in the same one); ``benchmarks/bench_battlefield.py``
#: prints how many each deep side holds after an evaluation (800 to 5,300 in 5,000
#: episodes).
GREEDY_CACHE_SLOTS = 2**14
#: Fibonacci hashing of a state index into the cache's slots.
HASH_MULTIPLIER = np.uint64(0x9E3779B97F4A7C15)
HASH_SHIFT = np.uint64(40)
#: The inputs a deep side can read, by name.
INPUTS = ("features", "index")
#: [choice] The most states a deep side reads as one-hot indices (its Q-table copy holds
#: every state): a larger game needs state features.
MAX_INDEX_STATES = 100_000


class Weights(NamedTuple):
    """A copy of the agent networks' parameters, agent-major (float32)."""

    w1: np.ndarray
    """(n_agents, n_features, hidden)"""
    b1: np.ndarray
    """(n_agents, hidden)"""
    w2: np.ndarray
    """(n_agents, hidden, width)"""
    b2: np.ndarray
    """(n_agents, width)"""
    wm: np.ndarray
    """(n_agents, layers - 1, hidden, hidden): the hidden layers after the first
    (``hidden_layers``; empty along its second axis for one hidden layer)"""
    bm: np.ndarray
    """(n_agents, layers - 1, hidden)"""


class GreedyCache(NamedTuple):
    """The greedy actions a deep side computed at the states it met, kept while its
    weights stay those of one generation (``counters[GENERATION]``), where the game's
    state determines its features and masks (``GameSpec.state_determines_features``;
    elsewhere the arrays are empty and every action comes from the networks). A slot
    holds one state at a time (the last one hashed there)."""

    keys: np.ndarray
    """(slots,) int64: the state each slot holds (-1: none yet)."""
    generations: np.ndarray
    """(slots,) int64: the weights' generation it was computed with."""
    actions: np.ndarray
    """(slots, n_agents) int32: each agent's greedy action there (-1: not computed)."""
    states: np.ndarray
    """(max_steps + 1,) int64: the learning episode's state index at each turn."""


class FeatureData(NamedTuple):
    """A deep side reading feature vectors: its arrays, as its kernels read them."""

    counts: np.ndarray
    weights: Weights
    hidden: np.ndarray
    """Scratch: one agent's hidden layer (float32)."""
    obs: np.ndarray
    """The episode so far: each turn's features, (max_steps + 2, n_features), the last
    row the greedy evaluation's own (it may run between two turns of a learning episode)
    ..."""
    legal: np.ndarray
    """... its legal actions, (max_steps + 1, n_agents, width) ..."""
    joints: np.ndarray
    rewards: np.ndarray
    replay: Replay
    counters: np.ndarray
    schedule: np.ndarray
    """The learner's constants (``DeepLearnerConfig.schedule``: VDN's and QMIX's ε
    schedule (start, end, anneal fraction, after), learning episodes, train_every)."""
    scratch: np.ndarray
    """(2, width) floats a learner's kernels may use as they like."""
    cache: GreedyCache
    """The greedy actions computed so far (VDN and QMIX)."""
    starts: np.ndarray
    """(n_agents,) int64: the first feature each agent's network reads (0 where it reads
    them all; its own observation's where the game lays them out, ``GameSpec.own_dim``)."""


class IndexData(NamedTuple):
    """A deep side reading state indices: its arrays, as its kernels read them."""

    counts: np.ndarray
    values: np.ndarray
    """(n_states, n_agents, width): the agent networks' Q-values of every state."""
    legal: np.ndarray
    """(n_states, n_agents, width): each state's masks, read on its first visit (every
    action legal before)."""
    seen: np.ndarray
    """The states met so far."""
    obs: np.ndarray
    """The episode so far: each turn's state ..."""
    joints: np.ndarray
    rewards: np.ndarray
    replay: Replay
    counters: np.ndarray
    schedule: np.ndarray
    scratch: np.ndarray


# ------------------------------------------------------------ shared kernels


@kernel
def deep_fits(side, max_steps: int) -> bool:
    """A deep side's memory does not grow with the states it sees."""
    return True


@kernel
def deep_end_episode(side, length: int) -> None:
    side.counters[EPISODES] += 1


@kernel
def deep_pause(side) -> bool:
    """Stop the loop every ``train_every`` turns, for the gradient step."""
    return side.counters[TURNS] - side.counters[PAUSED_AT] >= side.schedule[TRAIN_EVERY_ENTRY]


@kernel
def exploration(side) -> float:
    """ε of the side's current learning episode (eq. 18), or of its current learning
    turn where its exploration counts environment steps (the schedule's last entry),
    over the length of the schedule's entry 4 (L, or the steps ε anneals over)."""
    s = side.schedule
    done = side.counters[TURNS] if s[s.shape[0] - 1] == STEPS_UNIT else side.counters[EPISODES]
    return annealed_epsilon(done + 1, int(s[4]), s[0], s[1], s[2], s[3])


# ---------------------------------------------------------- feature inputs


@kernel
def hidden_layer(weights, agent: int, x, hidden) -> None:
    """``hidden`` := ReLU(x W1 + b1) of agent ``agent`` (:func:`hidden_layer_at` the
    whole of ``x``)."""
    hidden_layer_at(weights, agent, x, 0, hidden)


@kernel
def hidden_layer_at(weights, agent: int, x, lo: int, hidden) -> None:
    """``hidden`` := ReLU(x[lo : lo + d] W1 + b1) of agent ``agent`` (``d``: its
    network's inputs, the whole feature vector or its own observation), in float32 as
    the networks compute it (``hidden`` is a float32 scratch), then through its middle
    layers where it has more than one (:func:`middle_layers`).

    Each unit's sum runs over the features in their order, as before, but the units
    are summed side by side, so that the inner loop (over units, along W1's rows)
    vectorises; a feature of value 0 adds nothing and is skipped. For finite weights
    these are the very sums of the unit-by-unit loop, bit for bit
    (``tests/training/test_deep_kernels.py``)."""
    w1, b1 = weights[0], weights[1]
    units = b1.shape[1]
    for h in range(units):
        hidden[h] = b1[agent, h]
    for f in range(w1.shape[1]):
        value = x[lo + f]
        if value == 0.0:
            continue
        for h in range(units):
            hidden[h] += value * w1[agent, f, h]
    for h in range(units):
        if not hidden[h] > 0.0:  # ReLU (a NaN, too, becomes 0)
            hidden[h] = 0.0
    if weights[4].shape[1] > 0:
        middle_layers(weights[4], weights[5], agent, hidden)


@kernel
def middle_layers(wm, bm, agent: int, hidden) -> None:
    """``hidden[:H]`` := the agent's hidden layers after the first (each ``ReLU(h Wm +
    bm)``, ``Weights.wm``) applied to it in turn, summed as :func:`hidden_layer_at` sums
    (float32, units side by side, zeros skipped); ``hidden[H:2H]`` is its scratch (the
    kernels allocate nothing: :func:`hidden_scratch` sizes it)."""
    units = wm.shape[2]
    for m in range(wm.shape[1]):  # the next layer in hidden[units:], then moved down
        for h in range(units):
            hidden[units + h] = bm[agent, m, h]
        for f in range(units):
            value = hidden[f]
            if value == 0.0:
                continue
            for h in range(units):
                hidden[units + h] += value * wm[agent, m, f, h]
        for h in range(units):
            inner = hidden[units + h]
            hidden[h] = inner if inner > 0.0 else 0.0


def hidden_scratch(weights: Weights) -> np.ndarray:
    """The float32 scratch :func:`hidden_layer_at` needs for ``weights``: the hidden
    layer's units, twice that where the networks have middle layers."""
    units = weights.b1.shape[1]
    return np.zeros(units * (2 if weights.wm.shape[1] else 1), np.float32)


@kernel
def output_unit(weights, agent: int, hidden, a: int) -> float:
    """Output ``a`` of agent ``agent``'s network at its hidden layer ``hidden`` (from
    :func:`hidden_layer`): b2[a] + sum_h hidden[h] W2[h, a], summed in float64."""
    w2 = weights[2]
    q = np.float64(weights[3][agent, a])
    for h in range(w2.shape[1]):
        q += np.float64(hidden[h]) * w2[agent, h, a]
    return q


@kernel
def greedy_agent(weights, agent: int, x, legal_row, count: int, hidden) -> int:
    """The agent's legal action of largest Q at ``x`` (lowest index on ties)."""
    return greedy_agent_at(weights, agent, x, 0, legal_row, count, hidden)


@kernel
def greedy_agent_at(weights, agent: int, x, lo: int, legal_row, count: int, hidden) -> int:
    """:func:`greedy_agent`, the agent's network reading ``x`` from feature ``lo``."""
    hidden_layer_at(weights, agent, x, lo, hidden)
    best, best_q = -1, 0.0
    for a in range(count):
        if not legal_row[a]:
            continue
        q = output_unit(weights, agent, hidden, a)
        if best < 0 or q > best_q:
            best, best_q = a, q
    return best


def features_enter(side, env, team, offset, legal, length, terminal) -> int:
    """Template: turn ``length``'s features and legal actions into the episode record
    (a terminal state's are never read), and its state index where the side caches
    greedy actions."""
    if terminal:
        return length
    if side.cache.keys.shape[0] > 0:
        side.cache.states[length] = game.state(env, team)
    game.features(env, team, side.obs[length])
    game.legal(env, legal)
    for i in range(side.counts.shape[0]):
        for a in range(legal.shape[1]):
            side.legal[length, i, a] = legal[offset + i, a]
    return length


@kernel
def cache_slot(side, s: int) -> int:
    """The slot of state ``s`` in the side's greedy cache, emptied first if it holds
    another state or an older generation's actions; -1 where the side caches nothing."""
    cache = side.cache
    slots = cache.keys.shape[0]
    if slots == 0:
        return -1
    slot = int((np.uint64(s) * HASH_MULTIPLIER) >> HASH_SHIFT) & (slots - 1)
    generation = side.counters[GENERATION]
    if cache.keys[slot] != s or cache.generations[slot] != generation:
        cache.keys[slot], cache.generations[slot] = s, generation
        for i in range(cache.actions.shape[1]):
            cache.actions[slot, i] = -1
    return slot


@kernel
def cached_greedy(side, slot: int, agent: int, x, legal_row, count: int) -> int:
    """:func:`greedy_agent` at ``x``, read from cache slot ``slot`` once computed there
    (``slot`` -1: computed every time)."""
    lo = side.starts[agent]
    if slot < 0:
        return greedy_agent_at(side.weights, agent, x, lo, legal_row, count, side.hidden)
    action = side.cache.actions[slot, agent]
    if action < 0:
        action = greedy_agent_at(side.weights, agent, x, lo, legal_row, count, side.hidden)
        side.cache.actions[slot, agent] = action
    return action


@kernel
def features_act(side, key: int, rng, joint) -> None:
    """ε-greedy (eq. 18): each agent independently a uniform legal action with
    probability ε, else its greedy legal action."""
    eps = exploration(side)
    x, legal = side.obs[key], side.legal[key]
    slot = cache_slot(side, side.cache.states[key]) if side.cache.keys.shape[0] > 0 else -1
    for i in range(side.counts.shape[0]):
        count = side.counts[i]
        if rng.random() < eps:
            joint[i] = uniform_legal_action(legal[i], count, rng.random())
        else:
            joint[i] = cached_greedy(side, slot, i, x, legal[i], count)


@kernel
def features_observe(side, t: int, next_key: int, terminal: bool) -> None:
    """Append turn ``t`` to the ring."""
    push_row(
        side.replay,
        side.obs[t],
        side.obs[t + 1],
        side.legal[t + 1],
        side.joints[t],
        side.rewards[t],
        terminal,
    )
    side.counters[TURNS] += 1


def features_greedy(side, env, team, offset, legal, rng, joint) -> None:
    """Template: every agent's greedy legal action at the side's features (``rng`` is not
    drawn from: a network has a greedy action in every state); the features and masks
    are read only where the cache does not hold every action yet."""
    x = side.obs[side.obs.shape[0] - 1]
    slot = cache_slot(side, game.state(env, team)) if side.cache.keys.shape[0] > 0 else -1
    read = False
    for i in range(joint.shape[0]):
        if slot >= 0 and side.cache.actions[slot, i] >= 0:
            joint[i] = side.cache.actions[slot, i]
            continue
        if not read:
            game.features(env, team, x)
            game.legal(env, legal)
            read = True
        joint[i] = cached_greedy(side, slot, i, x, legal[offset + i], side.counts[i])


# ------------------------------------------------------------- index inputs


def index_enter(side, env, team, offset, legal, length, terminal) -> int:
    """Template: the state index, its masks read on the side's first visit (a terminal
    state's too: they bound the TD target's maximum)."""
    s = game.state(env, team)
    if not side.seen[s]:
        game.legal(env, legal)
        for i in range(side.counts.shape[0]):
            for a in range(legal.shape[1]):
                side.legal[s, i, a] = legal[offset + i, a]
        side.seen[s] = True
        side.counters[NEW_STATES] = 1
    side.obs[length] = s
    return s


@kernel
def index_act(side, s: int, rng, joint) -> None:
    """ε-greedy (eq. 18) on the Q-table of state ``s``."""
    epsilon_greedy(side.values[s], side.legal[s], side.counts, exploration(side), rng, joint)


@kernel
def index_observe(side, t: int, next_s: int, terminal: bool) -> None:
    """Append turn ``t`` to the ring."""
    push(side.replay, side.obs[t], side.joints[t], side.rewards[t], next_s, terminal)
    side.counters[TURNS] += 1


def index_greedy(side, env, team, offset, legal, rng, joint) -> None:
    """Template: every agent's greedy legal action in the state's Q-table."""
    s = game.state(env, team)
    game.legal(env, legal)
    for i in range(joint.shape[0]):
        joint[i] = greedy_action(side.values[s, i], legal[offset + i], side.counts[i])


def deep_kernels(spec: GameSpec, inputs: str, config: object = None) -> SideKernels:
    """The side kernels of VDN or QMIX on ``spec`` reading ``inputs`` (``config`` is not
    read: theirs are the same for either mixer)."""
    bound = {"game": spec.kernels}
    if inputs == "features":
        enter, act, observe = features_enter, features_act, features_observe
        greedy = features_greedy
    else:
        enter, act, observe, greedy = index_enter, index_act, index_observe, index_greedy
    return SideKernels(
        deep_fits,
        specialise_kernel(enter, **bound),
        act,
        observe,
        deep_end_episode,
        deep_pause,
        specialise_kernel(greedy, **bound),
    )


def inputs_of(spec: GameSpec) -> str:
    """What a deep side reads on ``spec``: its features where it has them, else its
    state indices (one-hot)."""
    if spec.n_features > 0:
        return "features"
    require(
        spec.n_states <= MAX_INDEX_STATES,
        "game",
        f"{spec.name} has no state features and {spec.n_states:,} states, more than the "
        f"{MAX_INDEX_STATES:,} a deep learner reads as one-hot indices",
    )
    return "index"
