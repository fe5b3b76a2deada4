"""Seed-batched VDN / QMIX training on the DSN (needs the ``[deep]`` extra).

B independent seeds train together: B copies of the DSN each take ``train_every`` steps
in one compiled call (:func:`cmarlcd.rollouts.dsn_collect`), replay batches are drawn in
another (:func:`cmarlcd.rollouts.replay_sample`), and one stacked model
(:class:`cmarlcd.learners.value_decomposition.ValueDecomposition`) takes the gradient
steps of all seeds at once. Each seed has its own streams, spawned from its run seed in
a fixed order: parameter initialisation, environment, exploration, replay sampling; so
seed b of a batch follows the same trajectory as that seed trained alone, up to float
rounding in the batched products.

Schedule (SPEC §4): after every ``train_every`` environment steps, one gradient step once
``batch_size`` transitions are stored; after it, the target networks are copied whenever
another ``target_every`` steps have passed. The networks only change at these gradient
steps, so between them each seed's greedy policy is a table over the 43 DSN states.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import torch

from cmarlcd.errors import require
from cmarlcd.games import sensor_network as dsn
from cmarlcd.learners.deep_config import DeepConfig, epsilon, epsilon_schedule
from cmarlcd.learners.value_decomposition import ValueDecomposition
from cmarlcd.rollouts import dsn_collect, replay_sample
from cmarlcd.runner import report_progress

#: Called as evaluate(seed index, episodes learnt, greedy policy (43, 12)).
Evaluator = Callable[[int, int, np.ndarray], None]


class DsnDeepBatch:
    """B seeds of VDN or QMIX learning the DSN for ``total_episodes`` episodes each."""

    def __init__(
        self, config: DeepConfig, seeds: Sequence[np.random.SeedSequence], total_episodes: int
    ) -> None:
        init, env, act, replay = zip(*(s.spawn(4) for s in seeds), strict=True)
        self.config, self.total_episodes, self.n_seeds = config, int(total_episodes), len(seeds)
        self.model = ValueDecomposition(dsn.ACTION_COUNTS, dsn.N_STATE_INDICES, config, init)
        self.env_rngs = tuple(np.random.default_rng(s) for s in env)
        self.act_rngs = tuple(np.random.default_rng(s) for s in act)
        self.replay_rngs = tuple(np.random.default_rng(s) for s in replay)
        b = self.n_seeds
        self.envs = (
            np.zeros((b, 2), np.int64),
            np.zeros((b, 2), np.int64),
            np.zeros(b, np.int64),
            np.zeros(b, np.int64),
        )
        cap = config.buffer_size
        # compact rows (states < 43, actions < 5): random replay reads stay in cache
        self.buffer = (
            np.zeros((b, cap), np.int8),
            np.zeros((b, cap, dsn.N_SENSORS), np.int8),
            np.zeros((b, cap), np.float32),
            np.zeros((b, cap), np.int8),
            np.zeros((b, cap), np.bool_),
            np.zeros(b, np.int64),
            np.zeros(b, np.int64),
        )
        for k in range(b):
            dsn.dsn_reset(self.envs[0][k], self.envs[1][k], self.env_rngs[k])
        self.steps = 0

    @property
    def episodes(self) -> np.ndarray:
        """Learning episodes finished by each seed."""
        return self.envs[3]

    def greedy_tables(self) -> np.ndarray:
        """(B, 43, 12): each seed's greedy joint action in every state."""
        return self.model.greedy_table().numpy()

    def train(self, checkpoints: Sequence[int], evaluate: Evaluator) -> None:
        """Learn until every seed has played ``total_episodes`` episodes, calling
        ``evaluate`` as each seed reaches each checkpoint (in episodes) with the greedy
        policy it had then."""
        cfg = self.config
        points = sorted(set(checkpoints) | {self.total_episodes})
        table = self.greedy_tables()
        schedule = epsilon_schedule(cfg)
        while (self.episodes < self.total_episodes).any():
            before = self.episodes.copy()
            active = int((before < self.total_episodes).sum())
            dsn_collect(
                table,
                cfg.train_every,
                self.total_episodes,
                schedule,
                self.envs,
                self.buffer,
                self.env_rngs,
                self.act_rngs,
            )
            report_progress(active * cfg.train_every)
            self._evaluate_crossed(before, points, table, evaluate)
            previous, self.steps = self.steps, self.steps + cfg.train_every
            if self.buffer[6].min() >= cfg.batch_size:
                self.model.td_step(self.sample())
                table = self.greedy_tables()
            if self.steps // cfg.target_every > previous // cfg.target_every:
                self.model.sync_target()

    def _evaluate_crossed(
        self, before: np.ndarray, points: list[int], table: np.ndarray, evaluate: Evaluator
    ) -> None:
        for k in range(self.n_seeds):
            for point in points:
                if before[k] < point <= self.episodes[k]:
                    evaluate(k, point, table[k])

    def sample(self) -> dict[str, torch.Tensor]:
        """A replay batch per seed, drawn with that seed's own generator (every DSN
        action is legal, so there is no ``next_legal``)."""
        b, n = self.n_seeds, self.config.batch_size
        out = (
            np.empty((b, n), np.int64),
            np.empty((b, n, dsn.N_SENSORS), np.int64),
            np.empty((b, n), np.float32),
            np.empty((b, n), np.int64),
            np.empty((b, n), np.bool_),
        )
        replay_sample(self.buffer, self.replay_rngs, n, out)
        keys = ("state", "actions", "reward", "next_state", "terminal")
        return {key: torch.from_numpy(array) for key, array in zip(keys, out, strict=True)}


