"""The rules of one Level-Based Foraging task, by name or by number, and its spec.

A task is named as the ``lbforaging`` package names its environments, without the
``Foraging-`` and ``-v3`` around it: ``[2s-]SxS-Pp-Ff[-coop]`` (``8x8-2p-2f-coop``,
``2s-10x10-3p-3f``; the package's whole id is accepted too), and any rule can be set
beside the name (``8x8-2p-2f-coop,penalty=0.1``). Every grid size, player count, food
count, sight and coop flag can be built, not only those the package registers (it
registers no five-food task, though the EPyMARL study ran three).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np

from cmarlcd.errors import ConfigError, require
from cmarlcd.games.foraging import kernels as k
from cmarlcd.games.spec import GameSpec

#: A task's name: ``[2s-]SxS-Pp-Ff[-coop]``, optionally inside ``Foraging-...-v3``.
TASK_PATTERN = re.compile(
    r"^(?:Foraging-)?(?:(?P<sight>\d+)s-)?(?P<size>\d+)x(?P=size)-(?P<players>\d+)p-"
    r"(?P<foods>\d+)f(?P<coop>-coop)?(?:-v3)?$"
)
#: The largest grid side, agent count and food count a task may have.
MAX_SIZE = 64
MAX_PLAYERS = 16
MAX_FOODS = 64
#: The most state indices a task numbers (:attr:`Foraging.n_states`); a larger one has
#: none, and only learners that read features play it.
MAX_INDEXED_STATES = 2**62


@dataclass(frozen=True)
class Foraging:
    """One LBF task: the package's ``ForagingEnv`` arguments, with its defaults.

    [choice] ``mask_invalid``: the package plays an invalid action as NONE and tells
    nobody which actions are valid (EPyMARL's learners see all six as available), so
    every action is legal by default; ``mask_invalid=True`` makes only the valid ones
    legal, for learners that should not waste steps on them.
    """

    size: int = 8
    """Rows and columns of the grid."""
    players: int = 2
    """Agents."""
    foods: int = 2
    """Foods placed at each reset, at most (the package's ``max_num_food``)."""
    sight: int | None = None
    """How many cells an agent sees in each direction (None: the whole grid)."""
    coop: bool = False
    """Every food at the largest level, so no agent can load one alone (``force_coop``)."""
    penalty: float = 0.0
    """The reward of each agent of a failed load, negated."""
    max_steps: int = 50
    """Steps of an episode (``max_episode_steps``)."""
    min_player_level: int = 1
    max_player_level: int = 2
    min_food_level: int = 1
    max_food_level: int | None = None
    """None: the sum of the three lowest agent levels of the episode."""
    mask_invalid: bool = False
    """Only valid actions legal (see the class's [choice])."""

    def __post_init__(self) -> None:
        for name in ("size", "players", "foods", "max_steps", "min_player_level",
                     "max_player_level", "min_food_level"):  # fmt: skip
            _whole(self, name)
        if self.sight is not None:
            _whole(self, "sight")
        if self.max_food_level is not None:
            _whole(self, "max_food_level")
        require(3 <= self.size <= MAX_SIZE, "size", f"must be in 3..{MAX_SIZE} (got {self.size})")
        require(
            1 <= self.players <= min(MAX_PLAYERS, self.size**2 - 1),
            "players",
            f"must be in 1..{min(MAX_PLAYERS, self.size**2 - 1)} on a {self.size}x{self.size} "
            f"grid (got {self.players})",
        )
        require(
            1 <= self.foods <= MAX_FOODS, "foods", f"must be in 1..{MAX_FOODS} (got {self.foods})"
        )
        require(
            self.sight is None or 1 <= self.sight <= self.size,
            "sight",
            f"must be in 1..{self.size} (got {self.sight})",
        )
        require(self.max_steps >= 1, "max_steps", f"must be >= 1 (got {self.max_steps})")
        require(
            1 <= self.min_player_level <= self.max_player_level,
            "max_player_level",
            f"needs 1 <= min_player_level <= max_player_level (got {self.min_player_level}, "
            f"{self.max_player_level})",
        )
        require(
            self.min_food_level >= 1
            and (self.max_food_level is None or self.min_food_level <= self.max_food_level),
            "max_food_level",
            f"needs 1 <= min_food_level <= max_food_level (got {self.min_food_level}, "
            f"{self.max_food_level})",
        )
        require(
            bool(np.isfinite(self.penalty)) and self.penalty >= 0,
            "penalty",
            f"must be a number >= 0 (got {self.penalty})",
        )
        object.__setattr__(self, "penalty", float(self.penalty))
        object.__setattr__(self, "coop", bool(self.coop))
        object.__setattr__(self, "mask_invalid", bool(self.mask_invalid))

    # ------------------------------------------------------------------ naming

    @classmethod
    def from_name(cls, text: str) -> Foraging:
        """The task ``text`` names: ``[2s-]SxS-Pp-Ff[-coop]``, then ``,rule=value``
        settings (e.g. ``8x8-2p-2f-coop,penalty=0.1``)."""
        name, *settings = [part.strip() for part in text.split(",")]
        match = TASK_PATTERN.match(name)
        if match is None:
            raise ConfigError(
                "game",
                f"not a foraging task: {name!r} (expected [2s-]SxS-Pp-Ff[-coop], e.g. "
                "8x8-2p-2f-coop or 2s-10x10-3p-3f)",
            )
        task = cls(
            size=int(match["size"]),
            players=int(match["players"]),
            foods=int(match["foods"]),
            sight=int(match["sight"]) if match["sight"] else None,
            coop=match["coop"] is not None,
        )
        return task.with_settings(dict(_setting(item) for item in settings if item))

    def with_settings(self, settings: dict[str, Any]) -> Foraging:
        """These rules with some of them changed, by name (values as text or numbers)."""
        known = {f.name: f for f in fields(self)}
        changes = {}
        for name, value in settings.items():
            if name not in known:
                raise ConfigError(
                    "game", f"foraging has no rule {name!r} (rules: {', '.join(known)})"
                )
            changes[name] = _value(name, value, getattr(self, name))
        return replace(self, **changes)

    @property
    def name(self) -> str:
        """The task's name (``2s-8x8-2p-2f-coop``), then the rules that differ from
        what the name says, as ``,rule=value``."""
        sight = "" if self.sight is None else f"{self.sight}s-"
        coop = "-coop" if self.coop else ""
        base = f"{sight}{self.size}x{self.size}-{self.players}p-{self.foods}f{coop}"
        named = Foraging(self.size, self.players, self.foods, self.sight, self.coop)
        extra = [
            f"{f.name}={getattr(self, f.name)}"
            for f in fields(self)
            if getattr(self, f.name) != getattr(named, f.name)
        ]
        return ",".join([base, *extra])

    # ------------------------------------------------------------------ sizes

    @property
    def view(self) -> int:
        """How far an agent sees (``sight``, or the grid's size)."""
        return self.size if self.sight is None else self.sight

    @property
    def observation_size(self) -> int:
        """Numbers in one agent's observation: ``3 * foods + 3 * players``."""
        return 3 * self.foods + 3 * self.players

    @property
    def food_levels(self) -> int:
        """The largest level a food can have."""
        if self.max_food_level is not None:
            return self.max_food_level
        return min(self.players, k.LOWEST_LEVELS) * self.max_player_level

    @property
    def state_count(self) -> int:
        """Indices of :func:`~.kernels.forage_state` (may exceed 64 bits)."""
        cells = self.size**2
        levels = self.max_player_level - self.min_player_level + 1
        return (cells * levels) ** self.players * (1 + cells * self.food_levels) ** self.foods

    @property
    def indexed(self) -> bool:
        """Whether the task numbers its states (at most :data:`MAX_INDEXED_STATES`)."""
        return self.state_count <= MAX_INDEXED_STATES

    @property
    def n_states(self) -> int:
        """State indices (1 where the task numbers none: every state reads 0)."""
        return self.state_count if self.indexed else 1

    # ------------------------------------------------------------------ game

    def rules_array(self) -> np.ndarray:
        """The rules' numbers, as the kernels read them (``kernels.ROWS`` ...)."""
        rules = np.zeros(k.N_RULES, dtype=np.int64)
        rules[k.ROWS] = rules[k.COLS] = self.size
        rules[k.SIGHT] = self.view
        rules[k.MAX_STEPS] = self.max_steps
        rules[k.FORCE_COOP] = self.coop
        rules[k.MIN_PLAYER_LEVEL] = self.min_player_level
        rules[k.MAX_PLAYER_LEVEL] = self.max_player_level
        rules[k.MIN_FOOD_LEVEL] = self.min_food_level
        rules[k.MAX_FOOD_LEVEL] = (
            k.FROM_PLAYERS if self.max_food_level is None else self.max_food_level
        )
        rules[k.MAX_FOODS] = self.foods
        rules[k.MASK_INVALID] = self.mask_invalid
        rules[k.FOOD_LEVELS] = self.food_levels if self.indexed else 0
        return rules

    def new_env(self) -> tuple[np.ndarray, ...]:
        """Fresh state arrays of one game (:func:`~.kernels.new_env`)."""
        return k.new_env(self.players, self.size, self.size, self.rules_array(), self.penalty)

    def spec(self) -> GameSpec:
        """The game protocol: one team of ``players`` agents of six actions; features
        are every agent's observation joined."""
        return GameSpec(
            name=f"Foraging-{self.name}-v3",
            kernels=k.KERNELS,
            new_env=self.new_env,
            agents=tuple(f"agent_{i}" for i in range(self.players)),
            action_counts=np.full(self.players, k.N_ACTIONS, dtype=np.int64),
            n_states=self.n_states,
            max_steps=self.max_steps,
            teams=(tuple(range(self.players)),),
            n_features=self.players * self.observation_size,
        )

    def package_kwargs(self) -> dict[str, Any]:
        """The keyword arguments of ``lbforaging.foraging.ForagingEnv`` for this task."""
        return {
            "players": self.players,
            "min_player_level": self.min_player_level,
            "max_player_level": self.max_player_level,
            "min_food_level": self.min_food_level,
            "max_food_level": self.max_food_level,
            "field_size": (self.size, self.size),
            "max_num_food": self.foods,
            "sight": self.view,
            "max_episode_steps": self.max_steps,
            "force_coop": self.coop,
            "penalty": self.penalty,
        }


def _whole(rules: Foraging, name: str) -> None:
    value = getattr(rules, name)
    ok = isinstance(value, (int, np.integer)) and not isinstance(value, bool)
    ok = ok or (isinstance(value, float) and value.is_integer())
    require(ok, name, f"must be a whole number (got {value!r})")
    object.__setattr__(rules, name, int(value))


def _setting(item: str) -> tuple[str, str]:
    name, sep, value = item.partition("=")
    if not sep or not name.strip():
        raise ConfigError("game", f"expected rule=value after the task's name (got {item!r})")
    return name.strip(), value.strip()


def _value(name: str, value: Any, current: Any) -> Any:
    """``value`` (text from the command line, or a number) as rule ``name`` takes it."""
    if not isinstance(value, str):
        return value
    lowered = value.lower()
    if name in ("sight", "max_food_level") and lowered in ("none", "null", ""):
        return None
    if name in ("coop", "mask_invalid"):
        if lowered in ("1", "true", "yes", "on"):
            return True
        if lowered in ("0", "false", "no", "off"):
            return False
        raise ConfigError("game", f"{name} must be true or false (got {value!r})")
    try:
        number = float(value)
    except ValueError:
        raise ConfigError("game", f"{name} must be a number (got {value!r})") from None
    if name == "penalty":
        return number
    if not math.isfinite(number) or not number.is_integer():
        raise ConfigError("game", f"{name} must be a whole number (got {value!r})")
    return int(number)
