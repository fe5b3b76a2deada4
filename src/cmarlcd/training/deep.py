"""Seed-batched VDN / QMIX training on any game of the compiled protocol (``[deep]`` extra).

B independent seeds train together: B copies of the game each take ``train_every`` steps
in one compiled call (:func:`collect`, a template bound to the game's kernels, see
:mod:`cmarlcd.compiled`), replay batches are drawn in another
(:func:`cmarlcd.training.replay.replay_sample`), and one stacked model
(:class:`cmarlcd.learners.value_decomposition.ValueDecomposition`) takes the gradient
steps of all seeds at once. Each seed has its own streams, spawned from its run seed in a
fixed order: parameter initialisation, environment, exploration, replay sampling; so seed
b of a batch follows the same trajectory as that seed trained alone, up to float rounding
in the batched products.

Schedule: after every ``train_every`` environment steps, one gradient step once
``batch_size`` transitions are stored; after it, the target networks are copied whenever
another ``target_every`` steps have passed. The networks only change at these gradient
steps, so between them each seed's greedy policy is a table over the game's states.
States are the game's state indices (one-hot inputs); a state's legal-action masks are
read from the game on its first visit, as in the tabular loop.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import torch

from cmarlcd.compiled import Unbound, specialise
from cmarlcd.games.spec import GameSpec
from cmarlcd.learners.deep_config import DeepConfig, epsilon_schedule
from cmarlcd.learners.policy import annealed_epsilon, epsilon_greedy
from cmarlcd.learners.tabular import full_legal
from cmarlcd.learners.value_decomposition import ValueDecomposition
from cmarlcd.progress import report_progress
from cmarlcd.training.replay import new_batch, new_buffers, replay_sample, store

#: Called as evaluate(seed index, episodes learnt, greedy policy (n_states, n_agents)).
Evaluator = Callable[[int, int, np.ndarray], None]

game = Unbound("game")


def collect(
    envs,
    values,
    legal,
    seen,
    counts,
    steps,
    total_episodes,
    max_steps,
    schedule,
    clock,
    episodes,
    buffer,
    env_rngs,
    act_rngs,
) -> tuple[int, bool]:
    """Template: step each of B game copies ``steps`` steps with ε-greedy actions (eq. 18).

    ``values[b, s, i]`` are seed b's agent i's Q-values in state s (the networks change
    only between calls); an agent's greedy action is the best of its legal actions in
    ``legal[b, s]``, the masks seed b read from the game when it first met state s (a
    state reached as the last of an episode included, since its masks bound the TD
    target). ``clock[b]`` counts the steps of seed b's current episode and
    ``episodes[b]`` its finished episodes; a seed that has finished its
    ``total_episodes`` stops. Transitions go into seed b's ring in ``buffer``.
    ``env_rngs[b]`` and ``act_rngs[b]`` are seed b's own generators, and a seed knows
    only the masks it has read itself, so the seeds are independent (seed b learns what
    it learns alone) and are stepped one after the other. Returns the steps taken by all
    copies together, and whether a seed met a state for the first time.
    """
    joint = np.zeros(counts.shape[0], dtype=np.int64)
    rewards = np.zeros(1)
    taken, first_visit = 0, False
    for b in range(len(envs)):
        env = envs[b]
        for _ in range(steps):
            if episodes[b] >= total_episodes:
                break
            s = game.state(env, 0)
            if not seen[b, s]:
                game.legal(env, legal[b, s])
                seen[b, s] = first_visit = True
            eps = annealed_epsilon(episodes[b] + 1, total_episodes, *schedule)
            epsilon_greedy(values[b, s], legal[b, s], counts, eps, act_rngs[b], joint)
            game.step(env, joint, env_rngs[b], rewards)
            clock[b] += 1
            taken += 1
            terminal = game.done(env)
            next_s = game.state(env, 0)
            store(buffer, b, s, joint, rewards[0], next_s, terminal)
            if not seen[b, next_s]:
                game.legal(env, legal[b, next_s])
                seen[b, next_s] = first_visit = True
            if terminal or clock[b] >= max_steps:
                episodes[b] += 1
                clock[b] = 0
                if episodes[b] < total_episodes:
                    game.reset(env, env_rngs[b])
    return taken, first_visit


class DeepBatch:
    """B seeds of VDN or QMIX learning one game for ``total_episodes`` episodes each."""

    def __init__(
        self,
        spec: GameSpec,
        config: DeepConfig,
        seeds: Sequence[np.random.SeedSequence],
        total_episodes: int,
    ) -> None:
        spec.require_one_team("DeepBatch")
        init, env, act, replay = zip(*(s.spawn(4) for s in seeds), strict=True)
        self.spec, self.config = spec, config
        self.total_episodes, self.n_seeds = int(total_episodes), len(seeds)
        self.counts = spec.action_counts.copy()
        self.model = ValueDecomposition(self.counts, spec.n_states, config, init)
        self.env_rngs = tuple(np.random.default_rng(s) for s in env)
        self.act_rngs = tuple(np.random.default_rng(s) for s in act)
        self.replay_rngs = tuple(np.random.default_rng(s) for s in replay)
        self.envs = tuple(spec.new_env() for _ in seeds)
        self.clock = np.zeros(self.n_seeds, np.int64)
        self.episodes = np.zeros(self.n_seeds, np.int64)
        """Learning episodes finished by each seed."""
        every = np.repeat(full_legal(self.counts)[None], spec.n_states, axis=0)
        self.legal = np.repeat(every[None], self.n_seeds, axis=0)
        """Each seed's masks of each state, (B, n_states, n_agents, width), read from the
        game when the seed first meets the state (every action legal until then)."""
        self.seen = np.zeros((self.n_seeds, spec.n_states), np.bool_)
        """The states each seed has met."""
        self.buffer = new_buffers(
            self.n_seeds, config.buffer_size, spec.n_agents, spec.n_states, spec.width
        )
        self._collect = specialise(collect, game=spec.kernels)
        for k in range(self.n_seeds):
            spec.kernels.reset(self.envs[k], self.env_rngs[k])
        self.steps = 0
        """Environment steps of the schedule: ``train_every`` per collection call."""
        self.env_steps = 0
        """Environment steps actually taken, all seeds together."""

    def greedy_tables(self) -> np.ndarray:
        """(B, n_states, n_agents): each seed's greedy joint action in every state, over
        the masks it has read."""
        return self.model.greedy_table().numpy()

    def value_tables(self) -> np.ndarray:
        """(B, n_states, n_agents, width): each seed's agents' Q-values in every state."""
        with torch.no_grad():
            return self.model.agents.tables().numpy()

    def train(self, checkpoints: Sequence[int], evaluate: Evaluator) -> None:
        """Learn until every seed has played ``total_episodes`` episodes, calling
        ``evaluate`` as each seed reaches each checkpoint (in episodes) with the greedy
        policy it had then."""
        cfg = self.config
        points = sorted(set(checkpoints) | {self.total_episodes})
        values = self.value_tables()
        schedule = epsilon_schedule(cfg)
        while (self.episodes < self.total_episodes).any():
            before = self.episodes.copy()
            taken, first_visit = self._collect(
                self.envs,
                values,
                self.legal,
                self.seen,
                self.counts,
                cfg.train_every,
                self.total_episodes,
                self.spec.max_steps,
                schedule,
                self.clock,
                self.episodes,
                self.buffer,
                self.env_rngs,
                self.act_rngs,
            )
            self.env_steps += taken
            if first_visit:
                self.model.set_state_legal(torch.from_numpy(self.legal))
            report_progress(float((self.episodes - before).sum()))
            self._evaluate_crossed(before, points, evaluate)
            previous, self.steps = self.steps, self.steps + cfg.train_every
            if self.buffer.size.min() >= cfg.batch_size:
                self.model.td_step(self.sample())
                values = self.value_tables()
            if self.steps // cfg.target_every > previous // cfg.target_every:
                self.model.sync_target()

    def _evaluate_crossed(self, before: np.ndarray, points: list[int], evaluate: Evaluator) -> None:
        """``evaluate`` each seed at each checkpoint it has just crossed."""
        crossed = [
            (k, point)
            for k in range(self.n_seeds)
            for point in points
            if before[k] < point <= self.episodes[k]
        ]
        if crossed:
            table = self.greedy_tables()
            for k, point in crossed:
                evaluate(k, point, table[k])

    def sample(self) -> dict[str, torch.Tensor]:
        """A replay batch per seed, drawn with that seed's own generator (the legal
        actions of the next states come from the model's per-state masks)."""
        batch = new_batch(self.n_seeds, self.config.batch_size, self.spec.n_agents)
        replay_sample(self.buffer, self.replay_rngs, self.config.batch_size, batch)
        return {
            key: torch.from_numpy(array) for key, array in zip(batch._fields, batch, strict=True)
        }
