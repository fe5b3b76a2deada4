"""A PettingZoo ``ParallelEnv`` over any game's compiled kernels (:mod:`cmarlcd.games.spec`).

Each agent observes its team's state index (``Discrete(n_states)``) and receives its
team's reward; ``infos[agent]["action_mask"]`` holds the agent's legal actions (int8, as
PettingZoo's masked environments do). ``reset(seed=s)`` reseeds ``self.np_random``;
``reset()`` continues its stream, so an episode sequence is reproducible from one seed.
An episode ends when ``done`` holds (termination) or after ``spec.max_steps`` steps
(truncation). An action outside its agent's mask is still passed to the game, whose
rules decide what it does (PettingZoo's API test samples actions without masks); the
masks tell learners what is worth playing. Games subclass this to add their own
``render`` and infos.
"""

from __future__ import annotations

import operator
from collections.abc import Mapping
from typing import Any, ClassVar

import gymnasium
import numpy as np
import pettingzoo

from cmarlcd.errors import ConfigError, require
from cmarlcd.games.spec import GameSpec


class KernelParallelEnv(pettingzoo.ParallelEnv):
    """The ``ParallelEnv`` face of a :class:`GameSpec`: the same kernels the loops run."""

    metadata: ClassVar[dict[str, Any]] = {
        "name": "kernel_game_v0",
        "render_modes": ["ansi", "human"],
    }

    def __init__(self, spec: GameSpec, render_mode: str | None = None) -> None:
        require(
            render_mode is None or render_mode in self.metadata["render_modes"],
            "render_mode",
            f"must be None or one of {self.metadata['render_modes']} (got {render_mode!r})",
        )
        self.spec = spec
        self.render_mode = render_mode
        self.possible_agents = list(spec.agents)
        self.agents: list[str] = []
        self.state_space = gymnasium.spaces.Discrete(spec.n_states)
        self.np_random: np.random.Generator | None = None
        self.env = spec.new_env()
        self.steps = 0
        self._index = {agent: i for i, agent in enumerate(spec.agents)}
        self._team = [spec.team_of(i) for i in range(spec.n_agents)]
        self._counts = [int(count) for count in spec.action_counts]
        self._all_agents = frozenset(spec.agents)
        self._mask_cache: dict[tuple[int, ...], list[np.ndarray]] = {}
        self._joint = np.zeros(spec.n_agents, dtype=np.int64)
        self._rewards = np.zeros(spec.n_teams)
        self._legal = np.zeros((spec.n_agents, spec.width), dtype=np.bool_)
        # one space object per agent, as the PettingZoo API asks (seeding works on them)
        self._observation_spaces = {
            agent: gymnasium.spaces.Discrete(spec.n_states) for agent in spec.agents
        }
        self._action_spaces = {
            agent: gymnasium.spaces.Discrete(int(count))
            for agent, count in zip(spec.agents, spec.action_counts, strict=True)
        }

    def observation_space(self, agent: str) -> gymnasium.spaces.Discrete:
        return self._observation_spaces[self._check_agent(agent)]

    def action_space(self, agent: str) -> gymnasium.spaces.Discrete:
        return self._action_spaces[self._check_agent(agent)]

    def _check_agent(self, agent: str) -> str:
        if agent not in self._index:
            names = f"{self.possible_agents[0]}..{self.possible_agents[-1]}"
            raise ConfigError("agent", f"unknown agent {agent!r}; expected {names}")
        return agent

    def state(self) -> np.int64:
        """The state index of team 0 (the whole game, for a cooperative game), of
        ``state_space``'s dtype."""
        return np.int64(self.spec.kernels.state(self.env, 0))

    def reset(
        self, seed: int | None = None, options: dict | None = None
    ) -> tuple[dict[str, np.int64], dict[str, dict[str, Any]]]:
        if seed is not None or self.np_random is None:
            self.np_random = np.random.default_rng(seed)
        self.spec.kernels.reset(self.env, self.np_random)
        self.agents = list(self.possible_agents)
        self.steps = 0
        states = self._team_states()
        return self._observations(states), self._infos(states)

    def step(self, actions: Mapping[str, object]) -> tuple[dict, dict, dict, dict, dict]:
        if not self.agents or self.np_random is None:
            raise RuntimeError("the episode is over (or never started); call reset() first")
        joint = self._joint_action(actions)
        self.spec.kernels.step(self.env, joint, self.np_random, self._rewards)
        self.steps += 1
        terminated = bool(self.spec.kernels.done(self.env))
        truncated = not terminated and self.steps >= self.spec.max_steps
        agents = self.agents
        states = self._team_states()
        observations, infos = self._observations(states), self._infos(states, stepped=True)
        team_rewards = self._rewards.tolist()
        rewards = {a: team_rewards[k] for a, k in zip(agents, self._team, strict=True)}
        terminations = dict.fromkeys(agents, terminated)
        truncations = dict.fromkeys(agents, truncated)
        if terminated or truncated:
            self.agents = []
        return observations, rewards, terminations, truncations, infos

    @property
    def team_rewards(self) -> np.ndarray:
        """Each team's reward at the last step, as the game gave it (a copy)."""
        return self._rewards.copy()

    def _team_states(self) -> tuple[int, ...]:
        state = self.spec.kernels.state
        return tuple([int(state(self.env, k)) for k in range(self.spec.n_teams)])

    def _observations(self, states: tuple[int, ...]) -> dict[str, np.int64]:
        """Each agent's observation: its team's state index as a NumPy ``int64``, the
        dtype of its ``Discrete`` space (what PettingZoo's checks and wrappers expect)."""
        observed = [np.int64(state) for state in states]
        return {a: observed[k] for a, k in zip(self.agents, self._team, strict=True)}

    def _infos(self, states: tuple[int, ...], stepped: bool = False) -> dict[str, dict[str, Any]]:
        masks = self._masks(states)
        extra = self.step_infos() if stepped else None
        infos = {}
        for i, agent in enumerate(self.agents):
            infos[agent] = (
                {"action_mask": masks[i]}
                if extra is None
                else {"action_mask": masks[i], **extra[i]}
            )
        return infos

    def _masks(self, states: tuple[int, ...]) -> list[np.ndarray]:
        """Each agent's legal actions in ``states`` (int8, read-only); masks depend on the
        state alone, so they are asked from the game once per state."""
        masks = self._mask_cache.get(states)
        if masks is None:
            self.spec.kernels.legal(self.env, self._legal)
            masks = []
            for i, count in enumerate(self._counts):
                mask = self._legal[i, :count].astype(np.int8)
                mask.setflags(write=False)
                masks.append(mask)
            self._mask_cache[states] = masks
        return masks

    def step_infos(self) -> list[dict[str, Any]] | None:
        """Extra infos of every agent after a step, in agent order (a game adds its own)."""
        return None

    def _joint_action(self, actions: Mapping[str, object]) -> np.ndarray:
        if actions.keys() != self._all_agents:  # every agent acts until the episode ends
            unknown = [agent for agent in actions if agent not in self._index]
            if unknown:
                raise ConfigError("actions", f"unknown or finished agent {unknown[0]!r}")
            missing = [agent for agent in self.agents if agent not in actions]
            raise ConfigError("actions", f"no action for {missing[0]!r}")
        for i, (agent, count) in enumerate(zip(self.agents, self._counts, strict=True)):
            action = actions[agent]
            try:
                if isinstance(action, (bool, np.bool_)):
                    raise TypeError
                value = operator.index(action)  # type: ignore[arg-type]
            except TypeError:
                message = f"{agent}: action must be an integer (got {action!r})"
                raise ConfigError("actions", message) from None
            if not 0 <= value < count:
                message = f"{agent}: action must be in 0..{count - 1} (got {value})"
                raise ConfigError("actions", message)
            self._joint[i] = value
        return self._joint

    def render(self) -> str | None:
        """The game's text picture (:meth:`render_text`): returned for ``"ansi"`` and
        ``None``, printed for ``"human"``."""
        text = self.render_text()
        if self.render_mode == "human":
            print(text)
            return None
        return text

    def render_text(self) -> str:
        """A text picture of the current state (a game overrides this)."""
        return f"{self.spec.name}: step {self.steps}, state {self.state()}"

    def close(self) -> None:
        """Nothing to release."""


