"""Greedy policies read back from a run: a table's and a network's, acting as the learner
did at its last evaluation.

* :class:`TablePolicy`: a table learner's greedy joint action of every state it met
  (the argmax of its values or strategies, every action legal), and, for states it never
  met, the greedy joint action of a fresh state of its table (what the learner plays
  there: it starts a state when it first meets it).
* :class:`NetworkPolicy`: a deep learner's agent networks (one per agent: input ->
  Linear -> ReLU -> Linear -> one value per action), the argmax over each agent's legal
  actions of its Q (VDN, QMIX, deep IQL, hysteretic DQN) or of its clipped coordination
  degrees (deep CMARL-CD, eq. 17 at T -> 0; where its keyed memory keeps a state and it
  acts from memory, the memory's degrees). The forward pass is numpy's, so a policy
  plays without PyTorch.

Both act in a PettingZoo loop with :meth:`act` (observations in, actions out) and in the
project's loops with ``greedy``/``greedy_many`` (states and legal-action masks).
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping, Sequence
from typing import Any

import numpy as np

from cmarlcd.errors import require


class _Acting:
    """What both kinds share: the learner's input from a PettingZoo loop's observations."""

    metadata: dict[str, Any]

    def greedy_many(self, states: Sequence, masks: Sequence) -> np.ndarray:
        raise NotImplementedError

    def greedy(self, state, masks=None) -> tuple[int, ...]:
        """The greedy legal joint action at ``state`` (masks: one per agent, or None)."""
        return tuple(int(a) for a in self.greedy_many([state], [masks])[0])

    def act(
        self, observations: Mapping[str, Any], state: Any = None, masks: Mapping | None = None
    ) -> dict[str, int]:
        """Each agent's greedy action from a PettingZoo ``ParallelEnv``'s observations
        (``state``: the environment's ``state()``, for a policy that learned from it;
        ``masks``: each agent's legal actions, where the environment gives them)."""
        agents = list(self.metadata.get("agents") or observations)
        inputs = self.metadata.get("inputs", "state")
        if inputs == "state":
            require(state is not None, "state", "this policy reads the environment's state()")
            x = state
        else:  # the agents' observations joined (own-observations: the network reads its own)
            missing = [a for a in agents if a not in observations]
            require(not missing, "observations", f"no observation of {missing}")
            x = np.concatenate([np.asarray(observations[a], np.float32).ravel() for a in agents])
        legal = None if masks is None else [masks[a] for a in agents]
        return dict(zip(agents, self.greedy(x, legal), strict=True))


def _legal(counts: np.ndarray, width: int, masks: Sequence | None) -> np.ndarray:
    """(n, width) bool: the actions an agent has, narrowed by its mask where given."""
    legal = np.arange(width)[None, :] < counts[:, None]
    if masks is not None:
        require(len(masks) == len(counts), "masks", "needs one mask per agent")
        for i, mask in enumerate(masks):
            legal[i, : counts[i]] &= np.asarray(mask, dtype=bool)
    return legal


class TablePolicy(_Acting):
    """A table learner's greedy joint actions; ``keys``: the states of its rows where
    they are not the integers ``0 .. S-1`` (a PettingZoo environment's hashable states)."""

    kind = "table"

    def __init__(
        self,
        actions: np.ndarray,
        seen: np.ndarray,
        fresh: np.ndarray,
        counts: np.ndarray,
        keys: list | None = None,
        metadata: Mapping[str, Any] | None = None,
    ) -> None:
        self.actions = np.asarray(actions, np.int64)
        self.seen, self.fresh = np.asarray(seen, bool), np.asarray(fresh, np.int64)
        self.counts = np.asarray(counts, np.int64)
        self.keys = keys
        self.index = None if keys is None else {k: r for r, k in enumerate(keys)}
        self.metadata = dict(metadata or {})

    def arrays(self) -> dict[str, np.ndarray]:
        return {"actions": self.actions, "seen": self.seen, "fresh": self.fresh,
                "counts": self.counts}  # fmt: skip

    def row(self, state: Hashable) -> int | None:
        """The row of ``state``, or None for a state the learner never met."""
        if self.index is not None:
            return self.index.get(state)
        row = int(state)  # type: ignore[call-overload]
        return row if 0 <= row < len(self.seen) and self.seen[row] else None

    def greedy_many(self, states: Sequence, masks: Sequence) -> np.ndarray:
        """Each state's greedy joint action; where a mask forbids an agent's greedy
        action, its first legal one (the table keeps the argmax with every action legal)."""
        out = np.empty((len(states), len(self.counts)), np.int64)
        width = int(self.counts.max())
        for k, (state, mask) in enumerate(zip(states, masks, strict=True)):
            row = self.row(state)
            joint = self.fresh if row is None else self.actions[row]
            legal = _legal(self.counts, width, mask)
            out[k] = [a if legal[i, a] else int(np.argmax(legal[i])) for i, a in enumerate(joint)]
        return out


class NetworkPolicy(_Acting):
    """A deep learner's agent networks: ``w1`` (n, in, hidden), ``b1`` (n, hidden), ``w2``
    (n, hidden, width), ``b2`` (n, width), ``counts`` (n,), where they have more than one
    hidden layer the middle ones' ``wm`` (n, layers - 1, hidden, hidden) and ``bm`` (n,
    layers - 1, hidden); deep CMARL-CD's clip and, where
    it acts from its memory, the memory's ``memory_keys`` (m,) and ``memory_degrees`` (m,
    n, width). ``metadata``: ``n_states`` (integer states, read one-hot) or None (features),
    ``own_dim`` (each agent reads its own ``own_dim`` features, the last ``n * own_dim`` of
    the input) or None, ``clip`` ([c_min, c_max]) or None."""

    kind = "network"

    def __init__(self, arrays: Mapping[str, np.ndarray], metadata: Mapping[str, Any]) -> None:
        self._arrays = {k: np.asarray(v) for k, v in arrays.items()}
        self.metadata = dict(metadata)
        self.counts = self._arrays["counts"].astype(np.int64)
        keys = self._arrays.get("memory_keys")
        self.memory = (
            None if keys is None
            else {int(k): d.astype(np.float64) for k, d in zip(keys, self._arrays["memory_degrees"],
                                                                 strict=True)}
        )  # fmt: skip

    def arrays(self) -> dict[str, np.ndarray]:
        return dict(self._arrays)

    def values(self, states: Sequence) -> np.ndarray:
        """Each agent's value of each action at each state: (N, n, width), float32 as the
        learner computed them (clipped for deep CMARL-CD), before any memory."""
        a, meta = self._arrays, self.metadata
        w1, b1, w2, b2 = a["w1"], a["b1"], a["w2"], a["b2"]
        n = len(self.counts)
        if meta.get("n_states"):
            rows = np.array([int(s) for s in states])
            hidden = np.maximum(w1[:, rows, :] + b1[:, None, :], 0)  # (n, N, h)
        else:
            x = np.stack([np.asarray(s, np.float32).ravel() for s in states])
            own = meta.get("own_dim")
            if own:
                x = x[:, x.shape[1] - n * own :].reshape(len(states), n, own).transpose(1, 0, 2)
                hidden = np.maximum(np.matmul(x, w1) + b1[:, None, :], 0)
            else:
                hidden = np.maximum(np.matmul(x[None], w1) + b1[:, None, :], 0)
        if "wm" in a:  # the hidden layers after the first
            for m in range(a["wm"].shape[1]):
                hidden = np.maximum(np.matmul(hidden, a["wm"][:, m]) + a["bm"][:, m, None, :], 0)
        q = (np.matmul(hidden, w2) + b2[:, None, :]).transpose(1, 0, 2)  # (N, n, width)
        clip = meta.get("clip")
        return q if clip is None else np.clip(q, clip[0], clip[1])

    def greedy_many(self, states: Sequence, masks: Sequence) -> np.ndarray:
        """Each agent's legal action of largest value (lowest index on ties)."""
        values = self.values(states).astype(np.float64)
        if self.memory is not None:
            for k, state in enumerate(states):
                degrees = self.memory.get(self.key(state))
                if degrees is not None:
                    values[k] = degrees
        width = values.shape[2]
        legal = np.stack([_legal(self.counts, width, m) for m in masks])
        return np.argmax(np.where(legal, values, -np.inf), axis=-1)

    def key(self, state) -> int:
        """Deep CMARL-CD's memory key of ``state``: the integer itself, or the hash of its
        float32 features."""
        if self.metadata.get("n_states"):
            return int(state)
        from cmarlcd.learners.deep.degree_memory import features_key

        return int(features_key(np.asarray(state, np.float32).ravel()))
