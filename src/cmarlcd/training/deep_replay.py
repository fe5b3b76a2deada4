"""What a deep side keeps to learn from (``[deep]`` extra): each learner's *replay kind*,
the part of :class:`cmarlcd.training.deep_side.DeepGroup` that differs with it.

* :data:`RING`: a ring of transitions (VDN and QMIX; deep CMARL-CD's ``replayed``
  update, a ring of visits), :mod:`cmarlcd.learners.deep.replay`;
* :data:`BOOTSTRAPPED`: deep CMARL-CD's ring of visits with λ-returns
  (``return_lambda`` below 1): the ring and a copy of the record network they are
  bootstrapped from (:class:`BootstrappedRing`);
* :data:`KEYED`: deep CMARL-CD's keyed memory (:mod:`cmarlcd.learners.deep.degree_memory`)
  with what its compiled side needs to fold an episode in (:class:`KeyedReplay`): each
  visit's key, the network's degrees and record estimate at it, and a copy of the record
  network to estimate with.

A kind makes B seeds' replay, gives each seed's view to its side's kernels, says how much
a seed has kept, draws a batch per seed with the seed's own stream, refreshes what
its kernels read of the model after a gradient step, and what it keeps after a target copy.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
import torch

from cmarlcd.games.spec import GameSpec
from cmarlcd.learners.deep.degree_memory import (
    DegreeMemory,
    KeyedParams,
    keyed_params,
    memory_view,
    new_memory,
    sample_memory,
)
from cmarlcd.learners.deep.replay import (
    draw,
    new_ring,
    recompute_lambda_returns,
    rows_of,
    sample,
    seed_view,
)
from cmarlcd.training.deep_kernels import Weights


class KeyedReplay(NamedTuple):
    """Deep CMARL-CD's keyed memory as its compiled side reads it (B seeds, or one seed's
    view without the seed axis)."""

    memory: DegreeMemory
    keys: np.ndarray
    """(B, max_steps) uint64: the episode's keys ..."""
    bases: np.ndarray
    """... (B, max_steps, n_agents, width) float32: the network's degrees at each visit ..."""
    estimates: np.ndarray
    """... (B, max_steps) float64: the record each visit of a state not kept is compared
    with (-inf: the table's first visit)."""
    record_table: np.ndarray
    """(B, n_states) float32: the record network's estimate of every integer state, or
    (B, 0) for feature inputs ..."""
    record_weights: Weights
    """... (one "agent" per seed) the record network's layers for feature inputs, or empty."""
    record_hidden: np.ndarray
    """(B, record_hidden) float32 scratch for the record network's hidden layer."""
    params: KeyedParams


class BootstrappedRing(NamedTuple):
    """A ring of visits whose returns are bootstrapped from the record network: the ring,
    and the record network's copy as the keyed memory holds it (B seeds, or one seed's
    view)."""

    ring: Any
    record_table: np.ndarray
    """(B, n_states) float32: the record network's estimate of every integer state, or
    (B, 0) for feature inputs ..."""
    record_weights: Weights
    """... its layers for feature inputs (one "agent" per seed), or empty."""
    record_hidden: np.ndarray
    """(B, record_hidden) float32 scratch for its hidden layer."""
    lam: float
    """λ of the returns (``DeepCMARLCDConfig.return_lambda``)."""
    greedy: bool
    """Whether they bootstrap from the critic's output at the degrees' greedy joint
    action (``critic_bootstrap="greedy"``; for feature inputs, where the compiled loop
    estimates; the copy of every integer state's estimate holds it already)."""
    summed: bool
    """Whether the critic is a sum of the agents' outputs (``critic_form="sum"``)."""
    shares: bool
    """Whether the critic is the sum of the agents' degrees (``critic_form="degrees"``):
    no record network to read."""
    step_reward: np.ndarray
    """(B, buffer_size) float32: each stored visit's own reward (the ring's ``terminal``
    marks an episode's last visit), from which its λ-return is recomputed ..."""
    refreshes: bool
    """... at each target copy (``refresh_returns``)."""


