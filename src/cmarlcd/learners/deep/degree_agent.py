"""Deep CMARL-CD for any PettingZoo ``ParallelEnv``, one seed, step by step (``[deep]``
extra).

:class:`DegreeAgent` has the object API of the tabular learners and of
:class:`cmarlcd.learners.deep.agent.DeepAgent`, so the generic loop
(:func:`cmarlcd.training.episodes.play_episodes`) drives it like them; the seed-batched
compiled path for the games of :mod:`cmarlcd.games` is :mod:`cmarlcd.training.deep`.
The rule is :mod:`cmarlcd.learners.deep.degree_model`'s: each agent samples from softmax(c/T)
over its legal actions (eq. 17); when its episode ends, the episode is folded into the
keyed memory (:mod:`cmarlcd.learners.deep.degree_memory`; ``replayed``: every visit is stored
with its discounted return) and the schedule of gradient steps
and record copies is every deep learner's (:func:`~cmarlcd.learners.deep.config.scheduled_work`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from cmarlcd.errors import ConfigError
from cmarlcd.learners.deep.agent import StepAgent, check_own_dim
from cmarlcd.learners.deep.config import scheduled_work
from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig
from cmarlcd.learners.deep.degree_memory import (
    features_key,
    find,
    fold_episode,
    keyed_params,
    memory_view,
    new_memory,
    sample_memory,
)
from cmarlcd.learners.deep.degree_model import DegreeModel
from cmarlcd.learners.deep.replay import new_ring, push_visit, push_visit_row, seed_view
from cmarlcd.learners.deep.threads import intra_op_threads
from cmarlcd.learners.policy import greedy_action, uniform_legal_action


class DegreeAgent(StepAgent):
    """Deep CMARL-CD for any ``ParallelEnv`` (one seed): ``act`` (softmax(c/T), eq. 17),
    ``observe``, ``end_episode``, ``greedy`` (the largest clipped degree); states and
    masks as :class:`~cmarlcd.learners.deep.agent.StepAgent` reads them.
    """

    def __init__(
        self,
        action_counts: Sequence[int],
        config: DeepCMARLCDConfig,
        total_episodes: int,
        *,
        n_states: int | None = None,
        state_dim: int | None = None,
        seed: int | np.random.SeedSequence | None = None,
        device: str | None = None,
        own_dim: int | None = None,
        unit: str = "episodes",
    ) -> None:
        super().__init__(action_counts, total_episodes, n_states, state_dim, seed, device, unit)
        check_own_dim(own_dim, state_dim, len(self.counts))
        if compiled := config.compiled_only():
            raise ConfigError(
                compiled[0],
                "is run by the compiled loop only (cmarl-cd field, or a compiled game); "
                "this agent, which plays any ParallelEnv, would learn without it",
            )
        self.config = config
        self.model = DegreeModel(
            self.counts, self.in_dim, config, [self.init_seed], self.device, own_dim
        )
        n = len(self.counts)
        if config.keyed:
            capacity = min(config.buffer_size, n_states) if n_states else config.buffer_size
            self.memory = new_memory(1, capacity, n, self.width, state_dim or 0, config.ways)
            self._memory = memory_view(self.memory, 0)
            self._params = keyed_params(config)
        else:
            size = config.buffer_size
            self.ring = new_ring(1, size, n, self.width, n_states or 1, state_dim or 0)
            self._view = seed_view(self.ring, 0)
        self._visits: dict[int, list[tuple[object, tuple[int, ...], float]]] = {}

    @property
    def stored(self) -> int:
        """States kept in the memory (``keyed``), or visits in the ring (``replayed``)."""
        return int(self._memory.size[0]) if self.config.keyed else int(self.ring.size[0])

    def _replay_batch(self) -> dict[str, torch.Tensor]:
        """A batch of kept states (``keyed``) or of stored visits, drawn with the agent's
        replay stream, on its device."""
        if not self.config.keyed:
            return super()._replay_batch()
        batch = sample_memory(self.memory, [self.replay_rng], self.config.batch_size)
        return {key: torch.from_numpy(a).to(self.device) for key, a in batch.items()}

    def _degrees(self, states, masks) -> tuple[list[np.ndarray], np.ndarray]:
        """Each agent's clipped degrees at each of ``states`` ((n, width) each) and the
        legal actions ((N, n, width)), with one forward pass: the memory's degrees (as
        float64) where it keeps the state and ``act_from`` is ``"memory"``, else the
        network's (float32)."""
        c = self.config
        x = self._encode_many(states)
        with torch.no_grad():
            degrees = list(self.model.agents(x)[0].clamp(*c.degree_bounds).cpu().numpy())
        if c.acts_from_memory:
            for k, state in enumerate(states):
                key = (
                    np.uint64(int(state))
                    if self.integer_states
                    else np.uint64(features_key(x[0, k].cpu().numpy()))
                )
                slot = find(self._memory, key)
                if slot >= 0:
                    degrees[k] = self._memory.target[slot].astype(np.float64)
        return degrees, self._legal_many(masks)

    def degrees(self, state, masks=None) -> np.ndarray:
        """Each agent's clipped degrees ``c_i(state, ·)``, shape (n_agents, width)."""
        return self._degrees([state], [masks])[0][0]

    def greedy_many(self, states, masks) -> np.ndarray:
        """Each agent's legal action of largest clipped degree (lowest index on ties) at
        each of ``states``: (N, n_agents)."""
        degrees, legal = self._degrees(states, masks)
        return np.argmax(np.where(legal, np.stack(degrees), -np.inf), axis=-1)

    def act_many(self, states, masks, copies) -> list:
        """A draw from softmax(c/T) over each agent's legal actions (eq. 17) at each
        state, with one forward pass; the draws go state by state, agent by agent. T is
        annealed over the steps observed where ``temperature_steps`` > 0, and measured
        in the range of the legal degrees with ``temperature_unit="range"``; with
        ``behaviour="epsilon-greedy"`` each agent is ε-greedy on its degrees instead."""
        all_degrees, all_legal = self._degrees(states, masks)
        if self.config.behaviour == "epsilon-greedy":
            return self._epsilon_greedy_many(all_degrees, all_legal)
        temperature = self.config.behaviour_temperature(self.steps)
        joints = []
        for degrees, legal in zip(all_degrees, all_legal, strict=True):
            joint = []
            for d, row in zip(degrees, legal, strict=True):
                logits = np.where(row, d / (temperature * self._unit(d, row)), -np.inf)
                p = np.exp(logits - logits.max())
                joint.append(int(self.act_rng.choice(self.width, p=p / p.sum())))
            joints.append(tuple(joint))
        return joints

    def _epsilon_greedy_many(self, all_degrees, all_legal) -> list:
        """``behaviour="epsilon-greedy"``: each agent a uniform legal action with
        probability ε (annealed over the steps observed), else its legal action of
        largest clipped degree (lowest index on ties)."""
        epsilon = self.config.behaviour_epsilon(self.steps)
        joints = []
        for degrees, legal in zip(all_degrees, all_legal, strict=True):
            joint = []
            for d, row in zip(degrees, legal, strict=True):
                if self.act_rng.random() < epsilon:  # the compiled loop's rule and draws
                    joint.append(uniform_legal_action(row, self.width, self.act_rng.random()))
                else:
                    joint.append(greedy_action(d, row, self.width))
            joints.append(tuple(joint))
        return joints

    def _unit(self, degrees: np.ndarray, legal: np.ndarray) -> float:
        """What T is measured in (``temperature_unit``): 1, or the range of the legal
        degrees (1 where they are all equal)."""
        if self.config.temperature_unit == "fixed":
            return 1.0
        spread = float(degrees[legal].max() - degrees[legal].min())
        return spread if spread > 0 else 1.0

    def observe(self, state, joint_action, reward: float, copy: int = 0) -> None:
        """Record a visit of ``copy``'s episode; the schedule of gradient steps counts
        environment steps."""
        visit = (state, tuple(int(a) for a in joint_action), float(reward))
        self._visits.setdefault(copy, []).append(visit)
        self.steps += 1
        step, sync = scheduled_work(self.steps - 1, self.steps, self.stored, self.config)
        with intra_op_threads(self.model.step_threads()):
            if step:
                self.model.learn(self._replay_batch())
            if sync:
                self.model.sync_target()

    def end_episode(self, final_state=None, terminated: bool = True, copy: int = 0) -> None:
        """Fold ``copy``'s episode into the keyed memory (``keyed``), or store every
        visit with its discounted return (``replayed``, ``imitation``). Returns are the
        episode's rewards from each visit on, a cut episode's return what it collected;
        with ``return_lambda`` below 1, λ-returns bootstrapped from the record network at
        the visits after each (:meth:`_store`), and a cut episode's (``terminated``
        false) from ``final_state`` with ``truncation="bootstrap"``."""
        visits = self._visits.pop(copy, [])
        if self.config.keyed:
            self._fold(visits)
        else:
            cut = self.config.truncation == "bootstrap" and not terminated
            self._store(visits, final_state if cut else None)
        self.episode += 1

    def _fold(self, visits: list) -> None:
        """An episode's visits into the memory
        (:func:`~cmarlcd.learners.deep.degree_memory.fold_episode`), with the networks' degrees
        and record estimate at every visit for the states not kept."""
        if not visits:
            return
        states = [state for state, _, _ in visits]
        x = self._encode_many(states)
        with torch.no_grad():
            bases = self.model.agents(x)[0].cpu().numpy()
            estimates = self.model.record(x)[0].double().cpu().numpy()
        if not self._params.estimate_unseen:
            estimates[:] = -np.inf
        if self.integer_states:
            inputs = np.array([int(s) for s in states], np.int64)
            keys = inputs.astype(np.uint64)
        else:
            inputs = x[0].cpu().numpy()
            keys = np.array([features_key(row) for row in inputs], np.uint64)
        joints = np.array([joint for _, joint, _ in visits], np.int64)
        rewards = np.array([reward for _, _, reward in visits])
        fold_episode(
            self._memory, keys, inputs, bases, estimates, joints, rewards, self.counts,
            len(states), self._params,
        )  # fmt: skip

    def _store(self, visits: list, cut_in=None) -> None:
        """Every visit of an episode with its discounted return, into the ring; with
        ``return_lambda`` λ below 1, ``G_t = r + γ((1 - λ) R(s_{t+1}) + λ G_{t+1})`` from
        the record network ``R`` as it is now (after the last visit 0, or ``R`` at
        ``cut_in``, the state a cut episode ended in), as the compiled loop stores them."""
        lam, gamma = self.config.return_lambda, self.config.gamma
        estimates = None
        if lam < 1 and visits:
            states = [state for state, _, _ in visits]
            x = self._encode_many(states if cut_in is None else [*states, cut_in])
            with torch.no_grad():
                estimates = self.model.estimate(x)[0].double().cpu().numpy()
        value = 0.0
        for t in range(len(visits) - 1, -1, -1):
            state, joint, reward = visits[t]
            if estimates is not None and t + 1 == len(visits):
                value = 0.0 if cut_in is None else float(estimates[t + 1])
            elif estimates is not None:
                value = (1 - lam) * estimates[t + 1] + lam * value
            value = reward + gamma * value
            actions = np.array(joint, dtype=np.int64)
            if self.integer_states:
                push_visit(self._view, int(state), actions, value)
            else:
                obs = np.asarray(state, dtype=np.float32).ravel()
                push_visit_row(self._view, obs, actions, value)
