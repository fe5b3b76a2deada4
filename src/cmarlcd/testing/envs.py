"""Conformance of a game's ``ParallelEnv``: every PettingZoo test that applies, through
every standard conversion, and what the compiled loops rely on.

:func:`check_game` is what the project's own tests run on every registered game, and what
a plug-in author runs on a new one. It raises ``AssertionError`` (or PettingZoo's own
error) at the first failure.
"""

from __future__ import annotations

import contextlib
import functools
import io
import warnings
from collections.abc import Callable
from typing import Any

import gymnasium
import numpy as np
import pettingzoo
from pettingzoo.test import (
    api_test,
    parallel_api_test,
    parallel_seed_test,
    render_test,
    seed_test,
    state_test,
)
from pettingzoo.utils import conversions, wrappers
from pettingzoo.utils.wrappers.multi_episode_parallel_env import MultiEpisodeParallelEnv

from cmarlcd.games.env import KernelParallelEnv
from cmarlcd.games.spec import GameSpec

EnvFactory = Callable[..., pettingzoo.ParallelEnv]

#: PettingZoo's warnings that every ``Discrete`` observation draws: a state index is one
#: NumPy integer by design, not an array.
SCALAR_OBSERVATION_WARNINGS = (
    "Observation is not a NumPy array",
    "Observation is a single number",
    "State is not NumPy array",
)

#: The PettingZoo checks :func:`check_game` runs, by name, for its report.
CHECKS = (
    "parallel_api_test",
    "parallel_seed_test",
    "parallel_api_test after MultiEpisodeParallelEnv",
    "api_test after parallel_to_aec",
    "api_test after parallel_to_aec and AssertOutOfBoundsWrapper",
    "seed_test after parallel_to_aec",
    "parallel_api_test after parallel_to_aec and aec_to_parallel",
    "state_test",
    "render_test",
    "observations of their spaces' dtype, masks, rewards",
    "the ParallelEnv steps as the compiled kernels do",
)


def check_game(game: GameSpec | EnvFactory, cycles: int = 100, seeds: int = 3) -> None:
    """Every conformance check of :data:`CHECKS` on a game.

    Args:
        game: a :class:`GameSpec` (checked through :class:`KernelParallelEnv`) or a
            factory of the game's own ``ParallelEnv`` class that accepts ``render_mode=``.
        cycles: steps per PettingZoo test.
        seeds: episodes of the observation and kernel checks (one seed each).
    """
    make = functools.partial(KernelParallelEnv, game) if isinstance(game, GameSpec) else game
    with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()):
        for message in SCALAR_OBSERVATION_WARNINGS:  # PettingZoo's tests print, and warn
            warnings.filterwarnings("ignore", message=message)
        _pettingzoo_tests(make, cycles)
    for seed in range(seeds):
        check_observations(make(), seed)
        spec = getattr(make(), "spec", None)
        if isinstance(spec, GameSpec):
            check_env_follows_kernels(make, spec, seed)


def _pettingzoo_tests(make: EnvFactory, cycles: int) -> None:
    parallel_api_test(make(), num_cycles=cycles)
    parallel_seed_test(make, num_cycles=cycles)
    parallel_api_test(MultiEpisodeParallelEnv(make(), num_episodes=2), num_cycles=cycles)
    api_test(conversions.parallel_to_aec(make()), num_cycles=cycles)
    bounded = wrappers.AssertOutOfBoundsWrapper(conversions.parallel_to_aec_wrapper(make()))
    api_test(wrappers.OrderEnforcingWrapper(bounded), num_cycles=cycles)
    seed_test(lambda: conversions.parallel_to_aec(make()), num_cycles=cycles)
    round_trip = conversions.aec_to_parallel_wrapper(conversions.parallel_to_aec(make()))
    parallel_api_test(round_trip, num_cycles=cycles)
    state_test(conversions.parallel_to_aec(make()), make(), num_cycles=cycles)
    render_test(lambda render_mode: conversions.parallel_to_aec(make(render_mode=render_mode)))