def record_copies(config, seeds: int, counts: np.ndarray, spec: GameSpec, features: int) -> tuple:
    """Zeros for a copy of the record network: every integer state's estimate (B, S) or
    (B, 0), its layers for feature inputs (one hidden layer, no middle ones) or empty, and
    the scratch of its hidden layer. Its outputs: one, or one per joint action
    (``update="critic"``, of the side's agents, ``counts`` actions each; the compiled loop
    reads their best)."""
    hidden, outputs = config.record_hidden, config.record_outputs(counts)
    first = ((features, hidden), (hidden,), (hidden, outputs), (outputs,))
    shapes = (
        (*first, (0, hidden, hidden), (0, hidden))
        if features
        else ((0, 0), (0, 0), (0, 0), (0, 0), (0, 0, 0), (0, 0))
    )
    return (
        np.zeros((seeds, 0 if features else spec.n_states), np.float32),
        Weights(*(np.zeros((seeds, *shape), np.float32) for shape in shapes)),
        np.zeros((seeds, hidden), np.float32),
    )


def record_view(replay: Any, b: int) -> tuple:
    """Seed ``b``'s part of a replay's record copy (:func:`record_copies`' three): its
    record network, or its agents' rows where the copy is of the degree networks
    (``critic_form="degrees"``)."""
    per_seed = replay.record_weights[0].shape[0] // replay.record_table.shape[0]
    rows = slice(b * per_seed, (b + 1) * per_seed)
    weights = Weights(*(array[rows] for array in replay.record_weights))
    return replay.record_table[b], weights, replay.record_hidden[b]


def copy_record(model: Any, inputs: str, table: np.ndarray, weights: Weights) -> None:
    """Copy the record network into ``table`` (integer states: every state's estimate) or
    ``weights`` (features: its layers)."""
    with torch.no_grad():
        if inputs == "index":
            np.copyto(table, model.record_table().cpu().numpy())
            return
        for copy, weight in zip(weights, model.record_weights(), strict=True):
            np.copyto(copy, weight.cpu().numpy())


class RingKind:
    """A ring of transitions or visits (:mod:`cmarlcd.learners.deep.replay`)."""

    def new(self, config, seeds: int, counts: np.ndarray, spec: GameSpec, features: int):
        n, width = counts.shape[0], int(counts.max())
        return new_ring(seeds, config.buffer_size, n, width, spec.n_states, features)

    def view(self, replay, b: int):
        return seed_view(replay, b)

    def stored(self, replay, b: int) -> int:
        return int(replay.size[b])

    def draw(self, replay, rngs: Sequence[np.random.Generator], batch_size: int) -> dict:
        return sample(replay, rngs, batch_size)

    def refresh(self, replay, model: Any, inputs: str) -> None:
        """Nothing of the model is read from the ring."""

    def target_copied(self, replay, model: Any, inputs: str) -> None:
        """Nothing kept depends on the target copy."""

    def greedy_table(self, replay, table: np.ndarray, legal: np.ndarray, config) -> np.ndarray:
        """The greedy table of the networks, ``table``: a ring holds no degrees."""
        return table

    def nbytes(self, view) -> int:
        return sum(array.nbytes for array in view)


class KeyedKind:
    """Deep CMARL-CD's keyed memory and its episode scratch (:class:`KeyedReplay`)."""

    def new(self, config, seeds: int, counts: np.ndarray, spec: GameSpec, features: int):
        n, width, steps = counts.shape[0], int(counts.max()), spec.max_steps
        capacity = config.buffer_size if features else min(config.buffer_size, spec.n_states)
        return KeyedReplay(
            new_memory(seeds, capacity, n, width, features, config.ways),
            np.zeros((seeds, steps), np.uint64),
            np.zeros((seeds, steps, n, width), np.float32),
            np.zeros((seeds, steps)),
            *record_copies(config, seeds, counts, spec, features),
            keyed_params(config),
        )

    def view(self, replay: KeyedReplay, b: int) -> KeyedReplay:
        return KeyedReplay(
            memory_view(replay.memory, b),
            replay.keys[b],
            replay.bases[b],
            replay.estimates[b],
            *record_view(replay, b),
            replay.params,
        )

    def stored(self, replay: KeyedReplay, b: int) -> int:
        return int(replay.memory.size[b])

    def draw(self, replay: KeyedReplay, rngs: Sequence[np.random.Generator], batch_size: int):
        return sample_memory(replay.memory, rngs, batch_size)

    def target_copied(self, replay: KeyedReplay, model: Any, inputs: str) -> None:
        """Nothing kept depends on the target copy."""

    def refresh(self, replay: KeyedReplay, model: Any, inputs: str) -> None:
        """Copy the record network's estimates (integer states: every state's; features:
        its layers) for the fold, where unseen states are compared with them."""
        if replay.params.estimate_unseen:
            copy_record(model, inputs, replay.record_table, replay.record_weights)

    def greedy_table(
        self, replay: KeyedReplay, table: np.ndarray, legal: np.ndarray, config
    ) -> np.ndarray:
        """(index inputs) The greedy table (B, n_states, n_agents) the side executes:
        the networks' ``table``, with (``act_from="memory"``) each kept state's greedy
        joint action from its memory degrees over its masks ``legal`` (B, n_states,
        n_agents, width); lowest index on ties, as the compiled greedy takes it."""
        if not config.acts_from_memory:
            return table
        memory = replay.memory
        for b in range(table.shape[0]):
            slots = memory.order[b, : memory.size[b]]
            states = memory.state[b, slots]
            degrees = np.where(legal[b, states], memory.target[b, slots], -np.inf)
            table[b, states] = degrees.argmax(axis=-1)
        return table

    def nbytes(self, view: KeyedReplay) -> int:
        arrays = [*view.memory, view.keys, view.bases, view.estimates, view.record_table]
        return sum(array.nbytes for array in arrays)


