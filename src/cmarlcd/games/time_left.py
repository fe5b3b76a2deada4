"""A game whose agents also read the time left in the episode (``time_left``, beyond the
paper): each agent's observation ``o_i`` becomes ``[o_i, τ]`` with ``τ = (T - t) / T``,
``t`` the steps taken in the episode and ``T`` the game's step cap (1 at the start, 0 at
the state an episode is cut in).

Why: an episode cut at the cap ends in a state whose value no observation explains, so a
learner either ends the cut episode's return there (and takes the steps left as noise of
the state) or bootstraps from its estimate there (and its optimism compounds where every
early episode is cut). With the time left in the input the cut is part of the state and
ending the return there is exact (Pardo et al., "Time Limits in Reinforcement Learning",
ICML 2018: time-aware agents). Every agent can count its own steps, so the input keeps
execution decentralised.

The game's state arrays gain one array at the end, ``[t, T, width, n]``; the wrapped
kernels hand the game its own arrays (the tuple without that one: a slice numba takes at
compile time), so the game's kernels and everything that reads its arrays by position
are unchanged. The state index (``state``) is the game's: a tabular learner reads no time.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from cmarlcd.compiled import Unbound, specialise_kernel
from cmarlcd.errors import require
from cmarlcd.games.spec import GameKernels, GameSpec

game = Unbound("game")

#: Entries of the clock array a wrapped game's state arrays end with.
STEPS, CAP, WIDTH, AGENTS = range(4)


def clocked_reset(env, rng) -> None:
    """Template: the game's reset, the episode's clock at 0."""
    game.reset(env[:-1], rng)
    env[-1][STEPS] = 0


def clocked_step(env, joint, rng, rewards) -> None:
    """Template: the game's step, counted."""
    game.step(env[:-1], joint, rng, rewards)
    env[-1][STEPS] += 1


def clocked_state(env, team: int) -> int:
    """Template: the game's state index (no time in it)."""
    return game.state(env[:-1], team)


def clocked_done(env) -> bool:
    """Template: the game's termination."""
    return game.done(env[:-1])


def clocked_legal(env, masks) -> None:
    """Template: the game's legal actions."""
    game.legal(env[:-1], masks)


def clocked_features(env, team: int, out) -> None:
    """Template: ``out`` := ``[o_1, τ, ..., o_n, τ]``: the game's features (``n``
    observations of ``width`` numbers) written first, then spread from the last agent's
    to the first, each followed by the time left (a number moves to an index at or after
    its own, so none is overwritten before it is moved)."""
    clock = env[-1]
    width, agents = clock[WIDTH], clock[AGENTS]
    game.features(env[:-1], team, out[: agents * width])
    left = np.float32((clock[CAP] - clock[STEPS]) / clock[CAP])
    for i in range(agents - 1, -1, -1):
        for k in range(width - 1, -1, -1):
            out[i * (width + 1) + k] = out[i * width + k]
        out[i * (width + 1) + width] = left


def with_time_left(spec: GameSpec, width: int) -> GameSpec:
    """``spec`` whose features ``[o_1, ..., o_n]`` (each agent's observation of ``width``
    numbers, joined in agent order) become ``[o_1, τ, ..., o_n, τ]``, each agent's
    observation ``width + 1`` numbers (compose with
    :func:`cmarlcd.games.observations.own_observations` at that width)."""
    require(
        spec.n_features == spec.n_agents * width and spec.own_dim == 0,
        "time_left",
        f"{spec.name}'s features are not {spec.n_agents} observations of {width} numbers",
    )
    bound = {"game": spec.kernels}
    kernels = GameKernels(
        reset=specialise_kernel(clocked_reset, **bound),
        step=specialise_kernel(clocked_step, **bound),
        state=specialise_kernel(clocked_state, **bound),
        done=specialise_kernel(clocked_done, **bound),
        legal=specialise_kernel(clocked_legal, **bound),
        features=specialise_kernel(clocked_features, **bound),
    )
    clock = (0, spec.max_steps, width, spec.n_agents)
    inner = spec.new_env

    def new_env() -> tuple:
        return (*inner(), np.array(clock, dtype=np.int64))

    return dataclasses.replace(
        spec,
        kernels=kernels,
        new_env=new_env,
        n_features=spec.n_agents * (width + 1),
        state_determines_features=False,
    )


def time_left_features(joined: np.ndarray, agents: int, steps: int, cap: int) -> np.ndarray:
    """What :func:`with_time_left`'s features are after ``steps`` steps of an episode,
    from the game's own ``joined`` features (``agents`` observations of equal width): for
    a loop in Python that holds the game's own state arrays (``cmarl-cd play``)."""
    rows = np.asarray(joined, np.float32).reshape(agents, -1)
    left = np.full((agents, 1), (cap - steps) / cap, np.float32)
    return np.concatenate([rows, left], axis=1).ravel()