def check_observations(env: pettingzoo.ParallelEnv, seed: int) -> None:
    """Over one episode of random legal actions: every observation is of its space's
    dtype and in it, every mask is an int8 array of the agent's action count with a legal
    action, every reward a float, ``state()`` in ``state_space``."""
    observations, infos = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    while True:
        _check_step(env, observations, infos)
        if not env.agents:
            return
        actions = {a: _legal_choice(infos[a], env.action_space(a), rng) for a in env.agents}
        observations, rewards, _, _, infos = env.step(actions)
        for agent, reward in rewards.items():
            assert isinstance(reward, float), f"{agent}: reward {reward!r} is not a float"


def _check_step(env: pettingzoo.ParallelEnv, observations: dict, infos: dict) -> None:
    for agent, observation in observations.items():
        space = env.observation_space(agent)
        _assert_of_dtype(observation, space, f"{agent}: observation")
        assert space.contains(observation), f"{agent}: {observation!r} is outside {space}"
    for agent in env.agents:
        mask = infos[agent].get("action_mask")
        if mask is not None:
            count = env.action_space(agent).n
            assert isinstance(mask, np.ndarray) and mask.dtype == np.int8, f"{agent}: mask"
            assert mask.shape == (count,), f"{agent}: mask of {mask.shape}, not ({count},)"
            assert mask.any(), f"{agent}: no legal action"
    state_space = getattr(env, "state_space", None)
    if state_space is not None:
        state = env.state()
        assert state_space.contains(state), f"state {state!r} is outside {state_space}"
        _assert_of_dtype(state, state_space, "state()")


def _assert_of_dtype(value: Any, space: gymnasium.spaces.Space, what: str) -> None:
    """``value`` is a NumPy value of ``space``'s dtype (spaces without one: anything)."""
    if space.dtype is None:
        return
    assert isinstance(value, (np.ndarray, np.generic)), (
        f"{what} {value!r} is a Python {type(value).__name__}, not a NumPy {space.dtype}"
    )
    assert value.dtype == space.dtype, f"{what} is {value.dtype}, its space says {space.dtype}"


def _legal_choice(info: dict[str, Any], space: gymnasium.spaces.Discrete, rng) -> int:
    mask = info.get("action_mask")
    legal = np.flatnonzero(mask) if mask is not None else np.arange(space.n)
    return int(rng.choice(legal))


def check_env_follows_kernels(make: EnvFactory, spec: GameSpec, seed: int) -> None:
    """The ``ParallelEnv`` and the game's kernels, driven with the same actions and the
    same generator, see the same states, rewards, masks and episode ends (the compiled
    loops and the PettingZoo face are one game)."""
    env = make()
    observations, infos = env.reset(seed=seed)
    kernels, state = spec.kernels, spec.new_env()
    rng = np.random.default_rng(seed)  # what env.reset(seed) draws from
    kernels.reset(state, rng)
    rewards = np.zeros(spec.n_teams)
    legal = np.zeros((spec.n_agents, spec.width), dtype=np.bool_)
    pick = np.random.default_rng([seed, 1])
    for step in range(spec.max_steps):
        _same_view(env, spec, state, observations, infos, legal)
        actions = {a: _legal_choice(infos[a], env.action_space(a), pick) for a in env.agents}
        joint = np.array([actions[a] for a in spec.agents], dtype=np.int64)
        observations, env_rewards, terminations, truncations, infos = env.step(actions)
        kernels.step(state, joint, rng, rewards)
        for i, agent in enumerate(spec.agents):
            assert env_rewards[agent] == rewards[spec.team_of(i)], f"step {step}: rewards"
        done = bool(kernels.done(state))
        assert all(t == done for t in terminations.values()), f"step {step}: termination"
        capped = not done and step + 1 == spec.max_steps
        assert all(t == capped for t in truncations.values()), f"step {step}: truncation"
        if done or capped:
            assert not env.agents, "agents left after the episode ended"
            return


def _same_view(env, spec: GameSpec, state, observations, infos, legal) -> None:
    kernels = spec.kernels
    kernels.legal(state, legal)
    for i, agent in enumerate(spec.agents):
        team = spec.team_of(i)
        assert observations[agent] == kernels.state(state, team), f"{agent}: state"
        mask = infos[agent].get("action_mask")
        if mask is not None:
            count = int(spec.action_counts[i])
            assert mask.tolist() == legal[i, :count].astype(np.int8).tolist(), f"{agent}: mask"
