"""Deep CMARL-CD's networks and update, B seeds stacked in one model (``[deep]`` extra).

The settings and the rule in words are in :mod:`cmarlcd.learners.deep.coordination`.
Like :class:`cmarlcd.learners.deep.value_decomposition.ValueDecomposition`, every tensor has a
leading seed axis and no parameter is shared between seeds, so each seed learns exactly
what it would alone; the degree networks are those of
:mod:`cmarlcd.learners.deep.agent_networks` (per agent, or one shared with the agent's
index), so the compiled loops act with them in the same way.
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
    per_state,
    stacked_middle,
)
from cmarlcd.learners.deep.config import takes_fused_step
from cmarlcd.learners.deep.coordination import RANGE_WEIGHT, DeepCMARLCDConfig
from cmarlcd.learners.deep.fused.step import FusedDegreeStep, FusedSharesStep
from cmarlcd.learners.deep.td_options import RewardStatistics
from cmarlcd.learners.deep.value_decomposition import StackedModel


class RecordNetwork(nn.Module):
    """``R(s)`` for B seeds: state -> Linear -> ReLU -> Linear -> ``outputs`` values, one
    (the state's record) or one per joint action ``R(s, a)`` (``update="critic"``), whose
    best is the state's record."""

    def __init__(
        self, in_dim: int, hidden: int, generators: Sequence[torch.Generator], outputs: int = 1
    ) -> None:
        super().__init__()
        self.first = GroupLinear(in_dim, hidden, generators)
        self.second = GroupLinear(hidden, outputs, generators)

    def values(self, state: torch.Tensor) -> torch.Tensor:
        """(B, N[, in]) -> (B, N, outputs)."""
        return per_state(self.first, state, lambda x: self.second(torch.relu(x)))

    def forward(self, state: torch.Tensor) -> torch.Tensor:
        """The state's record, (B, N[, in]) -> (B, N): the best of the outputs."""
        return self.values(state).amax(dim=-1)


def standardised_returns(batch: dict[str, torch.Tensor], rewards: RewardStatistics):
    """Each visit's one-step return ``r + γ V'(s')`` (``batch["reward"]``, (B, N)) with
    its own reward ``r`` (``batch["step_reward"]``) replaced by the reward standardised
    by ``rewards`` after they take the batch's: ``G - r + (r - mean) / std`` (EPyMARL's
    ``standardise_rewards`` on a TD target)."""
    own = batch["step_reward"]
    return batch["reward"] - own + rewards.standardise(own)


class DegreeModel(StackedModel):
    """Deep CMARL-CD for B independent seeds: degree and record networks, the record's
    target copy, Adam, and the update of :mod:`cmarlcd.learners.deep.coordination`.

    Args:
        action_counts: actions of each agent.
        in_dim: state features, or the number of states for integer (one-hot) states.
        seeds: one :class:`numpy.random.SeedSequence` per seed (parameter initialisation).
        device: where it computes (``cpu``, ``cuda:N``; :mod:`cmarlcd.devices`).
        own_dim: features of each agent's own observation, for inputs laid out as
            ``[s, o_1, ..., o_n]``: agent ``i``'s degree network reads ``o_i`` alone; the
            record network reads the whole input.
    """

    def __init__(
        self,
        action_counts: Sequence[int],
        in_dim: int,
        config: DeepCMARLCDConfig,
        seeds: Sequence[np.random.SeedSequence],
        device: str = "cpu",
        own_dim: int | None = None,
    ) -> None:
        super().__init__(action_counts, config, seeds, device)
        gens, width = self.generators, self.width
        self.agents: nn.Module
        if config.share:
            shared = [g[0] for g in gens]
            self.agents = SharedAgentNetwork(
                self.n_seeds, self.n_agents, in_dim, config.hidden, width, shared, own_dim,
                config.hidden_layers,
            )  # fmt: skip
        else:
            self.agents = AgentNetworks(
                self.n_seeds, self.n_agents, in_dim, config.hidden, width, gens, own_dim,
                config.hidden_layers,
            )  # fmt: skip
        outputs = config.record_outputs(action_counts)
        self.record = RecordNetwork(in_dim, config.record_hidden, [g[-1] for g in gens], outputs)
        # joint action index = sum_i a_i * strides[i], the last agent's action fastest
        counts = torch.as_tensor(np.asarray(action_counts, np.int64), device=self.device)
        self.strides = torch.cat([counts.flip(0).cumprod(0).flip(0)[1:], counts.new_ones(1)])
        self.counts = counts
        # critic_form="sum": agent i's action a is output offsets[i] + a
        self.offsets = torch.cat([counts.new_zeros(1), counts.cumsum(0)[:-1]])
        self.summed = config.update == "critic" and config.critic_form == "sum"
        self.shares = config.shares
        self.target_record = copy.deepcopy(self.record).requires_grad_(False)
        # critic_form="degrees": the shares' target copy, which values the greedy action
        self.target_agents = (
            copy.deepcopy(self.agents).requires_grad_(False) if self.shares else None
        )
        self.place()
        self.optimizer = torch.optim.Adam(
            [
                {"params": list(self.agents.parameters()), "lr": config.lr},
                {"params": list(self.record.parameters()), "lr": config.record_lr},
            ],
            fused=True,
        )
        fused = takes_fused_step(config.step, self.device, config.auto_fuses)
        step = FusedSharesStep if config.shares else FusedDegreeStep
        self.fused = step(self) if fused else None
        self.rewards = RewardStatistics(self.n_seeds, self.device)

    def targets(
        self, degrees: torch.Tensor, actions: torch.Tensor, returns: torch.Tensor,
        record: torch.Tensor,
    ) -> tuple[torch.Tensor, torch.Tensor]:  # fmt: skip
        """Algorithm 2's updates as regression targets: the new degrees (B, N, n, A) of
        each visit given its present ``degrees``, taken ``actions`` (B, N, n), return
        (B, N) and the record estimate (B, N); and which visits have one (record or tie,
        (B, N) bool)."""
        c = self.config
        new_record = returns > record + c.margin
        tie = ~new_record & ((returns - record).abs() <= c.tolerance)
        base = torch.where(new_record[..., None, None], c.c_init, degrees.clamp(c.c_min, c.c_max))
        step = torch.where(new_record, c.delta_reset, c.delta)[..., None, None]
        return self.moved(base, actions, step), new_record | tie

    def moved(self, base: torch.Tensor, actions: torch.Tensor, step) -> torch.Tensor:
        """Eqs. (14)-(15): degrees ``base`` (B, N, n, A) with each agent's ``actions``
        (B, N, n) raised by ``step`` and every other action lowered by it, clipped."""
        c = self.config
        taken = nn.functional.one_hot(actions, base.shape[-1]).bool()
        return (base + torch.where(taken, step, -step)).clamp(c.c_min, c.c_max)

    def learn(self, batch: dict[str, torch.Tensor]) -> float:
        """One Adam step on :meth:`loss` (by autograd, or the fused step of
        ``config.step``), on each visit's target with its reward standardised first where
        ``standardise_rewards`` says so (:func:`standardised_returns`); returns the mean
        loss per seed."""
        if self.config.standardise_rewards:
            batch = {**batch, "reward": standardised_returns(batch, self.rewards)}
        if self.fused is not None:
            return self.fused(batch)
        return self.optimise(self.loss(batch))

    def loss(self, batch: dict[str, torch.Tensor]) -> torch.Tensor:
        """The seeds' summed losses on a batch (:meth:`keyed_loss`, :meth:`replayed_loss`
        or :meth:`imitation_loss`, as the config's ``update``)."""
        if self.config.keyed:
            return self.keyed_loss(batch)
        if self.config.update == "imitation":
            return self.imitation_loss(batch)
        if self.config.update == "critic":
            return self.critic_loss(batch)
        return self.replayed_loss(batch)

    def keyed_loss(self, batch: dict[str, torch.Tensor]) -> torch.Tensor:
        """The seeds' summed losses on a batch of kept states: ``state`` (B, N[, in]),
        ``target`` (B, N, n, A): the degrees the memory holds there, ``record`` (B, N):
        their records. The degrees' squared distance to the targets over each agent's
        real actions, summed over the agents and averaged over the states; with
        ``unseen_record`` compared with an estimate, plus the record network's squared error."""
        state = batch["state"]
        degrees = self.agents(state)
        valid = self.valid.to(degrees.dtype)
        loss = (((degrees - batch["target"]) ** 2) * valid).sum(dim=(2, 3)).mean(dim=1).sum()
        if self.config.estimates_unseen:
            loss = loss + ((self.record(state) - batch["record"]) ** 2).mean(dim=1).sum()
        return loss

    def replayed_loss(self, batch: dict[str, torch.Tensor]) -> torch.Tensor:
        """The seeds' summed losses on a batch of visits: ``state`` (B, N[, in]),
        ``actions`` (B, N, n), ``reward`` (B, N): each visit's discounted return (every
        tensor on the model's device). The degrees' squared distance to their targets,
        averaged over the visits that have one, plus the record's expectile loss."""
        state, actions, returns = batch["state"], batch["actions"], batch["reward"]
        degrees = self.agents(state)
        with torch.no_grad():
            record = self.target_record(state)
            target, updated = self.targets(degrees, actions, returns, record)
        weight = (updated[..., None, None] & self.valid).to(degrees.dtype)
        per_visit = (((degrees - target) ** 2) * weight).sum(dim=(2, 3))  # (B, N)
        visits = updated.sum(dim=1).clamp(min=1).to(degrees.dtype)
        degree_loss = (per_visit.sum(dim=1) / visits).sum()  # mean over the updated visits
        return degree_loss + self.record_loss(state, returns)

    def record_loss(self, state: torch.Tensor, returns: torch.Tensor) -> torch.Tensor:
        """The record network's expectile loss at τ = ``expectile`` on visits' returns
        (B, N): ``|τ - [G < R(s)]| (G - R(s))²``, averaged over the visits, summed over
        the seeds (its minimiser is the τ-expectile of the returns from ``s``)."""
        return self.expectile_loss(self.record(state), returns)

    def imitation_loss(self, batch: dict[str, torch.Tensor]) -> torch.Tensor:
        """Self-imitation gated by the record (``update="imitation"``), the seeds' summed
        losses on a batch of visits (:meth:`replayed_loss`'s keys). Each visit ``t`` of
        seed ``b`` weighs ``w = max(0, (G - R'(s)) / σ_b + tolerance)``, ``R'`` the record
        network's target copy and ``σ_b`` the spread of the batch's returns (their
        standard deviation): the margin by which it passes the record, in spreads. The
        loss: ``Σ_i -w log π_i(a_i | s)`` with ``π_i = softmax(clip(c_i)/T)`` over the
        agent's real actions (eq. 17), averaged over the visits; plus
        :data:`~cmarlcd.learners.deep.coordination.RANGE_WEIGHT` times each degree's
        squared distance to ``[c_min, c_max]``; plus :meth:`record_loss`. A visit below
        the record by more than ``tolerance`` spreads moves no degree."""
        c = self.config
        state, actions, returns = batch["state"], batch["actions"], batch["reward"]
        degrees = self.agents(state)  # (B, N, n, A)
        with torch.no_grad():
            spread = returns.std(dim=1, correction=0, keepdim=True).clamp(min=1e-6)
            weight = ((returns - self.target_record(state)) / spread + c.tolerance).clamp(min=0)
        return self.imitated(degrees, actions, weight) + self.record_loss(state, returns)

    def imitated(
        self, degrees: torch.Tensor, actions: torch.Tensor, weight: torch.Tensor | None = None
    ) -> torch.Tensor:
        """The seeds' summed cross-entropy ``Σ_i -w log π_i(a_i | s)`` of the strategies
        ``π_i = softmax(clip(c_i)/T)`` over each agent's real actions (eq. 17) towards
        ``actions`` (B, N, n), each visit weighted by ``weight`` (B, N; 1 where None),
        averaged over the visits; plus :data:`RANGE_WEIGHT` times each degree's squared
        distance to ``[c_min, c_max]``, which keeps a degree pushed past a bound within
        reach of the clipped strategy's gradient."""
        c = self.config
        clipped = degrees.clamp(c.c_min, c.c_max)
        logits = (clipped / c.temperature).masked_fill(~self.valid, float("-inf"))
        taken = logits.log_softmax(dim=-1).gather(-1, actions[..., None])[..., 0]  # (B, N, n)
        if weight is not None:
            taken = weight[..., None] * taken
        valid = self.valid.to(degrees.dtype)
        outside = (((degrees - clipped) ** 2) * valid).sum(dim=(2, 3)).mean(dim=1).sum()
        return -taken.sum(dim=2).mean(dim=1).sum() + RANGE_WEIGHT * outside

    def critic_loss(self, batch: dict[str, torch.Tensor]) -> torch.Tensor:
        """A centralised critic of joint actions as the record (``update="critic"``), the
        seeds' summed losses on a batch of visits (:meth:`replayed_loss`'s keys). The
        critic ``R(s, a)`` learns the expectile loss of :meth:`record_loss` at each visit's
        taken joint action. The degrees learn the joint action that reaches the record:
        at each visit's state, the best joint action ``a* = argmax_a R'(s, a)`` of the
        critic's target copy (lowest index on ties), whatever the visit's return, by
        ``critic_fit``: a cross-entropy ``Σ_i -log π_i(a*_i | s)`` of the strategies
        ``π_i = softmax(clip(c_i)/T)`` plus :data:`RANGE_WEIGHT` times each degree's squared
        distance to ``[c_min, c_max]`` (``"imitation"``), or the tie of eqs. (14)-(15),
        ``a*_i`` raised by ``delta`` and the others lowered, from the present degrees,
        clipped, by squared error (``"tie"``); averaged over the visits. Acting stays
        decentralised, each agent from its degrees. With ``critic_form="degrees"`` the
        critic is the degrees themselves (:meth:`shares_at`), fitted by the expectile loss
        alone."""
        c = self.config
        state, actions, returns = batch["state"], batch["actions"], batch["reward"]
        degrees = self.agents(state)  # (B, N, n, A)
        if self.shares:
            return self.expectile_loss(self.shares_at(degrees, actions), returns)
        with torch.no_grad():
            best_actions = self.critic_best(self.target_record.values(state))
        if c.critic_fit == "tie":
            with torch.no_grad():
                target = self.moved(degrees.clamp(c.c_min, c.c_max), best_actions, c.delta)
            valid = self.valid.to(degrees.dtype)
            degree_loss = (((degrees - target) ** 2) * valid).sum(dim=(2, 3)).mean(dim=1).sum()
        else:
            degree_loss = self.imitated(degrees, best_actions)
        estimate = self.critic_at(self.record.values(state), actions)
        return degree_loss + self.expectile_loss(estimate, returns)

    def expectile_loss(self, estimate: torch.Tensor, returns: torch.Tensor) -> torch.Tensor:
        """``|τ - [G < R]| (G - R)²`` at τ = ``expectile``, averaged over the visits,
        summed over the seeds (its minimiser is the τ-expectile of the returns)."""
        tau = self.config.expectile
        below = (returns < estimate).to(estimate.dtype).detach()
        expectile = (tau + (1 - 2 * tau) * below) * (returns - estimate) ** 2
        return expectile.mean(dim=1).sum()

    @torch.no_grad()
    def estimate(self, state: torch.Tensor) -> torch.Tensor:
        """What λ-returns bootstrap from at ``state`` (B, N[, in]) -> (B, N): the record
        network's estimate, or (``critic_bootstrap="greedy"``) the critic's value of the
        joint action the degrees take greedily there (over each agent's real actions);
        with ``critic_form="degrees"`` the critic is the degrees' target copy (a double
        estimator, after van Hasselt et al., 2016: the largest of noisy shares valued by
        the shares that chose it would compound through the returns)."""
        if not self.config.greedy_bootstrap:
            return self.record(state)
        degrees = self._masked(self.agents(state).clamp(*self.config.degree_bounds), None)
        if self.shares:
            return self.shares_at(self.target_agents(state), degrees.argmax(dim=-1))
        return self.critic_at(self.record.values(state), degrees.argmax(dim=-1))

    @staticmethod
    def shares_at(degrees: torch.Tensor, actions: torch.Tensor) -> torch.Tensor:
        """The record as the agents' shares (``critic_form="degrees"``): ``Σ_i c_i(s,
        a_i)`` of ``degrees`` (B, N, n, A) at the joint actions ``actions`` (B, N, n),
        (B, N)."""
        return degrees.gather(-1, actions[..., None])[..., 0].sum(dim=-1)

    def critic_at(self, values: torch.Tensor, actions: torch.Tensor) -> torch.Tensor:
        """The critic's ``values`` (B, N, K) at the joint actions of ``actions`` (B, N, n):
        the joint action's output, or the sum of each agent's (``critic_form="sum"``)."""
        if self.summed:
            return values.gather(-1, actions + self.offsets).sum(dim=-1)
        joint = (actions * self.strides).sum(dim=-1)
        return values.gather(-1, joint[..., None])[..., 0]

    def critic_best(self, values: torch.Tensor) -> torch.Tensor:
        """The critic's best joint action (B, N, n) at its ``values`` (B, N, K), lowest
        index on ties: the argmax joint output decoded, or each agent's best action
        (``critic_form="sum"``)."""
        if not self.summed:
            best = values.argmax(dim=-1)
            return (best[..., None] // self.strides) % self.counts
        actions = torch.arange(self.width, device=values.device)
        index = (self.offsets[:, None] + actions).clamp(max=values.shape[-1] - 1)  # (n, A)
        per_agent = values[..., index]  # (B, N, n, A)
        return self._masked(per_agent, None).argmax(dim=-1)

    @torch.no_grad()
    def record_table(self) -> torch.Tensor:
        """The record network's estimate of every integer state, (B, S): the best of its
        outputs, or the critic's value of the degrees' greedy joint action there
        (``critic_bootstrap="greedy"``, :meth:`greedy_table`)."""
        if self.shares:
            return self.shares_at(self.target_agents.tables(), self.greedy_table())
        record = self.record
        values = record.second(torch.relu(record.first.table()))
        if self.config.greedy_bootstrap:
            return self.critic_at(values, self.greedy_table())
        return values.amax(dim=-1)

    def record_weights(self) -> tuple[torch.Tensor, ...]:
        """The record network's layers as the compiled loop reads them (one "agent" per
        seed): (B, in, H), (B, H), (B, H, K), (B, K) for its K outputs, and no middle
        layers (one hidden layer: empty (B, 0, H, H), (B, 0, H)); with
        ``critic_form="degrees"``, the degree networks' target copy as the loop reads the
        degree networks (B * n agents)."""
        if self.target_agents is not None:
            return self.target_agents.feature_weights()
        first, second = self.record.first, self.record.second
        groups, hidden = first.weight.shape[0], first.weight.shape[2]
        none = stacked_middle(nn.ModuleList(), groups, hidden, first.weight)
        return first.weight, first.bias, second.weight, second.bias, *none

    def sync_target(self) -> None:
        """Clone the record network into its target copy (and, with
        ``critic_form="degrees"``, the degree networks into theirs)."""
        self.target_record.load_state_dict(self.record.state_dict())
        if self.target_agents is not None:
            self.target_agents.load_state_dict(self.agents.state_dict())

    @torch.no_grad()
    def greedy_table(self) -> torch.Tensor:
        """Greedy joint action (B, S, n) in every integer state: each agent's legal action
        of largest clipped degree (lowest index on ties, as the tabular learner)."""
        degrees = self.agents.tables().clamp(*self.config.degree_bounds)
        return self._masked(degrees, self.state_legal).argmax(dim=-1)
