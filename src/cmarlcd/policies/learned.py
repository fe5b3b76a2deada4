"""The greedy policy of an object-API learner at the end of its run (a table learner,
:class:`~cmarlcd.learners.deep.agent.DeepAgent` or
:class:`~cmarlcd.learners.deep.degree_agent.DegreeAgent`), for
:func:`cmarlcd.policies.files.write_policy`."""

from __future__ import annotations

from collections.abc import Mapping
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


def network_policy(learner: Any, metadata: Mapping[str, Any]) -> NetworkPolicy:
    """Seed 0's agent networks (the object-API learner trains one seed), and deep
    CMARL-CD's clip and memory."""
    agents, n = learner.model.agents, len(learner.counts)

    def seed0(tensor) -> np.ndarray:
        return tensor.detach().cpu().numpy()[:n].astype(np.float32)

    arrays = {"w1": seed0(agents.first.weight), "b1": seed0(agents.first.bias),
              "w2": seed0(agents.second.weight), "b2": seed0(agents.second.bias),
              "counts": learner.counts.astype(np.int64)}  # fmt: skip
    config = learner.config
    meta = {**metadata, "n_states": learner.in_dim if learner.integer_states else None,
            "own_dim": agents.own_dim, "clip": None}  # fmt: skip
    if hasattr(config, "c_min"):  # deep CMARL-CD: degrees clipped as it acts
        meta["clip"] = [float(config.c_min), float(config.c_max)]
        if config.acts_from_memory:  # and its memory's, where it keeps the state
            memory = learner._memory
            filled = np.asarray(memory.filled, bool)
            arrays["memory_keys"] = np.asarray(memory.key)[filled].astype(np.uint64)
            arrays["memory_degrees"] = np.asarray(memory.target)[filled].astype(np.float32)
    return NetworkPolicy(arrays, meta)
