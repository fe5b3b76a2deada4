"""A repeated game as a one-step PettingZoo ``ParallelEnv`` (for the generic loops)."""

from __future__ import annotations

from typing import Any, ClassVar

from cmarlcd.games.env import KernelParallelEnv
from cmarlcd.games.matrix.game import MatrixGame
from cmarlcd.games.matrix.render import render_text


class MatrixGameEnv(KernelParallelEnv):
    """Every episode is one play of ``game``: each agent picks an action, all receive the
    payoff of the joint action. Agents are ``agent_0 .. agent_{n-1}``; the state is 0."""

    metadata: ClassVar[dict[str, Any]] = {
        "name": "matrix_game_v0",
        "render_modes": ["ansi", "human"],
    }

    def __init__(self, game: MatrixGame, render_mode: str | None = None) -> None:
        super().__init__(game.spec(), render_mode)
        self.game = game
        self._last: tuple[int, ...] | None = None

    def reset(self, seed: int | None = None, options: dict | None = None):
        self._last = None
        return super().reset(seed, options)

    def step(self, actions):
        result = super().step(actions)
        self._last = tuple(int(a) for a in self._joint)
        return result

    def render_text(self) -> str:
        return render_text(self.game, self._last)
