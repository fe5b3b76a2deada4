"""The compiled side kernels of deep CMARL-CD (``[deep]`` extra, no PyTorch here): what
the loop of :mod:`cmarlcd.training.loop` calls on its side
(:mod:`cmarlcd.training.deep_side`), for both kinds of input of
:mod:`cmarlcd.training.deep_kernels` (whose entering, pausing and forward pass it
shares).

Acting samples each agent's action from ``softmax(c / T)`` of its clipped degrees over
the legal actions (eq. 17), one uniform per agent in agent order, as the tabular learner
does (or, with ``behaviour="epsilon-greedy"``, ε-greedy on them); greedy execution takes
the legal action of largest clipped degree (lowest index on ties). After each episode
the keyed update folds the episode into the keyed memory (:func:`keyed_index_store`,
:func:`keyed_features_store`: each visit keyed by its state index or the hash of its
features, the network's degrees and record estimate read for the states not kept); the
replayed update stores every visit with its discounted return (eq. 1, computed
backwards) in the ring.

With ``act_from="memory"`` the side acts (and executes greedily) with the keyed memory's
degrees where it keeps the state, found by the state's key as the fold finds it, and with
the network's elsewhere (:func:`memory_features_act`, :func:`memory_index_act` and their
greedy templates).
"""

from __future__ import annotations

import numpy as np

from cmarlcd.compiled import kernel, specialise_kernel
from cmarlcd.games.spec import GameSpec
from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig
from cmarlcd.learners.deep.degree_memory import features_key, find, fold_episode, may_be_missing
from cmarlcd.learners.deep.replay import push_visit, push_visit_row
from cmarlcd.learners.policy import (
    annealed,
    greedy_action,
    sample_action,
    softmax_strategy,
    uniform_legal_action,
)
from cmarlcd.training.deep_kernels import (
    ENDED_TERMINAL,
    EPISODES,
    TURNS,
    deep_fits,
    deep_pause,
    features_enter,
    game,
    hidden_layer,
    hidden_layer_at,
    index_enter,
    output_unit,
)
from cmarlcd.training.protocol import SideKernels

#: Entries of deep CMARL-CD's ``schedule`` (``DeepCMARLCDConfig.schedule``).
TEMPERATURE, C_MIN, C_MAX, GAMMA = range(4)
TEMPERATURE_END, TEMPERATURE_STEPS, TEMPERATURE_UNIT, TRUNCATION_BOOTSTRAP = 6, 7, 8, 9
BEHAVIOUR, EPSILON_START, EPSILON_END, EPSILON_STEPS = 10, 11, 12, 13


@kernel
def clip_row(values, count: int, lo: float, hi: float, out) -> None:
    """``out[:count]`` := ``values[:count]`` confined to ``[lo, hi]`` (Section IV-D)."""
    for a in range(count):
        out[a] = min(max(values[a], lo), hi)


@kernel
def agent_degrees(weights, agent: int, x, lo: int, count: int, hidden, out) -> None:
    """``out[:count]`` := agent ``agent``'s degree network at features ``x`` (from
    feature ``lo``: its own observation's, or 0 where it reads them all)."""
    hidden_layer_at(weights, agent, x, lo, hidden)
    for a in range(count):
        out[a] = output_unit(weights, agent, hidden, a)


@kernel
def legal_range(row, legal_row, count: int) -> float:
    """The largest minus the smallest of ``row`` over the legal actions; 1 where they
    are all equal (any T then gives the uniform strategy)."""
    lo, hi = np.inf, -np.inf
    for a in range(count):
        if legal_row[a]:
            lo, hi = min(lo, row[a]), max(hi, row[a])
    return hi - lo if hi > lo else 1.0


@kernel
def sample_degrees(side, raw, legal_row, count: int, rng) -> int:
    """An action from ``softmax(clip(raw) / T)`` over the legal actions (eq. 17), T
    annealed over the side's steps where the schedule anneals it, and in the range of
    the legal degrees with ``temperature_unit="range"``; with
    ``behaviour="epsilon-greedy"``, a uniform legal action with probability ε (one
    uniform, then a second for the action), else the greedy one."""
    s, row, probs = side.schedule, side.scratch[0], side.scratch[1]
    clip_row(raw, count, s[C_MIN], s[C_MAX], row)
    if s[BEHAVIOUR] == 1.0:  # "epsilon-greedy"
        eps = annealed(s[EPSILON_START], s[EPSILON_END], s[EPSILON_STEPS], side.counters[TURNS])
        if rng.random() < eps:
            return uniform_legal_action(legal_row, count, rng.random())
        return greedy_action(row, legal_row, count)
    t = annealed(s[TEMPERATURE], s[TEMPERATURE_END], s[TEMPERATURE_STEPS], side.counters[TURNS])
    if s[TEMPERATURE_UNIT] == 1.0:  # "range": T in the range of the legal degrees
        t *= legal_range(row, legal_row, count)
    softmax_strategy(row, legal_row, count, t, probs)
    return sample_action(probs, count, rng.random())