class BootstrappedKind:
    """A ring of visits with λ-returns bootstrapped from the record network
    (:class:`BootstrappedRing`)."""

    def new(self, config, seeds: int, counts: np.ndarray, spec: GameSpec, features: int):
        ring = RING.new(config, seeds, counts, spec, features)
        copies = record_copies(config, seeds, counts, spec, features)
        summed = config.update == "critic" and config.critic_form == "sum"
        lam = float(config.return_lambda)
        rewards = np.zeros((seeds, config.buffer_size), np.float32)
        return BootstrappedRing(
            ring, *copies, lam, config.greedy_bootstrap, summed, config.shares, rewards,
            config.refresh_returns,
        )  # fmt: skip

    def view(self, replay: BootstrappedRing, b: int) -> BootstrappedRing:
        view = seed_view(replay.ring, b)
        copies = record_view(replay, b)
        return BootstrappedRing(
            view, *copies, replay.lam, replay.greedy, replay.summed, replay.shares,
            replay.step_reward[b], replay.refreshes,
        )  # fmt: skip

    def stored(self, replay: BootstrappedRing, b: int) -> int:
        return int(replay.ring.size[b])

    def draw(self, replay: BootstrappedRing, rngs: Sequence[np.random.Generator], size: int):
        """A batch of visits (:func:`~cmarlcd.learners.deep.replay.sample`), each with its
        own reward (``step_reward``), which ``standardise_rewards`` reads."""
        picks = draw(replay.ring, rngs, size)
        out = rows_of(replay.ring, picks)
        out["step_reward"] = np.take_along_axis(replay.step_reward, picks, axis=1)
        return out

    def refresh(self, replay: BootstrappedRing, model: Any, inputs: str) -> None:
        """Copy the record network, which the next episodes' returns bootstrap from."""
        copy_record(model, inputs, replay.record_table, replay.record_weights)

    def target_copied(self, replay: BootstrappedRing, model: Any, inputs: str) -> None:
        """Recompute every stored λ-return from the model's estimates now
        (``refresh_returns``; :func:`~cmarlcd.learners.deep.replay.recompute_lambda_returns`)."""
        if not replay.refreshes:
            return
        ring, config = replay.ring, model.config
        with torch.no_grad():
            if inputs == "index":
                table = model.record_table()
                states = torch.from_numpy(ring.state.astype(np.int64)).to(table.device)
                values = torch.gather(table, 1, states)
            else:
                values = model.estimate(torch.from_numpy(ring.state).to(model.device))
        values = values.cpu().numpy().astype(np.float64)
        for b in range(values.shape[0]):
            recompute_lambda_returns(
                seed_view(ring, b), replay.step_reward[b], values[b], config.gamma, replay.lam
            )

    def greedy_table(self, replay, table: np.ndarray, legal: np.ndarray, config) -> np.ndarray:
        return table

    def nbytes(self, view: BootstrappedRing) -> int:
        return RING.nbytes(view.ring) + view.record_table.nbytes + view.step_reward.nbytes


RING, KEYED, BOOTSTRAPPED = RingKind(), KeyedKind(), BootstrappedKind()
