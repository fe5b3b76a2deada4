"""Level-Based Foraging as a PettingZoo ``ParallelEnv``, over the kernels the loops run."""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium
import numpy as np

from cmarlcd.games.env import KernelParallelEnv
from cmarlcd.games.foraging import kernels as k
from cmarlcd.games.foraging.render import render_text
from cmarlcd.games.foraging.rules import Foraging


class ForagingEnv(KernelParallelEnv):
    """One LBF task (:class:`~cmarlcd.games.foraging.rules.Foraging`) as a ``ParallelEnv``
    of ``agent_0`` ... ``agent_{P-1}``.

    Each agent observes the package's vector (``Box`` of ``3 * foods + 3 * players``
    float32, its bounds the package's) and receives the team's reward, the sum of the
    agents' rewards; ``infos[agent]`` carries its ``"action_mask"`` (all six actions
    unless ``mask_invalid``) and, after a step, its ``"individual_reward"``. ``state()``
    is every agent's observation joined, in agent order. An episode terminates when no
    food is left and is truncated after ``max_steps`` steps (the package's ``done`` is
    the two together).
    """

    metadata: ClassVar[dict[str, Any]] = {
        "name": "foraging_v3",
        "render_modes": ["ansi", "human"],
    }

    def __init__(self, rules: Foraging | str = "8x8-2p-2f", render_mode: str | None = None) -> None:
        rules = Foraging.from_name(rules) if isinstance(rules, str) else rules
        super().__init__(rules.spec(), render_mode)
        self.rules = rules
        size, width = rules.size, rules.observation_size
        foods = [[-1, -1, 0], [size - 1, size - 1, rules.food_levels]]
        people = [[-1, -1, 0], [size - 1, size - 1, rules.max_player_level]]
        low = np.array(foods[0] * rules.foods + people[0] * rules.players, dtype=np.float32)
        high = np.array(foods[1] * rules.foods + people[1] * rules.players, dtype=np.float32)
        self._observation_spaces = {
            agent: gymnasium.spaces.Box(low, high, (width,), np.float32)
            for agent in self.possible_agents
        }
        self.state_space = gymnasium.spaces.Box(
            np.tile(low, rules.players), np.tile(high, rules.players), dtype=np.float32
        )
        self._features = np.zeros(rules.players * width, dtype=np.float32)

    def observation_space(self, agent: str) -> gymnasium.spaces.Box:  # type: ignore[override]
        return self._observation_spaces[self._check_agent(agent)]

    def state(self) -> np.ndarray:  # type: ignore[override]
        """Every agent's observation joined, in agent order (a new array)."""
        self.spec.kernels.features(self.env, 0, self._features)
        return self._features.copy()

    def _observations(self, states: tuple[int, ...]) -> dict[str, np.ndarray]:
        joined = self.state()
        width = self.rules.observation_size
        return {agent: joined[i * width : (i + 1) * width] for i, agent in enumerate(self.agents)}

    def _masks(self, states: tuple[int, ...]) -> list[np.ndarray]:
        """Each agent's legal actions now (asked every step: the state index does not
        always say them, a task without one reads 0 everywhere)."""
        self.spec.kernels.legal(self.env, self._legal)
        return [self._legal[i, : k.N_ACTIONS].astype(np.int8) for i in range(self.rules.players)]

    @property
    def players(self) -> np.ndarray:
        """Each agent's row, column and level, shape (P, 3)."""
        return self.env[0]

    @property
    def field(self) -> np.ndarray:
        """The level of the food on each cell (0: none)."""
        return self.env[1]

    def step_infos(self) -> list[dict[str, Any]]:
        return [{"individual_reward": r} for r in self.env[4][: self.rules.players].tolist()]

    def render_text(self) -> str:
        """The grid: agents by number with their levels below, foods by level."""
        return render_text(self.env, int(self.env[3][k.STEP]))
