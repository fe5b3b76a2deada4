"""A game whose features are every agent's observation joined, read by each agent on its
own: the features laid out as ``[s, o_1, ..., o_n]`` (``s``, the mixer's state, is the
joined observations themselves), as VDN and QMIX were published (decentralised
execution: each agent acts on its own observation, QMIX's mixer reads the state)."""

from __future__ import annotations

import dataclasses

from cmarlcd.compiled import Unbound, specialise_kernel
from cmarlcd.errors import require
from cmarlcd.games.spec import GameSpec

game = Unbound("game")


def twice_features(env, team, out) -> None:
    """Template: the game's features (every agent's observation joined) written twice,
    once as the mixer's state and once as the agents' own observations."""
    half = out.shape[0] // 2
    game.features(env, team, out)
    for k in range(half):
        out[half + k] = out[k]


def own_observations(spec: GameSpec, width: int) -> GameSpec:
    """``spec`` whose features ``[o_1, ..., o_n]`` (each agent's observation of ``width``
    numbers, joined in agent order) become ``[o_1, ..., o_n, o_1, ..., o_n]`` with
    ``own_dim = width``."""
    require(
        spec.n_features == spec.n_agents * width and spec.own_dim == 0,
        "inputs",
        f"{spec.name}'s features are not {spec.n_agents} observations of {width} numbers",
    )
    features = specialise_kernel(twice_features, game=spec.kernels)
    return dataclasses.replace(
        spec,
        kernels=spec.kernels._replace(features=features),
        n_features=2 * spec.n_features,
        own_dim=width,
    )