@kernel
def greedy_degrees(side, raw, legal_row, count: int) -> int:
    """The legal action of largest clipped degree, lowest index on ties."""
    row = side.scratch[0]
    clip_row(raw, count, side.schedule[C_MIN], side.schedule[C_MAX], row)
    return greedy_action(row, legal_row, count)


@kernel
def count_turn(side, t: int, next_key: int, terminal: bool) -> None:
    """``observe``: count the turn, and whether it ended in a terminal state (the
    episode is stored when it ends)."""
    side.counters[TURNS] += 1
    side.counters[ENDED_TERMINAL] = 1 if terminal else 0


# ---------------------------------------------------------- feature inputs


@kernel
def features_act(side, key: int, rng, joint) -> None:
    x, legal, raw = side.obs[key], side.legal[key], side.scratch[1]
    for i in range(side.counts.shape[0]):
        count = side.counts[i]
        agent_degrees(side.weights, i, x, side.starts[i], count, side.hidden, raw)
        joint[i] = sample_degrees(side, raw, legal[i], count, rng)


@kernel
def features_store(side, length: int) -> None:
    """``end_episode``: every visit with its discounted return, backwards."""
    g = 0.0
    for t in range(length - 1, -1, -1):
        g = side.rewards[t] + side.schedule[GAMMA] * g
        push_visit_row(side.replay, side.obs[t], side.joints[t], g)
    side.counters[EPISODES] += 1


def features_greedy(side, env, team, offset, legal, rng, joint) -> None:
    """Template: every agent's greedy legal action at the side's features."""
    x, raw = side.obs[side.obs.shape[0] - 1], side.scratch[1]
    game.features(env, team, x)
    game.legal(env, legal)
    for i in range(joint.shape[0]):
        count = side.counts[i]
        agent_degrees(side.weights, i, x, side.starts[i], count, side.hidden, raw)
        joint[i] = greedy_degrees(side, raw, legal[offset + i], count)


# ------------------------------------------------------------- index inputs


@kernel
def index_act(side, s: int, rng, joint) -> None:
    for i in range(side.counts.shape[0]):
        joint[i] = sample_degrees(side, side.values[s, i], side.legal[s, i], side.counts[i], rng)


@kernel
def index_store(side, length: int) -> None:
    """``end_episode``: every visit with its discounted return, backwards."""
    g = 0.0
    for t in range(length - 1, -1, -1):
        g = side.rewards[t] + side.schedule[GAMMA] * g
        push_visit(side.replay, side.obs[t], side.joints[t], g)
    side.counters[EPISODES] += 1


@kernel
def cut_and_bootstrapped(side) -> bool:
    """Whether the episode just ended was cut at ``max_steps`` (its last turn did not
    end in a terminal state) and its last λ-return bootstraps from the estimate at the
    state it was cut in (``truncation="bootstrap"``)."""
    return side.schedule[TRUNCATION_BOOTSTRAP] == 1.0 and side.counters[ENDED_TERMINAL] == 0


@kernel
def index_lambda_store(side, length: int) -> None:
    """``end_episode``: every visit with its λ-return bootstrapped from the record
    network's estimate of the next visit's state (``return_lambda``), backwards; the
    last visit of a cut episode from the state it was cut in, with
    ``truncation="bootstrap"``, else from nothing."""
    replay, gamma = side.replay, side.schedule[GAMMA]
    g = 0.0
    for t in range(length - 1, -1, -1):
        after = 0.0
        if t + 1 < length:
            estimate = replay.record_table[side.obs[t + 1]]
            after = (1.0 - replay.lam) * estimate + replay.lam * g
        elif cut_and_bootstrapped(side):
            after = replay.record_table[side.obs[length]]
        g = side.rewards[t] + gamma * after
        p = replay.ring.position[0]
        push_visit(replay.ring, side.obs[t], side.joints[t], g)
        replay.ring.terminal[p], replay.step_reward[p] = t == length - 1, side.rewards[t]
    side.counters[EPISODES] += 1


