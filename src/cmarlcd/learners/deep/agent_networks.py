"""The agent networks of the deep learners, B seeds stacked (``[deep]`` extra).

Every tensor carries a leading *group* axis: one group per independent seed (and per
agent for :class:`AgentNetworks`), so B seeds train as one stacked model with batched
matrix products, and no parameter is shared between seeds.

* :class:`GroupLinear` -- B independent linear layers applied in one ``bmm``; for one-hot
  inputs (integer states), :meth:`GroupLinear.table` gives the layer's output for every
  state, so a network is evaluated once per distinct state and then looked up.
* :class:`AgentNetworks` -- one MLP per agent ([choice] ``share=False``, the paper's VDN
  and QMIX): state (or, with ``own_dim``, the agent's own observation) -> hidden (ReLU)
  -> a value per action; with ``layers`` > 1 ([choice] ``hidden_layers``, EPyMARL's
  feed-forward agent has two), more hidden layers of the same width (ReLU) between.
* :class:`SharedAgentNetwork` -- one MLP per seed for every agent ([choice]
  ``share=True``, EPyMARL's default ``agent: rnn`` with ``obs_agent_id``, here without the
  recurrent layer), the agent's one-hot index appended to its input. The compiled loops
  act with it as with per-agent networks: agent ``i``'s network is the shared one with
  its index row of the first layer folded into the first bias
  (:meth:`SharedAgentNetwork.feature_weights`).

Decentralised inputs (``own_dim``): a feature vector laid out as the mixer's state
followed by every agent's own observation, ``[s, o_1, ..., o_n]`` with each ``o_i`` of
``own_dim`` features; agent ``i``'s network then reads ``o_i`` alone.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
import torch
from torch import nn


class GroupLinear(nn.Module):
    """``groups`` independent linear layers ``in_dim -> out_dim``, applied with one bmm.

    Initialised like :class:`torch.nn.Linear` (uniform ±1/sqrt(in_dim)), group by group
    from that group's generator, so a group's parameters do not depend on the others.
    """

    def __init__(self, in_dim: int, out_dim: int, generators: Sequence[torch.Generator]) -> None:
        super().__init__()
        bound = 1.0 / math.sqrt(in_dim)
        weights, biases = [], []
        for gen in generators:
            weights.append(_uniform((in_dim, out_dim), bound, gen))
            biases.append(_uniform((out_dim,), bound, gen))
        self.weight = nn.Parameter(torch.stack(weights))
        self.bias = nn.Parameter(torch.stack(biases))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """``x``: (groups, N, in_dim) -> (groups, N, out_dim)."""
        return torch.baddbmm(self.bias[:, None, :], x, self.weight)

    def table(self) -> torch.Tensor:
        """The layer's output for every one-hot input: (groups, in_dim, out_dim)."""
        return self.weight + self.bias[:, None, :]


def rows(table: torch.Tensor, state: torch.Tensor) -> torch.Tensor:
    """``table`` (B, S, ...) at the integer states ``state`` (B, N) -> (B, N, ...)."""
    b, count = table.shape[:2]
    flat = table.reshape(b, count, -1)
    picked = torch.gather(flat, 1, state[:, :, None].expand(-1, -1, flat.shape[2]))
    return picked.view(*state.shape, *table.shape[2:])


def _uniform(shape: tuple[int, ...], bound: float, gen: torch.Generator) -> torch.Tensor:
    return (torch.rand(shape, generator=gen) * 2.0 - 1.0) * bound


def per_state(
    first: GroupLinear, state: torch.Tensor, rest: Callable[[torch.Tensor], torch.Tensor]
) -> torch.Tensor:
    """``rest(first(x))`` for the states: feature vectors go through as they are; integer
    states (one-hot encoding) are evaluated once per distinct state and then looked up,
    which gives the same values at a fraction of the cost."""
    if state.dtype == torch.int64:
        return rows(rest(first.table()), state)
    return rest(first(state))


def identity(x: torch.Tensor) -> torch.Tensor:
    """``x`` itself (the ``rest`` of :func:`per_state` that changes nothing)."""
    return x


def middle_layers(layers: int, hidden: int, generators: Sequence[torch.Generator]) -> nn.ModuleList:
    """The ``layers - 1`` hidden layers after the first, ``hidden -> hidden`` each (none
    for one hidden layer, so a network of one draws nothing more from its generators)."""
    if layers < 1:
        raise ValueError(f"hidden_layers must be >= 1 (got {layers})")
    return nn.ModuleList(GroupLinear(hidden, hidden, generators) for _ in range(layers - 1))


