"""The DSN as a PettingZoo ``ParallelEnv``, over the same kernels the training loops run."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from cmarlcd.games.env import KernelParallelEnv
from cmarlcd.games.sensor_network.kernels import SPEC
from cmarlcd.games.sensor_network.render import render_text


class SensorNetworkEnv(KernelParallelEnv):
    """The DSN (:data:`cmarlcd.games.sensor_network.SPEC`) as a ``ParallelEnv``.

    Every sensor observes the global state index (``Discrete(43)``, as in the paper) and
    receives the global reward; ``infos[agent]`` carries an all-ones ``"action_mask"``
    and, after a step, the sensor's ``"individual_reward"``.
    """

    metadata: ClassVar[dict[str, Any]] = {
        "name": SPEC.name,
        "render_modes": ["ansi", "human"],
    }

    def __init__(self, render_mode: str | None = None) -> None:
        super().__init__(SPEC, render_mode)
        self._last_joint: np.ndarray | None = None

    @property
    def targets(self) -> np.ndarray:
        """Each target's cell, ``-1`` once captured."""
        return self.env[0]

    @property
    def energy(self) -> np.ndarray:
        """Each target's energy left."""
        return self.env[1]

    def reset(self, seed: int | None = None, options: dict | None = None):
        self._last_joint = None
        return super().reset(seed, options)

    def step(self, actions):
        result = super().step(actions)
        self._last_joint = self._joint.copy()
        return result

    def step_infos(self) -> list[dict[str, Any]]:
        return [{"individual_reward": reward} for reward in self.env[2].tolist()]

    def render_text(self) -> str:
        """The grid: targets where they stand now and, after a step, the cells the last
        joint action focused (before the targets moved)."""
        return render_text(self.targets, self.energy, self._last_joint)
