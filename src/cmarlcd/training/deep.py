"""A deep learner (VDN, QMIX, deep CMARL-CD), seed-batched, on a cooperative game of one
team (``[deep]`` extra).

B independent seeds learn together: each seed is a play of the game
(:class:`cmarlcd.training.loop.Play`) whose only side is a view of one
:class:`cmarlcd.training.deep_side.DeepGroup`, so the B seeds take their gradient steps as
one stacked model (:class:`cmarlcd.training.loop.PlayBatch`). Each seed has its own
streams, spawned from its run seed in a fixed order: parameter initialisation,
environment, exploration, replay sampling; so seed b of a batch follows the same
trajectory as that seed trained alone, up to float rounding in the batched products.

The networks only change at the gradient steps, so a run is evaluated at its checkpoints
with the greedy policy it had when it finished the checkpoint's last episode: a table
over the game's states where the seeds read one-hot state indices, its own side's greedy
play where they read the game's features (:class:`cmarlcd.training.greedy.GreedyPolicy`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from cmarlcd.games.spec import GameSpec
from cmarlcd.learners.deep.config import DeepConfig, DeepLearnerConfig, epsilon
from cmarlcd.training.deep_side import DeepGroup
from cmarlcd.training.greedy import GreedyPolicy
from cmarlcd.training.loop import Play, PlayBatch

#: Called as evaluate(seed index, episodes learnt, greedy policy).
Evaluator = Callable[[int, int, GreedyPolicy], None]


class DeepBatch:
    """B seeds of a deep learner learning one game for ``total_episodes`` episodes each
    (or as many environment steps, to the end of the episode in play, where ``unit`` is
    ``"steps"``: ε then anneals over steps), reading the game's features where it has
    them, else its state indices (one-hot; :func:`cmarlcd.training.deep_kernels.inputs_of`),
    its stacked model on ``device`` (default: this process's,
    :func:`cmarlcd.devices.current`)."""

    def __init__(
        self,
        spec: GameSpec,
        config: DeepLearnerConfig,
        seeds: Sequence[np.random.SeedSequence],
        total_episodes: int,
        device: str | None = None,
        unit: str = "episodes",
    ) -> None:
        spec.require_one_team("DeepBatch")
        init, env, act, replay = zip(*(s.spawn(4) for s in seeds), strict=True)
        self.spec, self.config, self.unit = spec, config, unit
        self.total_episodes, self.n_seeds = int(total_episodes), len(seeds)
        replay_rngs = [np.random.default_rng(s) for s in replay]
        self.group = DeepGroup(
            spec, [0] * self.n_seeds, config, init, replay_rngs, self.total_episodes,
            device=device, unit=unit,
        )  # fmt: skip
        self.plays = [
            Play(spec, [view], np.random.default_rng(e), [np.random.default_rng(a)])
            for view, e, a in zip(self.group.views, env, act, strict=True)
        ]
        self.batch = PlayBatch(self.plays, [self.group], self.total_episodes, unit)

    @property
    def model(self):
        return self.group.model

    @property
    def episodes(self) -> np.ndarray:
        """Learning episodes finished by each seed."""
        return np.array([play.episodes for play in self.plays])

    @property
    def env_steps(self) -> int:
        """Environment steps taken, all seeds together."""
        return sum(play.turns for play in self.plays)

    @property
    def seen(self) -> np.ndarray:
        """(B, n_states): the states each seed has met."""
        return self.group.seen

    @property
    def inputs(self) -> str:
        """What the seeds read: ``"features"`` or ``"index"``."""
        return self.group.inputs

    def scalars(self, k: int) -> dict[str, float | None]:
        """Seed ``k``'s learning now, for its live curves: the latest gradient step's
        loss (the mean over the seeds, which step together; None before the first) and,
        for a learner exploring ε-greedily, ε (eq. 18) at its next turn."""
        found: dict[str, float | None] = {"train/loss": self.group.last_loss}
        if isinstance(self.config, DeepConfig):
            play, steps = self.plays[k], self.unit == "steps"
            found["train/epsilon"] = epsilon(play.episodes + 1, self.total_episodes,
                                             self.config, play.turns + 1, steps)  # fmt: skip
        return found

    def greedy_tables(self) -> np.ndarray:
        """(B, n_states, n_agents) (index inputs): each seed's greedy joint action in
        every state, over the masks it has read."""
        return self.group.greedy_tables()

    def greedy_policies(self) -> list[GreedyPolicy]:
        """Each seed's greedy policy now: its table (index inputs) or its play."""
        if self.inputs == "index":
            return [GreedyPolicy(self.spec, table=table) for table in self.greedy_tables()]
        return [GreedyPolicy(self.spec, play=play) for play in self.plays]

    def train(self, checkpoints: Sequence[int], evaluate: Evaluator) -> None:
        """Learn until every seed has played its learning stage, calling ``evaluate`` as
        each seed reaches each checkpoint (in episodes, or environment steps) with the
        greedy policy it had then (when the seeds next paused: the networks do not change
        in between); a checkpoint 0 is evaluated before any learning."""
        points = sorted(set(checkpoints) | {self.total_episodes})
        evaluated = [0] * self.n_seeds
        if 0 in points:  # before any learning: the networks as they were made
            for k, policy in enumerate(self.greedy_policies()):
                evaluate(k, 0, policy)
        steps = self.unit == "steps"

        def done(play: Play) -> int:
            return play.turns if steps else play.finished

        def crossed() -> None:
            reached = [
                (k, point)
                for k, play in enumerate(self.plays)
                for point in points
                if evaluated[k] < point <= done(play)
            ]
            if reached:
                policies = self.greedy_policies()
                for k, point in reached:
                    evaluate(k, point, policies[k])
            evaluated[:] = [done(play) for play in self.plays]

        self.batch.learn(crossed)
