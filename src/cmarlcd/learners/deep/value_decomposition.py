"""VDN and QMIX baselines (paper Section V-A/B), trained B seeds at a time.

Requires the ``[deep]`` extra (PyTorch). Every tensor carries a leading *group* axis: one
group per independent seed (and per agent for the agent networks), so B seeds train as one
stacked model with batched matrix products. Each seed has its own parameters, initialised
from its own generator, its own replay buffer and its own random streams; the losses of
the seeds are summed, and since no parameter is shared, each seed's gradient (and its Adam
update, which is element-wise) is exactly what it would be alone.

Pieces, each in one place:

* the agent networks (:mod:`cmarlcd.learners.deep.agent_networks`): one MLP per agent
  (:class:`AgentNetworks`, the paper's), or with ``share`` one per seed for every agent,
  the agent's one-hot index in its input (:class:`SharedAgentNetwork`, EPyMARL's);
* :class:`VDNMixer` (``Q_tot = Σ_i Q_i``) and :class:`QMixer` (hypernetworks on the state,
  non-negative weights via ``abs``, an ELU hidden layer, a state-dependent bias).
* :class:`ValueDecomposition` -- online and target networks, Adam, the one-step TD loss
  with the target network's greedy legal action (or, with ``double_q``, the online
  network's, valued by the target network), target copies, greedy action tables; and
  EPyMARL's optional parts (:mod:`cmarlcd.learners.deep.td_options`): rewards
  standardised by running statistics and each seed's gradient norm clipped.

Decentralised inputs (``own_dim``): a feature vector may be laid out as the mixer's state
followed by every agent's own observation, ``[s, o_1, ..., o_n]`` with each ``o_i`` of
``own_dim`` features; agent ``i``'s network then reads ``o_i`` alone and QMIX's mixer reads
``s``, as in the VDN and QMIX papers (centralised training, decentralised execution).

Integer states (the DSN's 43) take a fast path that gives the same values as the one-hot
product: the agents' Q-values are a table over the states, and QMIX's first mixing layer,
``Σ_i Q_i |W1(s)|_i``, is one ``embedding_bag`` over the rows ``(seed, s, i)`` of the
hypernetwork's table weighted by ``Q_i``, so no per-sample weight matrix is ever built.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence

import numpy as np
import torch
from torch import nn

from cmarlcd.learners.deep.agent_networks import (
    AgentNetworks,
    GroupLinear,
    SharedAgentNetwork,
    identity,
    per_state,
)
from cmarlcd.learners.deep.config import DeepConfig, takes_fused_step
from cmarlcd.learners.deep.fused.step import FusedStep
from cmarlcd.learners.deep.td_options import RewardStatistics, clip_per_seed
from cmarlcd.learners.deep.threads import intra_op_threads, step_threads, step_work


class VDNMixer(nn.Module):
    """VDN: ``Q_tot = Σ_i Q_i``."""

    def forward(self, q: torch.Tensor, state: torch.Tensor) -> torch.Tensor:
        return q.sum(dim=-1)


class NoMixer(nn.Module):
    """No mixer (deep IQL, hysteretic DQN): each agent's value stays its own,
    ``(B, N, n) -> (B, N, n)``, and so does its TD target."""

    def forward(self, q: torch.Tensor, state: torch.Tensor) -> torch.Tensor:
        return q


class TwoLayerHypernetwork(nn.Module):
    """A hypernetwork of two layers for B seeds, ``Linear -> ReLU -> Linear`` of the
    state (EPyMARL's QMIX with ``hypernet_layers: 2``, ``hypernet_embed`` hidden units),
    with :class:`GroupLinear`'s interface: called on states, or :meth:`table` for every
    one-hot state."""

    def __init__(
        self, in_dim: int, embed: int, out_dim: int, generators: Sequence[torch.Generator]
    ) -> None:
        super().__init__()
        self.first = GroupLinear(in_dim, embed, generators)
        self.second = GroupLinear(embed, out_dim, generators)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.second(torch.relu(self.first(x)))

    def table(self) -> torch.Tensor:
        """The output for every one-hot input: (groups, in_dim, out_dim)."""
        return self.second(torch.relu(self.first.table()))


class QMixer(nn.Module):
    """QMIX's monotonic mixer for B seeds: hypernetworks on the state give non-negative
    (``abs``) weights, an ELU hidden layer of ``hidden`` units and a state-dependent bias
    ``V(s)`` (a ReLU MLP), so ``∂Q_tot/∂Q_i >= 0``. The weights' hypernetworks are one
    linear layer each (the paper's), or with ``hypernet_hidden`` two
    (:class:`TwoLayerHypernetwork`, EPyMARL's)."""

    def __init__(
        self,
        seeds: int,
        n_agents: int,
        in_dim: int,
        hidden: int,
        generators: Sequence[Sequence[torch.Generator]],
        hypernet_hidden: int | None = None,
    ) -> None:
        super().__init__()
        gens = [g[-1] for g in generators]  # each seed's mixer generator
        self.hidden = hidden
        embed = hypernet_hidden

        def hyper(out_dim: int) -> nn.Module:
            if embed is None:
                return GroupLinear(in_dim, out_dim, gens)
            return TwoLayerHypernetwork(in_dim, embed, out_dim, gens)

        self.hyper_w1 = hyper(n_agents * hidden)
        self.hyper_b1 = GroupLinear(in_dim, hidden, gens)
        self.hyper_w2 = hyper(hidden)
        self.value_1 = GroupLinear(in_dim, hidden, gens)
        self.value_2 = GroupLinear(hidden, 1, gens)

    def forward(self, q: torch.Tensor, state: torch.Tensor) -> torch.Tensor:
        """``q``: (B, N, n_agents), ``state``: (B, N[, in]) -> Q_tot (B, N)."""
        b1 = per_state(self.hyper_b1, state, identity)
        hidden = nn.functional.elu(self._first_layer(q, state) + b1)
        w2 = per_state(self.hyper_w2, state, torch.abs)
        value = per_state(self.value_1, state, lambda x: self.value_2(torch.relu(x)))[..., 0]
        return (hidden * w2).sum(dim=-1) + value

    def _first_layer(self, q: torch.Tensor, state: torch.Tensor) -> torch.Tensor:
        """``Σ_i q_i |W1(s)|_i``: (B, N, hidden)."""
        b, n, agents = q.shape
        if state.dtype != torch.int64:
            w1 = torch.abs(self.hyper_w1(state)).view(b, n, agents, self.hidden)
            return (q[..., None] * w1).sum(dim=2)
        w1 = torch.abs(self.hyper_w1.table())  # (B, S, agents * hidden)
        seed_state = torch.arange(b, device=state.device)[:, None] * w1.shape[1] + state
        bags = seed_state[..., None] * agents + torch.arange(agents, device=state.device)
        out = nn.functional.embedding_bag(
            bags.view(b * n, agents),
            w1.view(-1, self.hidden),
            mode="sum",
            per_sample_weights=q.reshape(b * n, agents),
        )
        return out.view(b, n, self.hidden)


# ------------------------------------------------------------------------ learner


class StackedModel(nn.Module):
    """What the stacked model of every deep learner has: B seeds of agents with these
    action counts (``valid``: each agent's real actions), each seed's generators (one
    per agent network, then one more), the per-state masks of integer states, and the
    device it computes on.

    Parameters are drawn on the CPU from each seed's generators, then moved with
    :meth:`place` (so a seed starts from the same weights on every device); every tensor
    a step makes is made on :attr:`device`.
    """

    def __init__(
        self,
        action_counts: Sequence[int],
        config,
        seeds: Sequence[np.random.SeedSequence],
        device: str = "cpu",
    ) -> None:
        super().__init__()
        self.config, self.device = config, torch.device(device)
        counts = torch.as_tensor(list(action_counts))
        self.n_agents, self.n_seeds = len(counts), len(seeds)
        self.width = int(counts.max())
        self.register_buffer("valid", torch.arange(self.width)[None, :] < counts[:, None])
        self.generators = [generators_of(s, self.n_agents + 1) for s in seeds]
        self.state_legal: torch.Tensor | None = None
        self._threads: int | None = None  # see step_threads

    def step_threads(self) -> int:
        """The intra-op threads its steps take (:mod:`cmarlcd.learners.deep.threads`),
        chosen at the first call from their work and the threads the process allows:
        one for the fused step and on a GPU."""
        if self._threads is None:
            if self.device.type != "cpu" or getattr(self, "fused", None) is not None:
                self._threads = 1
            else:
                self._threads = step_threads(step_work(self), torch.get_num_threads())
        return self._threads

    def optimise(self, loss: torch.Tensor, clip: float | None = None) -> float:
        """One Adam step on ``loss`` (the seeds' summed losses), each seed's gradient
        first clipped to norm ``clip`` if given
        (:func:`~cmarlcd.learners.deep.td_options.clip_per_seed`); the mean loss per seed.

        The backward pass and Adam take the model's own threads (:meth:`step_threads`),
        whoever calls: torch's fused Adam wakes every thread the process allows however
        small the parameters, and on a busy machine one step of a small model then waits
        tens of milliseconds for them (measured: 59 ms a step with 2 threads against 2.2
        with 1, beside three other processes on 2 cores)."""
        with intra_op_threads(self.step_threads()):
            self.optimizer.zero_grad(set_to_none=True)  # type: ignore[attr-defined]
            loss.backward()
            if clip is not None:
                params = [p for group in self.optimizer.param_groups for p in group["params"]]  # type: ignore[attr-defined]
                clip_per_seed(params, self.n_seeds, clip)
            self.optimizer.step()  # type: ignore[attr-defined]
        return float(loss.detach()) / self.n_seeds

    def place(self) -> None:
        """Move every parameter and buffer to :attr:`device` (before the optimiser is
        built on them)."""
        self.to(self.device)

    def _masked(self, values: torch.Tensor, legal: torch.Tensor | None) -> torch.Tensor:
        """``values`` with illegal and padded actions at -inf."""
        allowed = self.valid if legal is None else legal & self.valid
        return values.masked_fill(~allowed, -torch.inf)

    def set_state_legal(self, legal: torch.Tensor) -> None:
        """The legal actions of every integer state, (S, n, A) bool for all seeds or
        (B, S, n, A) for each seed its own, for games whose masks depend on the state
        (default: every action legal everywhere); on the CPU the model reads ``legal``
        itself (no copy)."""
        self.state_legal = legal.to(self.device)


class ValueDecomposition(StackedModel):
    """VDN or QMIX for B independent seeds: networks, targets, optimiser and TD step.

    Args:
        action_counts: actions of each agent.
        in_dim: state features, or the number of states for integer (one-hot) states.
        seeds: one :class:`numpy.random.SeedSequence` per seed (parameter initialisation).
        device: where it computes (``cpu``, ``cuda:N``; :mod:`cmarlcd.devices`).
        own_dim: features of each agent's own observation, for inputs laid out as
            ``[s, o_1, ..., o_n]`` (the agents read their own, the mixer ``s``); None:
            every network reads the whole input.
    """

    def __init__(
        self,
        action_counts: Sequence[int],
        in_dim: int,
        config: DeepConfig,
        seeds: Sequence[np.random.SeedSequence],
        device: str = "cpu",
        own_dim: int | None = None,
    ) -> None:
        super().__init__(action_counts, config, seeds, device)
        gens, width = self.generators, self.width
        self.agents: AgentNetworks | SharedAgentNetwork
        if config.share:
            shared = [g[0] for g in gens]  # each seed's first generator, as deep CMARL-CD's
            self.agents = SharedAgentNetwork(
                self.n_seeds, self.n_agents, in_dim, config.hidden, width, shared, own_dim,
                config.hidden_layers,
            )  # fmt: skip
        else:
            self.agents = AgentNetworks(
                self.n_seeds, self.n_agents, in_dim, config.hidden, width, gens, own_dim,
                config.hidden_layers,
            )  # fmt: skip
        self.mixer_dim = in_dim - (0 if own_dim is None else self.n_agents * own_dim)
        embed = config.hypernet_hidden if config.hypernet_layers == 2 else None
        self.mixer: nn.Module = (
            QMixer(self.n_seeds, self.n_agents, self.mixer_dim, config.mixer_hidden, gens, embed)
            if config.mixer == "qmix"
            else NoMixer()
            if config.independent
            else VDNMixer()
        )
        self.target_agents = copy.deepcopy(self.agents).requires_grad_(False)
        self.target_mixer = copy.deepcopy(self.mixer).requires_grad_(False)
        self._next_value_table: torch.Tensor | None = None  # see _next_values
        self.place()
        self.optimizer = torch.optim.Adam(
            list(self.agents.parameters()) + list(self.mixer.parameters()),
            lr=config.lr,
            fused=True,  # one pass over the parameters: ~10x the default on CPU (CUDA too)
        )
        fused = takes_fused_step(config.step, self.device, config.auto_fuses)
        self.fused = FusedStep(self) if fused else None
        self.rewards = RewardStatistics(self.n_seeds, self.device)
        """The running statistics of ``standardise_rewards`` (unused without it)."""

    def q_values(self, state: torch.Tensor, legal: torch.Tensor | None = None) -> torch.Tensor:
        """Online Q (B, N, n, A) with illegal and padded actions at -inf."""
        return self._masked(self.agents(state), legal)

    @torch.no_grad()
    def greedy(self, state: torch.Tensor, legal: torch.Tensor | None = None) -> torch.Tensor:
        """Greedy legal joint actions (B, N, n) for the states (B, N[, in])."""
        return self.q_values(state, legal).argmax(dim=-1)

    def set_state_legal(self, legal: torch.Tensor) -> None:
        """:meth:`StackedModel.set_state_legal`, read by :meth:`greedy_table` and for the
        next states of :meth:`td_step` (whose cached values it clears)."""
        super().set_state_legal(legal)
        self._next_value_table = None
        if getattr(self, "fused", None) is not None:  # None too while it is being made
            self.fused.targets_changed()

    @torch.no_grad()
    def greedy_table(self) -> torch.Tensor:
        """Greedy joint action (B, S, n) in every integer state (its legal actions)."""
        return self._masked(self.agents.tables(), self.state_legal).argmax(dim=-1)

    def learn(self, batch: dict[str, torch.Tensor]) -> float:
        """The learner's update on a replay batch: :meth:`td_step`."""
        return self.td_step(batch)

    def td_step(self, batch: dict[str, torch.Tensor]) -> float:
        """One Adam step on :meth:`td_loss` (by autograd, or the fused step of
        ``config.step``), on the batch's rewards standardised first where
        ``standardise_rewards`` says so; returns the mean loss per seed."""
        if self.config.standardise_rewards:
            batch = {**batch, "reward": self.rewards.standardise(batch["reward"])}
        if self.fused is not None:
            return self.fused(batch)
        return self.optimise(self.td_loss(batch), self.config.grad_clip)

    def td_loss(self, batch: dict[str, torch.Tensor]) -> torch.Tensor:
        """The summed per-seed one-step TD losses of VDN or QMIX (paper Section V-A/B).

        ``batch``: state (B, N[, in]), actions (B, N, n), reward (B, N), next_state,
        terminal (B, N) bool, and optionally next_legal (B, N, n, A) bool (default: the
        per-state masks of :meth:`set_state_legal` for integer states, else every action
        legal); every tensor on the model's device.
        """
        chosen = self._chosen_q(batch["state"], batch["actions"])
        q_tot = self.mixer(chosen, self._mixer_state(batch["state"]))
        with torch.no_grad():
            next_tot = self._next_values(batch["next_state"], batch.get("next_legal"))
            reward, alive = batch["reward"], (~batch["terminal"]).to(q_tot.dtype)
            if self.config.independent:  # each agent its own target: (B, N, n)
                reward, alive = reward[..., None], alive[..., None]
            target = reward + self.config.gamma * alive * next_tot
        if not self.config.independent:
            return ((q_tot - target) ** 2).mean(dim=1).sum()
        return self._independent_loss(q_tot, target)

    def _independent_loss(self, q: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        """Deep IQL's loss: each agent's squared TD error, the mean over transitions and
        agents (as EPyMARL's IQL averages them), summed over seeds; hysteretic DQN weighs
        an error whose TD error ``target − q`` is negative by ``negative_weight``."""
        error = q - target
        squared = error**2
        weight = self.config.negative_weight
        if weight != 1.0:
            squared = torch.where(error > 0, weight * squared, squared)
        return squared.mean(dim=(1, 2)).sum()

    def _mixer_state(self, state: torch.Tensor) -> torch.Tensor:
        """What the mixer reads of the input: all of it, or its state ``s`` where the
        agents read their own observations."""
        if state.dtype == torch.int64 or state.shape[-1] == self.mixer_dim:
            return state
        return state[..., : self.mixer_dim]

    def _chosen_q(self, state: torch.Tensor, actions: torch.Tensor) -> torch.Tensor:
        """Each agent's online Q of its action in ``actions`` (B, N, n)."""
        if state.dtype != torch.int64:
            return self.agents(state).gather(-1, actions[..., None])[..., 0]
        table = self.agents.tables()  # (B, S, n, A): pick entries, build no (B, N, n, A)
        b, _, n, width = table.shape
        flat = (state[..., None] * n + torch.arange(n, device=state.device)) * width + actions
        return table.reshape(b, -1).gather(1, flat.view(b, -1)).view(actions.shape)

    def _next_values(self, state: torch.Tensor, legal: torch.Tensor | None) -> torch.Tensor:
        """The target networks' ``Q_tot`` at ``state`` (B, N) with each agent's best legal
        action (the online networks' choice with ``double_q``). For integer states with
        per-state masks it depends on the state alone, so it is a (B, S) table, computed
        once per target copy (every step with ``double_q``) and looked up."""
        if state.dtype != torch.int64 or legal is not None:
            target = self._masked(self.target_agents(state), legal)
            online = self.agents(state) if self.config.double_q else None
            best = self._best(target, online, legal)
            return self.target_mixer(best, self._mixer_state(state))
        if self._next_value_table is None or self.config.double_q:
            masked = self._masked(self.target_agents.tables(), self.state_legal)
            online = self.agents.tables() if self.config.double_q else None
            best = self._best(masked, online, self.state_legal)
            every_state = torch.arange(best.shape[1], device=best.device).expand(best.shape[0], -1)
            self._next_value_table = self.target_mixer(best, every_state)
        table = self._next_value_table  # (B, S), or (B, S, n) without a mixer
        if table.dim() == 3:
            return torch.gather(table, 1, state[..., None].expand(-1, -1, table.shape[2]))
        return torch.gather(table, 1, state)

    def _best(
        self, target: torch.Tensor, online: torch.Tensor | None, legal: torch.Tensor | None
    ) -> torch.Tensor:
        """Each agent's value of its next action (``target``: the target networks' masked
        Q-values): the largest, or (double Q) the one at the online values' greedy legal
        action."""
        if online is None:
            return target.max(dim=-1).values
        choice = self._masked(online, legal).argmax(dim=-1, keepdim=True)
        return target.gather(-1, choice)[..., 0]

    def sync_target(self) -> None:
        """Clone the online networks into the target networks."""
        self.target_agents.load_state_dict(self.agents.state_dict())
        self.target_mixer.load_state_dict(self.mixer.state_dict())
        self._next_value_table = None
        if self.fused is not None:
            self.fused.targets_changed()


def generators_of(seed: np.random.SeedSequence, count: int) -> list[torch.Generator]:
    """``count`` torch generators from one seed: one per agent network, then the mixer."""
    states = seed.generate_state(count, dtype=np.uint64)
    return [torch.Generator().manual_seed(int(s) & 0x7FFF_FFFF_FFFF_FFFF) for s in states]