class ObservationsParallelEnv(KernelParallelEnv):
    """The ``ParallelEnv`` of a game whose features are every agent's observation joined
    in agent order (LBF, simple_spread): each agent observes its own ``Box`` of float32
    (bounds ``low``, ``high``), ``state()`` is all of them joined, and the masks are asked
    every step (a game without a state index reads 0 everywhere, so they cannot be
    cached by it)."""

    def __init__(
        self, spec: GameSpec, low: np.ndarray, high: np.ndarray, render_mode: str | None = None
    ) -> None:
        super().__init__(spec, render_mode)
        low, high = np.asarray(low, np.float32), np.asarray(high, np.float32)
        self._width = low.size
        self._observation_spaces = {  # type: ignore[assignment]
            agent: gymnasium.spaces.Box(low, high, (self._width,), np.float32)
            for agent in self.possible_agents
        }
        n = spec.n_agents
        self.state_space = gymnasium.spaces.Box(  # type: ignore[assignment]
            np.tile(low, n), np.tile(high, n), dtype=np.float32
        )
        self._features = np.zeros(n * self._width, dtype=np.float32)

    def observation_space(self, agent: str) -> gymnasium.spaces.Box:  # type: ignore[override]
        return self._observation_spaces[self._check_agent(agent)]

    def state(self) -> np.ndarray:  # type: ignore[override]
        """Every agent's observation joined, in agent order (a new array)."""
        self.spec.kernels.features(self.env, 0, self._features)
        return self._features.copy()

    def _observations(self, states: tuple[int, ...]) -> dict[str, np.ndarray]:  # type: ignore[override]
        joined, width = self.state(), self._width
        return {agent: joined[i * width : (i + 1) * width] for i, agent in enumerate(self.agents)}

    def _masks(self, states: tuple[int, ...]) -> list[np.ndarray]:
        self.spec.kernels.legal(self.env, self._legal)
        return [self._legal[i, :count].astype(np.int8) for i, count in enumerate(self._counts)]
