"""simple_spread as a PettingZoo ``ParallelEnv``, over the kernels the loops run."""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium
import numpy as np

from cmarlcd.games.env import KernelParallelEnv
from cmarlcd.games.spread import kernels as k
from cmarlcd.games.spread.rules import SimpleSpread


class SimpleSpreadEnv(KernelParallelEnv):
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
        super().__init__(rules.spec(), render_mode)
        self.rules = rules
        width = rules.observation_size
        self._observation_spaces = {
            agent: gymnasium.spaces.Box(-np.inf, np.inf, (width,), np.float32)
            for agent in self.possible_agents
        }
        self.state_space = gymnasium.spaces.Box(-np.inf, np.inf, (rules.N * width,), np.float32)
        self._features = np.zeros(rules.N * width, dtype=np.float32)

    def observation_space(self, agent: str) -> gymnasium.spaces.Box:  # type: ignore[override]
        return self._observation_spaces[self._check_agent(agent)]

    def state(self) -> np.ndarray:  # type: ignore[override]
        """Every agent's observation joined, in agent order (a new array)."""
        self.spec.kernels.features(self.env, 0, self._features)
        return self._features.copy()

    def _observations(self, states: tuple[int, ...]) -> dict[str, np.ndarray]:
        joined, width = self.state(), self.rules.observation_size
        return {agent: joined[i * width : (i + 1) * width] for i, agent in enumerate(self.agents)}

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
