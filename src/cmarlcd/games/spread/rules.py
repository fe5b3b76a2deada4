"""One simple_spread task: its agent count, ``local_ratio`` and episode length, by name
(``N=5,local_ratio=0``, mpe2's own keyword names) or by number, and its spec."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from cmarlcd.errors import ConfigError, require
from cmarlcd.games.spec import GameSpec
from cmarlcd.games.spread import kernels as k

#: The most agents (and landmarks) a task may have.
MAX_AGENTS = 16


@dataclass(frozen=True)
class SimpleSpread:
    """mpe2's ``simple_spread_v3`` with discrete actions; the defaults are mpe2's."""

    N: int = 3
    """Agents, and landmarks."""
    local_ratio: float = 0.5
    """The weight of each agent's own (collision) reward; the global one has 1 - it."""
    max_cycles: int = 25
    """Steps of an episode."""
    reward: str = "sum"
    """[choice] The team's reward from the agents': their ``sum`` (as ``train --env``'s
    default) or their ``mean`` (BenchMARL's, the anchor's)."""

    def __post_init__(self) -> None:
        require(
            isinstance(self.N, (int, np.integer)) and 1 <= self.N <= MAX_AGENTS,
            "N",
            f"must be a whole number in 1..{MAX_AGENTS} (got {self.N!r})",
        )
        ratio = self.local_ratio
        require(
            isinstance(ratio, (int, float)) and math.isfinite(ratio) and 0 <= ratio <= 1,
            "local_ratio",
            f"must be in [0, 1] (got {ratio!r})",
        )
        require(
            isinstance(self.max_cycles, (int, np.integer)) and self.max_cycles >= 1,
            "max_cycles",
            f"must be a whole number >= 1 (got {self.max_cycles!r})",
        )
        require(
            self.reward in ("sum", "mean"), "reward", f"must be sum or mean (got {self.reward!r})"
        )
        object.__setattr__(self, "N", int(self.N))
        object.__setattr__(self, "local_ratio", float(ratio))
        object.__setattr__(self, "max_cycles", int(self.max_cycles))

    @classmethod
    def from_name(cls, text: str) -> SimpleSpread:
        """The task of ``text``: empty (mpe2's defaults) or ``name=value`` settings
        joined by commas (``N=5,local_ratio=0``)."""
        given: dict[str, Any] = {}
        for item in (part.strip() for part in text.split(",")):
            if not item:
                continue
            name, sep, value = item.partition("=")
            name = name.strip()
            if not sep or name not in ("N", "local_ratio", "max_cycles", "reward"):
                raise ConfigError(
                    "game",
                    "simple_spread takes N, local_ratio, max_cycles and reward as name=value "
                    f"(got {item!r})",
                )
            if name == "reward":
                given[name] = value.strip()
                continue
            try:
                number = float(value)
            except ValueError:
                raise ConfigError(
                    "game", f"{name} must be a number (got {value.strip()!r})"
                ) from None
            if name != "local_ratio":
                if not (math.isfinite(number) and number.is_integer()):
                    raise ConfigError(
                        "game", f"{name} must be a whole number (got {value.strip()!r})"
                    )
                number = int(number)
            given[name] = number
        return cls(**given)

    @property
    def name(self) -> str:
        """``N=3,local_ratio=0.5,max_cycles=25``: every setting (``reward`` where it is
        not the sum), so that a name says it all."""
        name = f"N={self.N},local_ratio={self.local_ratio:g},max_cycles={self.max_cycles}"
        return name if self.reward == "sum" else f"{name},reward={self.reward}"

    @property
    def observation_size(self) -> int:
        """Numbers in one agent's observation: ``4 + 2N + 4(N - 1)``."""
        return 4 + 2 * self.N + 4 * (self.N - 1)

    def new_env(self) -> tuple[np.ndarray, ...]:
        return k.new_env(self.N, self.local_ratio, self.reward == "mean")

    def spec(self) -> GameSpec:
        """The game protocol: one team of N agents of five actions, no state index, every
        agent's observation joined as the features."""
        return GameSpec(
            name="simple_spread_v3",
            kernels=k.KERNELS,
            new_env=self.new_env,
            agents=tuple(f"agent_{i}" for i in range(self.N)),
            action_counts=np.full(self.N, k.N_ACTIONS, dtype=np.int64),
            n_states=1,
            max_steps=self.max_cycles,
            teams=(tuple(range(self.N)),),
            n_features=self.N * self.observation_size,
        )

    def package_kwargs(self) -> dict[str, Any]:
        """The keyword arguments of ``mpe2.simple_spread_v3.parallel_env``."""
        return {
            "N": self.N,
            "local_ratio": self.local_ratio,
            "max_cycles": self.max_cycles,
            "continuous_actions": False,
        }
