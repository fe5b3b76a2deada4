"""VDN / QMIX for any PettingZoo ``ParallelEnv``, one seed, step by step (``[deep]`` extra).

:class:`DeepAgent` has the object API of the tabular learners, so the generic loop
(:func:`cmarlcd.training.episodes.play_episodes`) drives it like them; the seed-batched
compiled path for the games of :mod:`cmarlcd.games` is :mod:`cmarlcd.training.deep`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from cmarlcd import devices
from cmarlcd.errors import require
from cmarlcd.learners.deep.config import DeepConfig, epsilon, scheduled_work
from cmarlcd.learners.deep.replay import new_ring, push, push_row, sample, seed_view
from cmarlcd.learners.deep.threads import intra_op_threads
from cmarlcd.learners.deep.value_decomposition import ValueDecomposition


def check_own_dim(own_dim: int | None, state_dim: int | None, n_agents: int) -> None:
    """One clear error where ``own_dim`` cannot lay out own observations in the state:
    they are the last ``n_agents * own_dim`` features, after the state."""
    if own_dim is not None:
        require(
            state_dim is not None and 0 < own_dim * n_agents < state_dim,
            "own_dim",
            "own observations are the last n_agents * own_dim of a feature state, "
            "after the state the mixer reads",
        )


class StepAgent:
    """What the step-by-step deep learners share: a seed's streams (spawned in the order
    parameters, acting, replay), the action counts, how states reach a network and the
    legal actions.

    States are integers in ``[0, n_states)`` (one-hot encoding) when ``n_states`` is
    given, else feature vectors of length ``state_dim``. ``masks`` give the legal actions
    of each agent (1 = legal). The model computes on ``device`` (default: this
    process's, :func:`cmarlcd.devices.current`); what the agent hands back is on the host.

    Several copies of an environment may be played at once: :meth:`act_many` acts in
    each copy's state with one forward pass, and ``copy`` (0 by default) tells
    ``act``, ``observe`` and ``end_episode`` whose episode a call belongs to.
    """

    def __init__(
        self,
        action_counts: Sequence[int],
        total_episodes: int,
        n_states: int | None,
        state_dim: int | None,
        seed: int | np.random.SeedSequence | None,
        device: str | None = None,
        unit: str = "episodes",
    ) -> None:
        require((n_states is None) != (state_dim is None), "n_states", "give n_states or state_dim")
        require(unit in ("episodes", "steps"), "unit", f"must be episodes or steps (got {unit!r})")
        #: What ``total_episodes`` counts: episodes, or environment steps (then ε anneals
        #: over the steps, eq. 18 read per step).
        self.by_steps = unit == "steps"
        self.device = devices.current() if device is None else devices.resolve(device)
        root = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
        self.init_seed, act, replay = root.spawn(3)
        self.total_episodes = int(total_episodes)
        self.counts = np.array([int(k) for k in action_counts], dtype=np.int64)
        self.width = int(self.counts.max())
        self.integer_states = n_states is not None
        self.in_dim = int(n_states or state_dim)  # type: ignore[arg-type]
        self.act_rng, self.replay_rng = np.random.default_rng(act), np.random.default_rng(replay)
        self.episode, self.steps = 0, 0

    @property
    def stored(self) -> int:
        """Entries in the replay ring."""
        return int(self.ring.size[0])  # type: ignore[attr-defined]

    def _encode_many(self, states) -> torch.Tensor:
        """States as the model's input: (1, N) integers or (1, N, state_dim) features."""
        if self.integer_states:
            return torch.tensor([[int(x) for x in states]], device=self.device)
        rows = [np.asarray(x, dtype=np.float32).ravel() for x in states]
        return torch.as_tensor(np.stack(rows)[None], device=self.device)

    def _legal_array(self, masks) -> np.ndarray:
        """(n_agents, width) bool on the host: each agent's legal actions."""
        legal = np.arange(self.width)[None, :] < self.counts[:, None]
        if masks is not None:
            for i, mask in enumerate(masks):
                legal[i, : self.counts[i]] &= np.asarray(mask, dtype=bool)
        return legal

    def _legal_many(self, masks: Sequence) -> np.ndarray:
        """(N, n_agents, width) bool on the host: the legal actions in each of N states
        (``masks[k]``: that state's masks, or None)."""
        return np.stack([self._legal_array(m) for m in masks])

    def act(self, state, masks=None, copy: int = 0) -> tuple[int, ...]:
        """A joint action to take at ``state`` in ``copy``'s episode (:meth:`act_many`
        for one state)."""
        return self.act_many([state], [masks], [copy])[0]

    def greedy(self, state, masks=None) -> tuple[int, ...]:
        """The greedy legal joint action at ``state``."""
        return tuple(int(a) for a in self.greedy_many([state], [masks])[0])

    def act_many(self, states: Sequence, masks: Sequence, copies: Sequence[int]) -> list:
        """Joint actions to take at ``states[k]`` in the episode of ``copies[k]``."""
        raise NotImplementedError

    def greedy_many(self, states: Sequence, masks: Sequence) -> np.ndarray:
        """The greedy legal joint action at each of ``states``: (N, n_agents)."""
        raise NotImplementedError

    def _replay_batch(self) -> dict[str, torch.Tensor]:
        """A replay batch, drawn with the agent's replay stream, on its device."""
        batch = sample(self.ring, [self.replay_rng], self.config.batch_size)  # type: ignore[attr-defined]
        return {key: torch.from_numpy(a).to(self.device) for key, a in batch.items()}


class DeepAgent(StepAgent):
    """VDN / QMIX for any PettingZoo ``ParallelEnv`` (one seed), for
    :func:`cmarlcd.training.episodes.play_episodes`: ``act`` (ε-greedy, eq. 18), ``observe``,
    ``end_episode``, ``greedy``; states and masks as :class:`StepAgent` reads them
    (illegal actions are never chosen nor bootstrapped from).

    ``own_dim``: feature states laid out as ``[s, o_1, ..., o_n]``, each agent's own
    observation ``o_i`` of ``own_dim`` features last: agent ``i`` acts on ``o_i`` alone and
    QMIX's mixer reads ``s`` (decentralised execution; :class:`ValueDecomposition`).
    """

    def __init__(
        self,
        action_counts: Sequence[int],
        config: DeepConfig,
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
        self.config = config
        self.model = ValueDecomposition(
            self.counts, self.in_dim, config, [self.init_seed], self.device, own_dim
        )
        self.ring = new_ring(
            1, config.buffer_size, len(self.counts), self.width, n_states or 1, state_dim or 0,
            masks=True,
        )  # fmt: skip
        self._view = seed_view(self.ring, 0)
        self._pending: dict[int, tuple] = {}

    def greedy_many(self, states: Sequence, masks: Sequence) -> np.ndarray:
        """The greedy legal joint action at each of ``states``: (N, n_agents)."""
        legal = torch.as_tensor(self._legal_many(masks), device=self.device)
        return self.model.greedy(self._encode_many(states), legal)[0].cpu().numpy()

    def act_many(self, states: Sequence, masks: Sequence, copies: Sequence[int]) -> list:
        """ε-greedy per agent (eq. 18, ε of the current episode) at each state, with one
        forward pass; first completes each copy's pending transition with its state as
        the successor. The draws go copy by copy, agent by agent."""
        for state, mask, copy in zip(states, masks, copies, strict=True):
            self._complete(copy, state, mask, terminal=False)
        eps = epsilon(
            self.episode + 1, self.total_episodes, self.config, self.steps + 1, self.by_steps
        )
        greedy, legal = self.greedy_many(states, masks), self._legal_many(masks)
        joints = []
        for best_joint, legal_joint in zip(greedy, legal, strict=True):
            joint = []
            for best, row in zip(best_joint, legal_joint, strict=True):
                if self.act_rng.random() < eps:
                    joint.append(int(self.act_rng.choice(np.flatnonzero(row))))
                else:
                    joint.append(int(best))
            joints.append(tuple(joint))
        return joints

    def observe(self, state, joint_action, reward: float, copy: int = 0) -> None:
        """Record a step of ``copy``'s episode; it becomes a transition when its
        successor is known."""
        self._pending[copy] = (state, tuple(int(a) for a in joint_action), float(reward))

    def end_episode(self, final_state=None, terminated: bool = True, copy: int = 0) -> None:
        """Close ``copy``'s episode: bootstrap from ``final_state`` unless ``terminated``."""
        self._complete(copy, final_state, None, terminal=terminated)
        self.episode += 1

    def _complete(self, copy: int, next_state, next_masks, terminal: bool) -> None:
        if copy not in self._pending:
            return
        state, joint, reward = self._pending.pop(copy)
        if terminal or next_state is None:
            next_state, terminal = state, True
        legal = self._legal_array(next_masks)
        joint_array = np.array(joint, dtype=np.int64)
        if self.integer_states:
            row = int(self._view.position[0])
            push(self._view, int(state), joint_array, reward, int(next_state), terminal)
            self._view.next_legal[row] = legal
        else:
            obs, next_obs = (np.asarray(x, dtype=np.float32).ravel() for x in (state, next_state))
            push_row(self._view, obs, next_obs, legal, joint_array, reward, terminal)
        self._step()

    def _step(self) -> None:
        """The schedule of every deep learner, one environment step at a time."""
        self.steps += 1
        step, copy = scheduled_work(self.steps - 1, self.steps, self.stored, self.config)
        with intra_op_threads(self.model.step_threads()):
            if step:
                self.model.td_step(self._replay_batch())
            if copy:
                self.model.sync_target()
