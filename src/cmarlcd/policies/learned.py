"""The greedy policy a learner ended its run with, for
:func:`cmarlcd.policies.files.write_policy`: an object-API learner's (a table learner,
:class:`~cmarlcd.learners.deep.agent.DeepAgent` or
:class:`~cmarlcd.learners.deep.degree_agent.DegreeAgent`), a compiled run's greedy table,
and each seed's of a seed-batched deep run (:class:`cmarlcd.training.deep.DeepBatch`)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from cmarlcd.policies.greedy import NetworkPolicy, TablePolicy


def policy_of(learner: Any, metadata: Mapping[str, Any]) -> TablePolicy | NetworkPolicy | None:
    """``learner``'s greedy policy (None for the random policy, which keeps none)."""
    from cmarlcd.learners.tabular.protocol import TabularLearner

    if isinstance(learner, TabularLearner):
        return table_policy(learner, metadata)
    if hasattr(learner, "model") and hasattr(learner.model, "agents"):
        return network_policy(learner, metadata)
    return None


def table_policy(learner: Any, metadata: Mapping[str, Any]) -> TablePolicy:
    """Every met state's greedy joint action, and a fresh state's."""
    from cmarlcd.learners.tabular.protocol import full_legal, greedy_policy, init_tables

    config, counts = learner.config, learner.counts
    actions = greedy_policy(config, learner.tables, counts)
    fresh_tables = init_tables(config, 1, counts)
    config.kernels.init_state(fresh_tables, learner.params, 0, full_legal(counts), counts)
    fresh = np.zeros(len(counts), np.int64)
    config.kernels.greedy(fresh_tables, 0, counts, fresh)
    keys = None if learner._index is None else list(learner._index)
    rows = len(learner._seen) if keys is None else len(keys)
    return TablePolicy(actions[:rows], learner._seen[:rows], fresh, counts, keys, metadata)


def full_table(table: np.ndarray, counts: np.ndarray, metadata: Mapping[str, Any]) -> TablePolicy:
    """A compiled run's greedy table over every state of its game, ``(n_states,
    n_agents)`` (every state has a row, so a fresh state's action is never read)."""
    counts = np.asarray(counts, np.int64)
    seen = np.ones(len(table), bool)
    return TablePolicy(table, seen, np.zeros(len(counts), np.int64), counts, metadata=metadata)


def network_policy(learner: Any, metadata: Mapping[str, Any]) -> NetworkPolicy:
    """The object-API learner's agent networks (it trains one seed), and deep
    CMARL-CD's clip and memory."""
    agents, n = learner.model.agents, len(learner.counts)
    layers = [w.detach().cpu().numpy()[:n] for w in agents.feature_weights()]
    memory = getattr(learner, "_memory", None)  # deep CMARL-CD's keyed memory
    n_states = learner.in_dim if learner.integer_states else None
    own_dim = getattr(agents, "own_dim", None)
    return seed_network(layers, learner.counts, learner.config, memory,
                        {**metadata, "n_states": n_states, "own_dim": own_dim})  # fmt: skip


def seed_network(
    layers: Sequence[np.ndarray],
    counts: np.ndarray,
    config: Any,
    memory: Any,
    metadata: Mapping[str, Any],
) -> NetworkPolicy:
    """One seed's agent networks from their per-agent ``layers`` (w1, b1, w2, b2 and the
    middle layers' wm, bm, agent-major, as the compiled loop reads them: a shared
    network's weights with each agent's index folded into its bias), deep CMARL-CD's clip
    and, where it acts from its keyed ``memory`` (that seed's view), the memory's keys and
    degrees. A network of one hidden layer keeps no ``wm``, ``bm`` (its files as before)."""
    arrays = {
        name: np.asarray(layer, np.float32).copy()
        for name, layer in zip(("w1", "b1", "w2", "b2", "wm", "bm"), layers, strict=True)
    }
    if arrays["wm"].shape[1] == 0:
        del arrays["wm"], arrays["bm"]
    arrays["counts"] = np.asarray(counts, np.int64)
    meta = {"n_states": None, "own_dim": None, **metadata, "clip": None}
    if hasattr(config, "c_min"):  # deep CMARL-CD: degrees clipped as it acts
        if not config.shares:  # shares of the record act unclipped
            meta["clip"] = [float(config.c_min), float(config.c_max)]
        if config.acts_from_memory and memory is not None:
            filled = np.asarray(memory.filled, bool)
            arrays["memory_keys"] = np.asarray(memory.key)[filled].astype(np.uint64)
            arrays["memory_degrees"] = np.asarray(memory.target)[filled].astype(np.float32)
    return NetworkPolicy(arrays, meta)


def side_network(side: Any, metadata: Mapping[str, Any]) -> NetworkPolicy:
    """The greedy policy a deep side of the compiled loop plays now
    (:class:`~cmarlcd.training.deep_side.DeepSide` reading features): a copy of the
    weights its kernels read and, for deep CMARL-CD acting from memory, of its keyed
    memory's entries."""
    data = side.data
    own_dim = getattr(side.model.agents, "own_dim", None)
    memory = getattr(data.replay, "memory", None)
    meta = {**metadata, "inputs": "observations", "own_dim": own_dim}
    return seed_network(data.weights, data.counts, side.config, memory, meta)


def evaluated_policy(
    policy: Any, counts: np.ndarray, metadata: Mapping[str, Any]
) -> TablePolicy | NetworkPolicy:
    """What a compiled run's greedy policy (:class:`cmarlcd.training.greedy.GreedyPolicy`)
    plays now, to keep: its table, or its deep side's networks."""
    if policy.play is None:
        return full_table(policy.table, counts, metadata)
    return side_network(policy.play.sides[0], metadata)