class DeepAgent:
    """VDN / QMIX for any PettingZoo ``ParallelEnv`` (one seed), for
    :func:`cmarlcd.rollouts.play_episodes`: ``act`` (ε-greedy, eq. 18), ``observe``,
    ``end_episode``, ``greedy``.

    States are integers in ``[0, n_states)`` (one-hot encoding) when ``n_states`` is
    given, else feature vectors of length ``state_dim``. ``masks`` give the legal actions
    of each agent (1 = legal); illegal actions are never chosen nor bootstrapped from.
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
    ) -> None:
        require((n_states is None) != (state_dim is None), "n_states", "give n_states or state_dim")
        root = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
        init, act, replay = root.spawn(3)
        self.config, self.total_episodes = config, int(total_episodes)
        self.counts = np.array([int(k) for k in action_counts], dtype=np.int64)
        self.width = int(self.counts.max())
        self.integer_states = n_states is not None
        self.model = ValueDecomposition(self.counts, n_states or state_dim, config, [init])
        self.act_rng, self.replay_rng = np.random.default_rng(act), np.random.default_rng(replay)
        self.episode, self.steps = 0, 0
        self.transitions: list[tuple] = []  # the replay buffer (a ring of buffer_size)
        self.position = 0
        self._pending: tuple | None = None

    def _encode(self, state) -> torch.Tensor:
        return self._encode_many([state])

    def _encode_many(self, states) -> torch.Tensor:
        """States as the model's input: (1, N) integers or (1, N, state_dim) features."""
        if self.integer_states:
            return torch.tensor([[int(x) for x in states]])
        rows = [np.asarray(x, dtype=np.float32).ravel() for x in states]
        return torch.as_tensor(np.stack(rows)[None])

    def _legal(self, masks) -> torch.Tensor:
        legal = np.arange(self.width)[None, :] < self.counts[:, None]
        if masks is not None:
            for i, mask in enumerate(masks):
                legal[i, : self.counts[i]] &= np.asarray(mask, dtype=bool)
        return torch.as_tensor(legal)

    def greedy(self, state, masks=None) -> tuple[int, ...]:
        """The greedy legal joint action at ``state``."""
        action = self.model.greedy(self._encode(state), self._legal(masks))[0, 0]
        return tuple(int(a) for a in action)

    def act(self, state, masks=None) -> tuple[int, ...]:
        """ε-greedy per agent (eq. 18, ε of the current episode); completes the pending
        transition with this state as its successor."""
        self._complete(state, masks, terminal=False)
        eps = epsilon(self.episode + 1, self.total_episodes, self.config)
        greedy, legal = self.greedy(state, masks), self._legal(masks).numpy()
        joint = []
        for i, best in enumerate(greedy):
            if self.act_rng.random() < eps:
                joint.append(int(self.act_rng.choice(np.flatnonzero(legal[i]))))
            else:
                joint.append(best)
        return tuple(joint)

    def observe(self, state, joint_action, reward: float) -> None:
        """Record a step; it becomes a transition when its successor is known."""
        self._pending = (state, tuple(int(a) for a in joint_action), float(reward))

    def end_episode(self, final_state=None, terminated: bool = True) -> None:
        """Close the episode: bootstrap from ``final_state`` unless ``terminated``."""
        self._complete(final_state, None, terminal=terminated)
        self.episode += 1

    def _complete(self, next_state, next_masks, terminal: bool) -> None:
        if self._pending is None:
            return
        state, joint, reward = self._pending
        self._pending = None
        if terminal or next_state is None:
            next_state, terminal = state, True
        item = (state, joint, reward, next_state, self._legal(next_masks), terminal)
        if len(self.transitions) < self.config.buffer_size:
            self.transitions.append(item)
        else:
            self.transitions[self.position] = item
        self.position = (self.position + 1) % self.config.buffer_size
        self._step()

    def _step(self) -> None:
        cfg = self.config
        self.steps += 1
        if self.steps % cfg.train_every == 0 and len(self.transitions) >= cfg.batch_size:
            picks = self.replay_rng.integers(0, len(self.transitions), cfg.batch_size)
            self.model.td_step(self._batch([self.transitions[k] for k in picks]))
        if self.steps % cfg.target_every == 0:
            self.model.sync_target()

    def _batch(self, items: list[tuple]) -> dict[str, torch.Tensor]:
        states, joints, rewards, nexts, legal, terminal = zip(*items, strict=True)
        return {
            "state": self._encode_many(states),
            "actions": torch.tensor([joints]),
            "reward": torch.tensor([rewards], dtype=torch.float32),
            "next_state": self._encode_many(nexts),
            "next_legal": torch.stack(legal)[None],
            "terminal": torch.tensor([terminal]),
        }
