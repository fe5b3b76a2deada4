"""The blood battlefield as a PettingZoo ``ParallelEnv``, over the kernels the loops run."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from cmarlcd.errors import require
from cmarlcd.games.battlefield.kernels import (
    N_SIDES,
    OUTCOME,
    PAPER,
    RECEIVED,
    TURN,
    Battlefield,
)
from cmarlcd.games.battlefield.render import render_text
from cmarlcd.games.env import KernelParallelEnv


class BattlefieldEnv(KernelParallelEnv):
    """Two troops (:class:`~cmarlcd.games.battlefield.kernels.Battlefield`) as a
    ``ParallelEnv`` of ``2 x n_units`` agents (``side0_marine_0`` ... ``side1_gunner_1``).

    Each agent observes its side's state index and receives its side's reward;
    ``infos[agent]["action_mask"]`` marks the live opponents it may fire at (a destroyed
    unit's only action is 0, ignored) and, after a step, ``"damage_taken"``. ``state()``
    is side 0's state index, ``state(1)`` side 1's.
    """

    metadata: ClassVar[dict[str, Any]] = {
        "name": "blood_battlefield_v0",
        "render_modes": ["ansi", "human"],
    }

    def __init__(self, rules: Battlefield = PAPER, render_mode: str | None = None) -> None:
        super().__init__(rules.spec(), render_mode)
        self.rules = rules
        self._kinds = ["marine"] * rules.marines + ["gunner"] * rules.gunners

    def state(self, side: int = 0) -> np.int64:  # type: ignore[override]
        """Side ``side``'s state index (PettingZoo's ``state()`` is side 0's), of
        ``state_space``'s dtype."""
        require(side in range(N_SIDES), "side", f"must be 0 or 1 (got {side})")
        return np.int64(self.spec.kernels.state(self.env, side))

    @property
    def hp(self):
        """Each unit's HP, shape (2, n_units); 0 = destroyed."""
        return self.env[0]

    @property
    def turn(self) -> int:
        return int(self.env[5][TURN])

    @property
    def outcome(self) -> int:
        """RUNNING, WIN_0, WIN_1 or TIE (see the kernels module)."""
        return int(self.env[5][OUTCOME])

    def step_infos(self) -> list[dict[str, Any]]:
        log = self.env[4]
        return [
            {"damage_taken": int(log[k, RECEIVED, u])}
            for k in range(N_SIDES)
            for u in range(self.rules.n_units)
        ]

    def render_text(self) -> str:
        """Both troops' HP, last turn's attacks and, at the end, the outcome."""
        return render_text(self.env, self._kinds, self.rules.max_turns)