@kernel
def features_lambda_store(side, length: int) -> None:
    """:func:`index_lambda_store` for feature inputs: the record network at the next
    visit's features."""
    replay, gamma = side.replay, side.schedule[GAMMA]
    g = 0.0
    for t in range(length - 1, -1, -1):
        after = 0.0
        if t + 1 < length:
            estimate = bootstrap_estimate(side, t + 1)
            after = (1.0 - replay.lam) * estimate + replay.lam * g
        elif cut_and_bootstrapped(side):
            after = bootstrap_estimate(side, length)
        g = side.rewards[t] + gamma * after
        p = replay.ring.position[0]
        push_visit_row(replay.ring, side.obs[t], side.joints[t], g)
        replay.ring.terminal[p], replay.step_reward[p] = t == length - 1, side.rewards[t]
    side.counters[EPISODES] += 1


def index_greedy(side, env, team, offset, legal, rng, joint) -> None:
    """Template: every agent's greedy legal action in the state's degree table."""
    s = game.state(env, team)
    game.legal(env, legal)
    for i in range(joint.shape[0]):
        joint[i] = greedy_degrees(side, side.values[s, i], legal[offset + i], side.counts[i])


# ------------------------------------------ acting from the keyed memory


@kernel
def kept_or_network_degrees(side, slot: int, i: int, x, count: int, raw) -> None:
    """``raw[:count]`` := agent ``i``'s degrees at features ``x``: the memory's entry
    ``slot`` where the memory keeps the state (``slot`` >= 0), else the network's."""
    if slot >= 0:
        for a in range(count):
            raw[a] = side.replay.memory.target[slot, i, a]
    else:
        agent_degrees(side.weights, i, x, side.starts[i], count, side.hidden, raw)


@kernel
def memory_features_act(side, key: int, rng, joint) -> None:
    """Eq. 17 with the memory's degrees where it keeps the state, else the network's."""
    x, legal, raw = side.obs[key], side.legal[key], side.scratch[1]
    slot = find(side.replay.memory, features_key(x))
    for i in range(side.counts.shape[0]):
        kept_or_network_degrees(side, slot, i, x, side.counts[i], raw)
        joint[i] = sample_degrees(side, raw, legal[i], side.counts[i], rng)


def memory_features_greedy(side, env, team, offset, legal, rng, joint) -> None:
    """Template: every agent's greedy legal action, with the memory's degrees where it
    keeps the state, else the network's."""
    x, raw = side.obs[side.obs.shape[0] - 1], side.scratch[1]
    game.features(env, team, x)
    game.legal(env, legal)
    slot = find(side.replay.memory, features_key(x))
    for i in range(joint.shape[0]):
        kept_or_network_degrees(side, slot, i, x, side.counts[i], raw)
        joint[i] = greedy_degrees(side, raw, legal[offset + i], side.counts[i])


@kernel
def kept_or_table_degrees(side, slot: int, s: int, i: int, raw) -> None:
    """``raw`` := agent ``i``'s degrees at state index ``s``: the memory's entry ``slot``
    where the memory keeps ``s`` (``slot`` >= 0), else the network's (its row of the
    loop's copy). Copied: a compiled kernel returns no view of an array it was not
    given."""
    for a in range(side.counts[i]):
        raw[a] = side.replay.memory.target[slot, i, a] if slot >= 0 else side.values[s, i, a]


@kernel
def memory_index_act(side, s: int, rng, joint) -> None:
    """Eq. 17 with the memory's degrees where it keeps the state, else the network's."""
    raw = side.scratch[1]
    slot = find(side.replay.memory, np.uint64(s))
    for i in range(side.counts.shape[0]):
        kept_or_table_degrees(side, slot, s, i, raw)
        joint[i] = sample_degrees(side, raw, side.legal[s, i], side.counts[i], rng)


def memory_index_greedy(side, env, team, offset, legal, rng, joint) -> None:
    """Template: every agent's greedy legal action, with the memory's degrees where it
    keeps the state, else the network's."""
    s = game.state(env, team)
    game.legal(env, legal)
    raw = side.scratch[1]
    slot = find(side.replay.memory, np.uint64(s))
    for i in range(joint.shape[0]):
        kept_or_table_degrees(side, slot, s, i, raw)
        joint[i] = greedy_degrees(side, raw, legal[offset + i], side.counts[i])


# ------------------------------------------------- the keyed memory's stores