def through(middle: nn.ModuleList, hidden: torch.Tensor) -> torch.Tensor:
    """``hidden`` (groups, N, H), a first hidden layer's ReLU, through the middle layers
    (each a linear layer and a ReLU)."""
    for layer in middle:
        hidden = torch.relu(layer(hidden))
    return hidden


def stacked_middle(middle: nn.ModuleList, groups: int, hidden: int, like: torch.Tensor):
    """The middle layers as the compiled loop reads them: weights (groups, L - 1, H, H)
    and biases (groups, L - 1, H), empty along L - 1 for one hidden layer."""
    if not middle:
        return like.new_zeros((groups, 0, hidden, hidden)), like.new_zeros((groups, 0, hidden))
    weights = torch.stack([layer.weight for layer in middle], dim=1)
    return weights, torch.stack([layer.bias for layer in middle], dim=1)


class AgentNetworks(nn.Module):
    """Per-agent MLPs for B seeds: state -> Linear -> ReLU -> (``layers - 1`` times
    Linear -> ReLU) -> Linear -> Q over actions.

    With ``own_dim``, agent ``i`` reads only its own observation, the ``i``-th of the
    last ``n_agents * own_dim`` features of the input (the layout ``[s, o_1, ..., o_n]``
    of the module's docstring). Rows are padded to the largest action count; padded
    actions are masked by callers.
    """

    def __init__(
        self,
        seeds: int,
        n_agents: int,
        in_dim: int,
        hidden: int,
        n_actions: int,
        generators: Sequence[Sequence[torch.Generator]],
        own_dim: int | None = None,
        layers: int = 1,
    ) -> None:
        super().__init__()
        self.seeds, self.n_agents, self.own_dim = seeds, n_agents, own_dim
        flat = [gens[i] for gens in generators for i in range(n_agents)]
        self.first = GroupLinear(in_dim if own_dim is None else own_dim, hidden, flat)
        self.middle = middle_layers(layers, hidden, flat)
        self.second = GroupLinear(hidden, n_actions, flat)
        self._scratch: tuple[torch.Tensor, torch.Tensor] | None = None
        """:meth:`copy_tables`' hidden layer and outputs, made at its first call."""

    def forward(self, state: torch.Tensor) -> torch.Tensor:
        """``state``: (B, N) int64 or (B, N, in_dim) -> Q (B, N, n_agents, n_actions)."""
        if state.dtype == torch.int64:
            return rows(self.tables(), state)
        hidden = through(self.middle, torch.relu(self.first(self._inputs(state))))
        return self._by_seed(self.second(hidden))

    def _inputs(self, state: torch.Tensor) -> torch.Tensor:
        """(B, N, in_dim) -> each agent's input, (B*n, N, in) grouped seed-major."""
        if self.own_dim is None:
            return state.repeat_interleave(self.n_agents, dim=0)
        b, count, n = state.shape[0], state.shape[1], self.n_agents
        own = state[..., state.shape[2] - n * self.own_dim :].reshape(b, count, n, self.own_dim)
        return own.transpose(1, 2).reshape(b * n, count, self.own_dim)

    def tables(self) -> torch.Tensor:
        """Q of every integer (one-hot) state: (B, in_dim, n_agents, n_actions)."""
        return self._by_seed(self.second(through(self.middle, torch.relu(self.first.table()))))

    def copy_tables(self, out: np.ndarray) -> None:
        """``out`` (B, in_dim, n_agents, n_actions) := :meth:`tables`, bit for bit (the
        same operations), computed in scratch kept between calls: the loop's copy after
        every gradient step spent most of its time getting fresh memory for them."""
        if self.middle:  # more hidden layers: no scratch of their own
            with torch.no_grad():
                np.copyto(out, self.tables().cpu().numpy())
            return
        weight = self.first.weight
        if self._scratch is None or self._scratch[0].device != weight.device:
            groups, states = weight.shape[:2]
            self._scratch = (
                torch.empty((groups, states, self.first.weight.shape[2]), device=weight.device),
                torch.empty((groups, states, self.second.weight.shape[2]), device=weight.device),
            )
        hidden, q = self._scratch
        with torch.no_grad():
            torch.add(weight, self.first.bias[:, None, :], out=hidden)
            hidden.relu_()
            torch.baddbmm(self.second.bias[:, None, :], hidden, self.second.weight, out=q)
        np.copyto(out, self._by_seed(q).cpu().numpy())

    def feature_weights(self) -> tuple[torch.Tensor, ...]:
        """The per-agent layers the compiled loop reads (w1, b1, w2, b2, then the middle
        layers' weights and biases, :func:`stacked_middle`), agent-major."""
        first, second = self.first, self.second
        middle = stacked_middle(
            self.middle, first.weight.shape[0], first.weight.shape[2], first.weight
        )
        return first.weight, first.bias, second.weight, second.bias, *middle

    def _by_seed(self, q: torch.Tensor) -> torch.Tensor:
        """(B*n, N, A), grouped seed-major -> (B, N, n, A)."""
        return q.view(self.seeds, self.n_agents, *q.shape[1:]).transpose(1, 2)


