"""simple_spread as a PettingZoo ``ParallelEnv``, over the kernels the loops run."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from cmarlcd.games.env import ObservationsParallelEnv
from cmarlcd.games.spread import kernels as k
from cmarlcd.games.spread.rules import SimpleSpread


class SimpleSpreadEnv(ObservationsParallelEnv):
    """One simple_spread task (:class:`~cmarlcd.games.spread.rules.SimpleSpread`) as a
    ``ParallelEnv`` of ``agent_0`` ... ``agent_{N-1}``, as mpe2's ``parallel_env`` with
    discrete actions: each agent observes mpe2's vector (float32) and receives its own
    reward (``global · (1 - local_ratio) + own · local_ratio``); ``state()`` is every
    agent's observation joined; episodes are truncated after ``max_cycles`` steps.
    ``infos[agent]["action_mask"]`` is all ones."""

    metadata: ClassVar[dict[str, Any]] = {
        "name": "simple_spread_v3",
        "render_modes": ["ansi", "human"],
    }

    def __init__(self, rules: SimpleSpread | str = "", render_mode: str | None = None) -> None:
        rules = SimpleSpread.from_name(rules) if isinstance(rules, str) else rules
        bound = np.full(rules.observation_size, np.inf)
        super().__init__(rules.spec(), -bound, bound, render_mode)
        self.rules = rules

    def step(self, actions):
        observations, team, terminations, truncations, infos = super().step(actions)
        own = self.env[4].tolist()
        rewards = {agent: own[i] for i, agent in enumerate(team)}
        return observations, rewards, terminations, truncations, infos

    def render_text(self) -> str:
        """Each agent's and landmark's position."""
        agents, landmarks = self.env[0], self.env[1]
        lines = [f"step {self.steps}"]
        lines += [f"agent_{i}: ({a[k.X]:+.2f}, {a[k.Y]:+.2f})" for i, a in enumerate(agents)]
        lines += [f"landmark {m}: ({p[0]:+.2f}, {p[1]:+.2f})" for m, p in enumerate(landmarks)]
        return "\n".join(lines)
