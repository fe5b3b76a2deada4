"""Level-Based Foraging as a PettingZoo ``ParallelEnv``, over the kernels the loops run."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from cmarlcd.games.env import ObservationsParallelEnv
from cmarlcd.games.foraging import kernels as k
from cmarlcd.games.foraging.render import render_text
from cmarlcd.games.foraging.rules import Foraging


class ForagingEnv(ObservationsParallelEnv):
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
        size = rules.size
        foods = [[-1, -1, 0], [size - 1, size - 1, rules.food_levels]]
        people = [[-1, -1, 0], [size - 1, size - 1, rules.max_player_level]]
        low = foods[0] * rules.foods + people[0] * rules.players
        high = foods[1] * rules.foods + people[1] * rules.players
        super().__init__(rules.spec(), np.array(low), np.array(high), render_mode)
        self.rules = rules

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
