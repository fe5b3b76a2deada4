"""A tiny PettingZoo ParallelEnv for the tests of ``cmarl-cd train``: two agents, three
steps; the team earns 1 at a step where both choose action 1 (each agent its half), so
the optimal return is 3 and a uniform random policy's expected return 3/4."""

from __future__ import annotations

import functools
from typing import ClassVar

import gymnasium
import numpy as np
from pettingzoo import ParallelEnv

STEPS = 3


class TinyEnv(ParallelEnv):
    metadata: ClassVar[dict] = {"name": "tiny_v0"}

    def __init__(
        self,
        continuous: bool = False,
        actions: int = 2,
        state: str = "vector",
        labels: list | None = None,
        offset: float = 0.0,
    ) -> None:
        """``state``: "vector" (a Box), "integer" (the step, no state space) or "none"
        (PettingZoo's default ``state()``, which raises); ``labels`` is ignored (a list
        argument, as some factories take); ``offset`` is added to each agent's reward at
        every step."""
        self.possible_agents = ["a", "b"]
        self.continuous, self.actions, self.kind = continuous, actions, state
        self.offset = offset
        self.state_space = gymnasium.spaces.Box(0.0, 1.0, (STEPS,), np.float32)
        if state == "integer":
            del self.state_space

    @functools.cache  # noqa: B019
    def action_space(self, agent):
        if self.continuous:
            return gymnasium.spaces.Box(-1.0, 1.0, (1,), np.float32)
        return gymnasium.spaces.Discrete(self.actions)

    @functools.cache  # noqa: B019
    def observation_space(self, agent):
        return self.state_space

    def state(self):
        if self.kind == "none":
            return super().state()
        if self.kind == "integer":
            return np.int64(self.t)
        return self._vector()

    def _vector(self) -> np.ndarray:
        x = np.zeros(STEPS, np.float32)
        x[min(self.t, STEPS - 1)] = 1.0
        return x

    def reset(self, seed=None, options=None):
        self.agents, self.t = list(self.possible_agents), 0
        return {a: self._vector() for a in self.agents}, {a: {} for a in self.agents}

    def step(self, actions):
        both = all(int(actions[a]) == 1 for a in self.agents)
        self.t += 1
        done = self.t >= STEPS
        rewards = {a: 0.5 * both + self.offset for a in self.agents}
        observations = {a: self._vector() for a in self.agents}
        terminations = {a: done for a in self.agents}
        truncations = {a: False for a in self.agents}
        infos = {a: {} for a in self.agents}
        if done:
            self.agents = []
        return observations, rewards, terminations, truncations, infos


def make(**kwargs) -> TinyEnv:
    return TinyEnv(**kwargs)


def make_declaring(**kwargs) -> TinyEnv:
    """The tiny game, declaring its episode length as PettingZoo's MPE does (``max_cycles``
    on the unwrapped environment)."""
    env = TinyEnv(**kwargs)
    env.max_cycles = STEPS
    return env


NOT_A_FACTORY = 3


class RandomLengthEnv(TinyEnv):
    """The tiny game, but each episode lasts 1 to 6 steps, drawn at reset from the seeded
    stream, and a step pays a random amount: copies played together end at different
    steps, and a copy's transitions depend on its own seed."""

    def reset(self, seed=None, options=None):
        if seed is not None or not hasattr(self, "rng"):
            self.rng = np.random.default_rng(seed)
        self.length = int(self.rng.integers(1, 7))
        return super().reset(seed, options)

    def state(self):
        return np.int64(min(self.t, STEPS - 1))

    def step(self, actions):
        observations, rewards, terminations, truncations, infos = super().step(actions)
        bonus = float(self.rng.random())
        rewards = {a: r + bonus for a, r in rewards.items()}
        done = self.t >= self.length
        terminations = {a: done for a in terminations}
        self.agents = [] if done else list(self.possible_agents)
        return observations, rewards, terminations, truncations, infos


_MADE = [0]


def make_disagreeing(**kwargs) -> TinyEnv:
    """A factory whose copies disagree: every second call makes a game of 3 actions."""
    _MADE[0] += 1
    return TinyEnv(actions=2 + _MADE[0] % 2, **kwargs)


class BreakingEnv(TinyEnv):
    """The tiny game, until a copy's 30th step raises: a run that fails in its worker."""

    def step(self, actions):
        self.steps = getattr(self, "steps", 0) + 1
        if self.steps >= 30:
            raise RuntimeError("the tiny game broke at its 30th step")
        return super().step(actions)


def make_breaking(**kwargs) -> TinyEnv:
    return BreakingEnv(**kwargs)


def make_random_length(**kwargs) -> RandomLengthEnv:
    """The tiny game with random lengths and random pay, whose returns depend on the reset
    seeds: an evaluation replayed with other seeds gives another return."""
    return RandomLengthEnv(**kwargs)