@kernel
def bootstrap_estimate(side, t: int) -> float:
    """What the λ-return of the visit before turn ``t`` bootstraps from at the features
    of turn ``t``: the record network's estimate (:func:`record_estimate`), or, for a
    critic that bootstraps from the greedy joint action (``critic_bootstrap="greedy"``),
    its output at the joint action the agents' degrees take greedily there (joint index
    ``sum_i a_i * prod_{j > i} |A_j|``), or the sum of each agent's output at its greedy
    action (``critic_form="sum"``), or of the degree networks' target copy at it
    (``critic_form="degrees"``: ``weights`` are that copy)."""
    replay, x = side.replay, side.obs[t]
    if not replay.greedy:
        return record_estimate(replay, x)
    weights, hidden = replay.record_weights, replay.record_hidden
    if not replay.shares:
        hidden_layer(weights, 0, x, hidden)
    raw, joint, offset, total = side.scratch[1], 0, 0, 0.0
    for i in range(side.counts.shape[0]):
        count = side.counts[i]
        agent_degrees(side.weights, i, x, side.starts[i], count, side.hidden, raw)
        a = greedy_degrees(side, raw, side.legal[t, i], count)
        if replay.shares:  # critic_form="degrees": the target copy's degree at a
            target = side.scratch[0]
            agent_degrees(weights, i, x, side.starts[i], count, side.hidden, target)
            total += target[a]
        elif replay.summed:  # critic_form="sum": agent i's output offset + a
            total += output_unit(weights, 0, hidden, offset + a)
            offset += count
        else:
            joint = joint * count + a
    if replay.shares or replay.summed:
        return total
    return output_unit(weights, 0, hidden, joint)


@kernel
def record_estimate(replay, x) -> float:
    """The record network's estimate at features ``x``: the best of its outputs (one, or
    one per joint action for ``update="critic"``)."""
    weights, hidden = replay.record_weights, replay.record_hidden
    hidden_layer(weights, 0, x, hidden)
    best = output_unit(weights, 0, hidden, 0)
    for k in range(1, weights[3].shape[1]):
        best = max(best, output_unit(weights, 0, hidden, k))
    return best


@kernel
def keyed_index_store(side, length: int) -> None:
    """``end_episode``: fold the episode into the keyed memory; a state not kept starts
    from the network's degrees (its row of the loop's copy) and is compared with the
    record network's estimate or ``-inf``."""
    replay = side.replay
    estimate = replay.params.estimate_unseen
    for t in range(length):
        s = side.obs[t]
        replay.keys[t] = np.uint64(s)
        for i in range(side.counts.shape[0]):
            for a in range(side.counts[i]):
                replay.bases[t, i, a] = side.values[s, i, a]
        replay.estimates[t] = replay.record_table[s] if estimate else -np.inf
    fold_episode(
        replay.memory, replay.keys, side.obs, replay.bases, replay.estimates, side.joints,
        side.rewards, side.counts, length, replay.params,
    )  # fmt: skip
    side.counters[EPISODES] += 1


@kernel
def keyed_features_store(side, length: int) -> None:
    """``end_episode``: fold the episode into the keyed memory, keyed by the hash of each
    visit's features, with the network's degrees and (with ``estimate_unseen``) the
    record network's estimate, else ``-inf``, at each visit whose state may not be kept
    when the fold reaches it (:func:`may_be_missing`; the fold reads them there only)."""
    replay = side.replay
    estimate = replay.params.estimate_unseen
    for t in range(length):
        replay.keys[t] = features_key(side.obs[t])
    for t in range(length):
        if may_be_missing(replay.memory, replay.keys, length, t):
            x = side.obs[t]
            for i in range(side.counts.shape[0]):
                agent_degrees(
                    side.weights,
                    i,
                    x,
                    side.starts[i],
                    side.counts[i],
                    side.hidden,
                    replay.bases[t, i],
                )
            replay.estimates[t] = record_estimate(replay, x) if estimate else -np.inf
    fold_episode(
        replay.memory, replay.keys, side.obs, replay.bases, replay.estimates, side.joints,
        side.rewards, side.counts, length, replay.params,
    )  # fmt: skip
    side.counters[EPISODES] += 1


def degree_kernels(spec: GameSpec, inputs: str, config: DeepCMARLCDConfig) -> SideKernels:
    """The side kernels of deep CMARL-CD (``config``) on ``spec`` reading ``inputs``."""
    bound = {"game": spec.kernels}
    keyed = config.keyed
    memory = config.acts_from_memory
    if inputs == "features":
        enter = features_enter
        act, greedy = (
            (memory_features_act, memory_features_greedy)
            if memory
            else (features_act, features_greedy)
        )
        store = keyed_features_store if keyed else features_store
        store = features_lambda_store if config.bootstraps else store
    else:
        enter = index_enter
        act, greedy = (
            (memory_index_act, memory_index_greedy) if memory else (index_act, index_greedy)
        )
        store = keyed_index_store if keyed else index_store
        store = index_lambda_store if config.bootstraps else store
    return SideKernels(
        deep_fits,
        specialise_kernel(enter, **bound),
        act,
        count_turn,
        store,
        deep_pause,
        specialise_kernel(greedy, **bound),
    )
