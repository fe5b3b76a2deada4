"""The fused CPU steps of VDN and QMIX (``DeepConfig.step = "fused"``) and of deep
CMARL-CD's keyed update (``DeepCMARLCDConfig.step``): the loss, its gradients and Adam in
compiled kernels (:mod:`cmarlcd.learners.deep.fused.kernels`,
:mod:`cmarlcd.learners.deep.fused.degree_kernels`) that read and write the model's own
parameters in place, so the model, its targets and everything that copies its weights
see the update as they see PyTorch's.

It replaces the model's autograd and optimiser step, not the model:
greedy actions, target copies and the side's weight copies still go through PyTorch. It
keeps its own Adam moments, so a model takes every step one way or the other.

The kernels run with subnormal floats flushed to zero (:func:`subnormals_flushed`).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import torch

from cmarlcd.errors import require
from cmarlcd.learners.deep.fused import degree_kernels as fused_degree_kernels
from cmarlcd.learners.deep.fused import kernels as fused_kernels
from cmarlcd.learners.deep.fused.networks import own_starts, spread_shared, stacked


def _arrays(module: torch.nn.Module) -> tuple[np.ndarray, ...]:
    """The module's parameters as NumPy arrays sharing their memory, in registration
    order."""
    return tuple(p.detach().numpy() for p in module.parameters())


class FusedStep:
    """The TD step of one :class:`ValueDecomposition` model, fused (see the module)."""

    def __init__(self, model) -> None:
        _on_the_cpu(model)
        self.model = model
        self.qmix = model.config.mixer == "qmix"
        self.agents, self.middle = _layers(model.agents)
        self.target_agents, self.target_middle = _layers(model.target_agents)
        self.layers = self.agents[4].shape[0] + 1
        self.share = bool(model.config.share)
        self.shared, self.target_shared = self.agents, self.target_agents
        if self.share:  # the kernels step per-agent layers spread from the shared network
            n = model.n_agents
            self.agents, self.target_agents = _per_agent(self.shared, n), _per_agent(self.shared, n)
        if self.qmix:
            self.mixer, self.target_mixer = _mixer(model.mixer), _mixer(model.target_mixer)
        else:  # VDN has no parameters: empty arrays of the kernels' types
            self.mixer = self.target_mixer = _no_mixer(model.n_seeds)
        self.agent_grads = tuple(np.zeros_like(p) for p in self.agents)
        self.shared_grads = (
            tuple(np.zeros_like(p) for p in self.shared) if self.share else _no_shared()
        )
        self.mixer_grads = tuple(np.zeros_like(p) for p in self.mixer)
        # Adam steps the model's own parameters, in their order (the middle layers' too,
        # which the kernels read from stacked copies), from the gradients laid out alike
        own_grads = self.shared_grads if self.share else self.agent_grads
        mixer, mixer_grads = (self.mixer, self.mixer_grads) if self.qmix else (None, None)
        params = [*_arrays(model.agents), *_mixer_in_order(mixer)]  # VDN's: none stepped
        grads = [*_in_order(own_grads), *_mixer_in_order(mixer_grads)]
        self.flat = _flat(params, grads)
        self.rates = np.full(len(params), model.optimizer.param_groups[0]["lr"], np.float64)
        self.adam = adam_settings(model.optimizer)
        self.steps = 0
        # integer states, masks per state: the target's Q_tot at every state, per seed
        states = self.agents[0].shape[1]
        self.target_table = np.zeros((model.n_seeds, states), np.float32)
        self.targets_changed()

    def targets_changed(self) -> None:
        """The target networks or the per-state masks changed: the kept target values
        are recomputed at the next step (as autograd's step recomputes its table)."""
        self.refresh = True

    def __call__(self, batch: dict[str, torch.Tensor]) -> float:
        """One step on a replay batch (the keys of :meth:`ValueDecomposition.td_loss`);
        the mean loss per seed."""
        index = batch["state"].dtype == torch.int64
        require(
            self.layers == 1 or not index,
            "hidden_layers",
            f"the fused step takes {self.layers} hidden layers on feature states only, "
            "not integer states; step=autograd there",
        )
        require(
            self.mixer[10].shape[1] == 0 or not index,
            "hypernet_layers",
            "the fused step takes two-layer hypernetworks on feature states only, not "
            "integer states; step=autograd there",
        )
        self.steps += 1
        per_state = index and "next_legal" not in batch
        n = self.model.n_agents
        _refresh(self.shared, self.middle, self.agents, self.share, n)
        _refresh(self.target_shared, self.target_middle, self.target_agents, self.share, n)
        arguments = (
            (self.agents, self.target_agents, self.mixer, self.target_mixer),
            (self.agent_grads, self.mixer_grads),
            self._batch(batch),
            self._legal(batch),
            self.model.valid.numpy(),
            self._shape(batch),
            (*self.flat, self.rates, (self.steps, *self.adam)),
            (self.refresh, self.target_table),
            (self.share, self.shared_grads),
        )
        with subnormals_flushed():
            loss = fused_kernels.td_step(*arguments)
        if per_state:
            self.refresh = False
        return loss / self.model.n_seeds

    def _batch(self, batch: dict[str, torch.Tensor]) -> tuple:
        features, states = split_states(batch["state"])
        next_features, next_states = split_states(batch["next_state"])
        return (
            features,
            next_features,
            states,
            next_states,
            batch["actions"].numpy(),
            np.ascontiguousarray(batch["reward"].numpy(), np.float32),
            batch["terminal"].numpy(),
        )

    def _legal(self, batch: dict[str, torch.Tensor]) -> tuple:
        seeds, n, width = self.model.n_seeds, self.model.n_agents, self.model.width
        own = batch.get("next_legal")
        if own is not None:  # as autograd's step does, a mask that broadcasts is one
            shape = (seeds, batch["state"].shape[1], n, width)
            legal = np.ascontiguousarray(np.broadcast_to(own.numpy(), shape))
            return True, legal, np.empty((0, 0, n, width), np.bool_)
        none = np.empty((0, 0, 0, width), np.bool_)
        legal = self.model.state_legal
        if legal is None or batch["state"].dtype != torch.int64:
            return False, none, np.empty((0, 0, n, width), np.bool_)
        legal = legal.numpy()
        if legal.ndim == 3:
            legal = np.broadcast_to(legal, (seeds, *legal.shape))
        return False, none, np.ascontiguousarray(legal)

    def _shape(self, batch: dict[str, torch.Tensor]) -> tuple:
        model = self.model
        index = batch["state"].dtype == torch.int64
        own = model.agents.own_dim or 0
        units = model.mixer.hidden if self.qmix else 0
        clip = float(model.config.grad_clip or 0.0)
        config = model.config
        gamma, double_q = float(config.gamma), config.double_q
        independent, weight = config.independent, float(config.negative_weight)
        return (
            self.qmix, index, gamma, own, model.mixer_dim, units, double_q, clip,
            independent, weight,
        )  # fmt: skip


class FusedDegreeStep:
    """The keyed update of one :class:`cmarlcd.learners.deep.degree_model.DegreeModel`, fused
    (:mod:`cmarlcd.learners.deep.fused.degree_kernels`): the degree networks regressed onto
    the keyed memory's degrees and, where unseen states are compared with an estimate,
    the record network onto its records; Adam with each network's learning rate."""

    def __init__(self, model) -> None:
        _on_the_cpu(model)
        self.model = model
        self.estimates = model.config.estimates_unseen
        self.agents, self.record = _arrays(model.agents), _arrays(model.record)
        self.agent_grads = tuple(np.zeros_like(p) for p in self.agents)
        self.record_grads = tuple(np.zeros_like(p) for p in self.record)
        # a network that gets no gradient is not stepped (PyTorch's Adam skips it)
        params = [*self.agents, *(self.record if self.estimates else ())]
        grads = [*self.agent_grads, *(self.record_grads if self.estimates else ())]
        self.flat = _flat(params, grads)
        rates = [model.config.lr] * 4 + [model.config.record_lr] * (len(params) - 4)
        self.rates = np.array(rates, np.float64)
        self.adam = adam_settings(model.optimizer)
        self.steps = 0
        # each agent's own observation, the last n * own features, where it reads one
        self.own = model.agents.own_dim or 0
        self.starts = own_starts(self.record[0].shape[1], model.n_agents, self.own)

    def __call__(self, batch: dict[str, torch.Tensor]) -> float:
        """One step on a batch of kept states (:meth:`DegreeModel.keyed_loss`'s keys); the
        mean loss per seed."""
        self.steps += 1
        index = batch["state"].dtype == torch.int64
        features, states = split_states(batch["state"])
        n_states = self.agents[0].shape[1] if index else 0
        arguments = (
            (self.agents, self.record),
            (self.agent_grads, self.record_grads),
            (
                features,
                states,
                np.ascontiguousarray(batch["target"].numpy(), np.float32),
                np.ascontiguousarray(batch["record"].numpy(), np.float32),
            ),
            self.model.valid.numpy(),
            (index, n_states, self.estimates, self.starts, self.own),
            (*self.flat, self.rates, (self.steps, *self.adam)),
        )
        with subnormals_flushed():
            loss = fused_degree_kernels.keyed_step(*arguments)
        return loss / self.model.n_seeds


class FusedSharesStep:
    """The shares of one :class:`cmarlcd.learners.deep.degree_model.DegreeModel`
    (``update="critic"``, ``critic_form="degrees"``), fused
    (:func:`cmarlcd.learners.deep.fused.degree_kernels.shares_step`): the degrees at each
    visit's taken joint action, summed, fitted to its stored return by the expectile loss;
    the agent networks as VDN's fused step takes them (one per agent or one shared, one
    hidden layer or more on feature states). Only the degree networks learn: the record
    network gets no gradient there, and PyTorch's Adam does not step it either."""

    def __init__(self, model) -> None:
        _on_the_cpu(model)
        self.model = model
        self.share = bool(model.config.share)
        self.shared, self.middle = _layers(model.agents)
        n = model.n_agents
        self.agents = _per_agent(self.shared, n) if self.share else self.shared
        self.agent_grads = tuple(np.zeros_like(p) for p in self.agents)
        self.shared_grads = (
            tuple(np.zeros_like(p) for p in self.shared) if self.share else _no_shared()
        )
        own_grads = self.shared_grads if self.share else self.agent_grads
        self.flat = _flat(list(_arrays(model.agents)), _in_order(own_grads))
        self.rates = np.full(len(self.flat[0]), model.config.lr, np.float64)
        self.adam = adam_settings(model.optimizer)
        self.steps = 0
        self.own = model.agents.own_dim or 0

    def __call__(self, batch: dict[str, torch.Tensor]) -> float:
        """One step on a batch of visits (:meth:`DegreeModel.critic_loss`'s keys:
        ``state``, ``actions``, ``reward``, the stored returns); the mean loss per seed."""
        index = batch["state"].dtype == torch.int64
        require(
            self.middle[0] == [] or not index,
            "hidden_layers",
            f"the fused step takes {len(self.middle[0]) + 1} hidden layers on feature "
            "states only, not integer states; step=autograd there",
        )
        self.steps += 1
        _refresh(self.shared, self.middle, self.agents, self.share, self.model.n_agents)
        features, states = split_states(batch["state"])
        returns = np.ascontiguousarray(batch["reward"].numpy(), np.float32)
        arguments = (
            self.agents,
            self.agent_grads,
            (features, states, batch["actions"].numpy(), returns),
            self.model.valid.numpy(),
            (index, self.own, float(self.model.config.expectile)),
            (*self.flat, self.rates, (self.steps, *self.adam)),
            (self.share, self.shared_grads),
        )
        with subnormals_flushed():
            loss = fused_degree_kernels.shares_step(*arguments)
        return loss / self.model.n_seeds


def _refresh(net, middle, agents, share: bool, n: int) -> None:
    """The kernels' copies of a network as it is now: its middle layers stacked into
    ``net`` (laid out as :func:`_layers`'s) from their own parameters ``middle``
    (weights, biases), and, where the agents share it, spread into each agent's layers
    ``agents``."""
    weights, biases = middle
    stacked(weights, net[4]), stacked(biases, net[5])
    if share:
        spread_shared(net, agents, n)


@contextmanager
def subnormals_flushed() -> Iterator[None]:
    """Run the block with subnormal floats (magnitude below 1.2e-38 in float32) read and
    written as zero on this thread (the CPU's flush-to-zero and denormals-are-zero
    modes, :func:`torch.set_flush_denormal`), then leave the thread's mode as it was.

    Why: a parameter that gets no gradient for a while (a state the batches miss) has
    Adam's first moment decay by beta1 per step into the subnormals, where every
    arithmetic operation takes a slow path of the CPU; on the DSN's tables that tripled
    the step's time. Flushed, such a moment is zero a few steps sooner. No parameter
    moves differently in practice: a moment that small changes a weight by less than
    ``lr`` × 1.2e-30 (Adam divides by at least its eps, 1e-8), far below a float32
    weight's rounding, and fixed-seed runs store the same numbers, bit for bit, with and
    without the flush (docs: The fused gradient step). Where the CPU has no
    such mode (``set_flush_denormal`` is False) the block runs as it is."""
    was_flushing = flushing_subnormals()
    turned_on = not was_flushing and torch.set_flush_denormal(True)
    try:
        yield
    finally:
        if turned_on:
            torch.set_flush_denormal(False)


def flushing_subnormals() -> bool:
    """Whether this thread flushes subnormal results to zero now (a float32 product that
    is subnormal when computed exactly comes back as zero)."""
    tiny = np.array([1.0e-38], np.float32)
    return bool((tiny * np.float32(0.5))[0] == 0.0)


def split_states(state: torch.Tensor) -> tuple[np.ndarray, np.ndarray]:
    """(features (B, N, F) float32, integer states (B, N)) of a batch's states: the kind
    it is not of is an empty (features) or zero (states) stand-in of the kernels' types."""
    array = state.numpy()
    seeds, count = array.shape[:2]
    if array.dtype == np.int64:
        return np.empty((seeds, count, 0), np.float32), array
    return np.ascontiguousarray(array, np.float32), np.zeros((seeds, count), np.int64)


def _layers(module: torch.nn.Module) -> tuple[tuple[np.ndarray, ...], tuple[list, list]]:
    """An agent network's layers as the kernels read them, ``(w1, b1, w2, b2, wm, bm)``
    (:mod:`~cmarlcd.learners.deep.fused.networks`; ``wm``, ``bm`` stacked copies of the
    middle layers, empty for one hidden layer), and the middle layers' own parameters
    (weights, biases), which the copies are refreshed from."""
    w1, b1, *middle, w2, b2 = _arrays(module)
    weights, biases = middle[0::2], middle[1::2]
    groups, units = w1.shape[0], w1.shape[2]
    wm = stacked(weights, np.zeros((len(weights), groups, units, units), np.float32))
    bm = stacked(biases, np.zeros((len(biases), groups, units), np.float32))
    return (w1, b1, w2, b2, wm, bm), (weights, biases)


def _in_order(net: tuple[np.ndarray, ...]) -> list[np.ndarray]:
    """The arrays of ``net`` (laid out as :func:`_layers`'s) in the module's parameter
    order: the first layer, each middle layer (weight, bias), the output layer."""
    w1, b1, w2, b2, wm, bm = net
    middle = [array for layer in range(wm.shape[0]) for array in (wm[layer], bm[layer])]
    return [w1, b1, *middle, w2, b2]


def _per_agent(shared: tuple[np.ndarray, ...], n: int) -> tuple[np.ndarray, ...]:
    """Per-agent layers (B*n groups) for a network shared by ``n`` agents: its first
    layer without the agents' index rows, the others as they are."""
    w1, b1, w2, b2, wm, bm = shared
    seeds, inputs = w1.shape[0], w1.shape[1] - n
    return (
        np.zeros((seeds * n, inputs, w1.shape[2]), np.float32),
        np.zeros((seeds * n, b1.shape[1]), np.float32),
        np.zeros((seeds * n, *w2.shape[1:]), np.float32),
        np.zeros((seeds * n, b2.shape[1]), np.float32),
        np.zeros((wm.shape[0], seeds * n, *wm.shape[2:]), np.float32),
        np.zeros((bm.shape[0], seeds * n, bm.shape[2]), np.float32),
    )


def _no_shared() -> tuple[np.ndarray, ...]:
    """Empty stand-ins of a shared network's gradients, of the kernels' types."""
    return (np.zeros((0, 0, 0), np.float32), np.zeros((0, 0), np.float32),
            np.zeros((0, 0, 0), np.float32), np.zeros((0, 0), np.float32),
            np.zeros((0, 0, 0, 0), np.float32), np.zeros((0, 0, 0), np.float32))  # fmt: skip


def _on_the_cpu(model) -> None:
    require(
        model.device.type == "cpu",
        "step",
        f"the fused step runs on the CPU, not {model.device}; use step=autograd there",
    )


def _flat(params: list[np.ndarray], grads: list[np.ndarray]) -> tuple:
    """Flat views of the parameters and gradients, and Adam's two moments (zeros)."""
    return (
        tuple(p.reshape(-1) for p in params),
        tuple(g.reshape(-1) for g in grads),
        tuple(np.zeros(p.size, np.float32) for p in params),
        tuple(np.zeros(p.size, np.float32) for p in params),
    )


def adam_settings(optimizer: torch.optim.Optimizer) -> tuple[float, float, float]:
    """(beta1, beta2, eps) of a PyTorch Adam (every group's are the defaults here)."""
    group = optimizer.param_groups[0]
    beta1, beta2 = group["betas"]
    return float(beta1), float(beta2), float(group["eps"])


def _no_mixer(seeds: int, count: int = 14) -> tuple[np.ndarray, ...]:
    """``count`` empty arrays shaped as QMIX's parameters (3-d weights, 2-d biases)."""
    return tuple(
        np.zeros((seeds, 0, 0) if k % 2 == 0 else (seeds, 0), np.float32) for k in range(count)
    )


def _mixer(module: torch.nn.Module) -> tuple[np.ndarray, ...]:
    """QMIX's parameters as the kernels take them (:mod:`~cmarlcd.learners.deep.fused.mixers`:
    the weights' hypernetworks' last layers first, their first layers at the end, empty
    for one-layer hypernetworks)."""
    arrays = _arrays(module)
    if len(arrays) == 10:  # one-layer hypernetworks
        return (*arrays, *_no_mixer(arrays[0].shape[0], 4))
    e1, e1_b, hw1, hw1_b, hb1, hb1_b, e2, e2_b, hw2, hw2_b, v1, v1_b, v2, v2_b = arrays
    return hw1, hw1_b, hb1, hb1_b, hw2, hw2_b, v1, v1_b, v2, v2_b, e1, e1_b, e2, e2_b


def _mixer_in_order(mixer: tuple[np.ndarray, ...] | None) -> list[np.ndarray]:
    """The arrays of ``mixer`` (laid out as :func:`_mixer`'s) in the module's parameter
    order; none for no mixer."""
    if mixer is None:
        return []
    hw1, hw1_b, hb1, hb1_b, hw2, hw2_b, v1, v1_b, v2, v2_b, e1, e1_b, e2, e2_b = mixer
    if e1.shape[1] == 0:
        return list(mixer[:10])
    return [e1, e1_b, hw1, hw1_b, hb1, hb1_b, e2, e2_b, hw2, hw2_b, v1, v1_b, v2, v2_b]