class SharedAgentNetwork(nn.Module):
    """One MLP per seed for every agent: input the state (with ``own_dim``, the agent's
    own observation, as in :class:`AgentNetworks`) and the agent's one-hot index, output
    one value per action; the same interface as :class:`AgentNetworks`. Seed ``k``'s
    weights are drawn from ``generators[k]``, like a ``torch.nn.Linear`` of the input
    and index features."""

    def __init__(
        self,
        seeds: int,
        n_agents: int,
        in_dim: int,
        hidden: int,
        n_actions: int,
        generators: Sequence[torch.Generator],
        own_dim: int | None = None,
        layers: int = 1,
    ) -> None:
        super().__init__()
        self.seeds, self.n_agents, self.own_dim = seeds, n_agents, own_dim
        self.in_dim = in_dim if own_dim is None else own_dim
        """The features each agent reads before its index: the state's or its own."""
        self.first = GroupLinear(self.in_dim + n_agents, hidden, generators)
        self.middle = middle_layers(layers, hidden, generators)
        self.second = GroupLinear(hidden, n_actions, generators)

    def _hidden(self, x: torch.Tensor) -> torch.Tensor:
        """(B, N, H) -> ReLU of every agent's first hidden layer, (B, N, n, H)."""
        agent = self.first.weight[:, self.in_dim :]  # (B, n, H): each agent's index row
        return torch.relu(x[:, :, None, :] + agent[:, None])

    def _values(self, hidden: torch.Tensor) -> torch.Tensor:
        """Every agent's first hidden layer (B, N, n, H) -> values (B, N, n, n_actions),
        through the middle layers."""
        b, n = hidden.shape[:2]
        flat = through(self.middle, hidden.reshape(b, -1, hidden.shape[-1]))
        out = torch.baddbmm(self.second.bias[:, None], flat, self.second.weight)
        return out.view(b, n, self.n_agents, -1)

    def forward(self, state: torch.Tensor) -> torch.Tensor:
        """``state``: (B, N) int64 or (B, N, in_dim) -> values (B, N, n_agents, n_actions)."""
        if state.dtype == torch.int64:
            return rows(self.tables(), state)
        weight, bias = self.first.weight[:, : self.in_dim], self.first.bias[:, None]
        b, n = state.shape[:2]
        if self.own_dim is None:
            hidden = self._hidden(torch.baddbmm(bias, state, weight))
        else:  # every agent's own observation through the same layer: (B, N * n, own)
            agents, own = self.n_agents, self.own_dim
            tail = state[..., state.shape[2] - agents * own :].reshape(b, n * agents, own)
            x = torch.baddbmm(bias, tail, weight).view(b, n, agents, -1)
            hidden = torch.relu(x + self.first.weight[:, None, self.in_dim :])
        return self._values(hidden)

    def tables(self) -> torch.Tensor:
        """Values of every integer (one-hot) state: (B, in_dim, n_agents, n_actions)."""
        if self.own_dim is not None:
            raise ValueError("integer states have no own observations (own_dim)")
        x = self.first.weight[:, : self.in_dim] + self.first.bias[:, None]  # (B, S, H)
        return self._values(self._hidden(x))

    def copy_tables(self, out: np.ndarray) -> None:
        """``out`` (B, in_dim, n_agents, n_actions) := :meth:`tables`."""
        with torch.no_grad():
            np.copyto(out, self.tables().cpu().numpy())

    def feature_weights(self) -> tuple[torch.Tensor, ...]:
        """The per-agent layers the compiled loop reads, agent-major (B * n, ...): the
        shared weights, each agent's index row folded into its first bias."""
        n, f = self.n_agents, self.in_dim
        w1 = self.first.weight[:, :f].repeat_interleave(n, dim=0)
        b1 = (self.first.bias[:, None] + self.first.weight[:, f:]).reshape(-1, w1.shape[-1])
        w2 = self.second.weight.repeat_interleave(n, dim=0)
        b2 = self.second.bias.repeat_interleave(n, dim=0)
        groups, hidden = self.first.weight.shape[0], self.first.weight.shape[2]
        middle = stacked_middle(self.middle, groups, hidden, w1)
        return w1, b1, w2, b2, *(m.repeat_interleave(n, dim=0) for m in middle)
