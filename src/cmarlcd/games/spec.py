"""The compiled game protocol: what every game exports and every loop reads.

A game is a transition written once as numba-compiled functions (its *kernels*) over the
game's own state arrays ``env``: a tuple of arrays that :attr:`GameSpec.new_env`
allocates and that nothing but the game's kernels looks inside. The five kernels are

==========================  ================================================================
``reset(env, rng)``         start an episode (draws from ``rng``, a NumPy ``Generator``)
``step(env, joint, rng,     every agent acts at once (``joint[i]`` is agent ``i``'s action);
rewards)``                  ``rewards[k]`` is set to team ``k``'s reward for the step
``state(env, team)``        the state index team ``team`` observes, in ``[0, n_states)``
``done(env)``               True once the episode has terminated (not merely timed out)
``legal(env, masks)``       ``masks[i, a]`` := action ``a`` of agent ``i`` is legal now
``features(env, team,       optional: ``out[:]`` := the feature vector of team ``team``'s
out)``                      state (``GameSpec.n_features`` numbers), for learners that
                            generalise across states (VDN, QMIX on large games)
==========================  ================================================================

The game's PettingZoo ``ParallelEnv`` (:class:`cmarlcd.games.env.KernelParallelEnv`) and
every compiled training loop (:mod:`cmarlcd.training`) call these same functions and read
the sizes below from the same :class:`GameSpec`, so a rule such as the episode cap has a
single source of truth. Adding a game means writing its kernels and one spec.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from cmarlcd.compiled import shared_kernel
from cmarlcd.errors import require


@shared_kernel
def no_features(env, team: int, out) -> None:
    """``features`` of a game that has none (its states are indices only)."""


class GameKernels(NamedTuple):
    """A game's compiled functions (see the module docstring for their signatures)."""

    reset: Any
    step: Any
    state: Any
    done: Any
    legal: Any
    features: Any = no_features


@dataclass(frozen=True, eq=False)
class GameSpec:
    """Everything the environment and the training loops need to know about a game.

    Attributes:
        name: a short identifier (also the PettingZoo ``metadata["name"]``).
        kernels: the compiled transition.
        new_env: allocates the state arrays one copy of the game plays on.
        agents: the agents' names, in the order of ``joint``.
        action_counts: actions of each agent (int64, one per agent).
        n_states: state indices a team can observe, terminal states included.
        max_steps: an episode is truncated after this many steps.
        teams: the agents of each team; a cooperative game has one team of everyone.
        n_features: length of the ``features`` vector (0: the game has none).
        state_determines_features: whether a team's ``features`` and its agents' legal
            actions are functions of its state index (``state(env, team)``), as on the
            battlefield; a deep side then keeps the greedy actions it computed at each
            state while its weights stay the same
            (:data:`cmarlcd.training.deep_kernels.GREEDY_CACHE_SLOTS`). Declare it only
            where it holds: a side would act on another state's actions otherwise.
        own_dim: where the features end with each agent's own observation, this many
            numbers each (``[s, o_1, ..., o_n]``, e.g.
            :func:`cmarlcd.games.observations.own_observations`), so that VDN's and
            QMIX's agent networks read their own and QMIX's mixer ``s``; 0: every
            network reads the whole feature vector.
    """

    name: str
    kernels: GameKernels
    new_env: Callable[[], tuple]
    agents: tuple[str, ...]
    action_counts: np.ndarray
    n_states: int
    max_steps: int
    teams: tuple[tuple[int, ...], ...]
    n_features: int = 0
    state_determines_features: bool = False
    own_dim: int = 0

    def __post_init__(self) -> None:
        counts = np.array(self.action_counts, dtype=np.int64)
        counts.setflags(write=False)
        object.__setattr__(self, "action_counts", counts)
        require(counts.ndim == 1 and counts.size >= 1, "action_counts", "needs one per agent")
        require(int(counts.min()) >= 1, "action_counts", f"must be >= 1 (got {counts.tolist()})")
        require(len(self.agents) == counts.size, "agents", "needs one name per action count")
        require(self.n_states >= 1, "n_states", f"must be >= 1 (got {self.n_states})")
        require(self.max_steps >= 1, "max_steps", f"must be >= 1 (got {self.max_steps})")
        require(
            self.own_dim >= 0 and counts.size * self.own_dim <= self.n_features,
            "own_dim",
            f"must fit the features: n_agents x own_dim <= {self.n_features} (got {self.own_dim})",
        )
        members = sorted(a for team in self.teams for a in team)
        require(
            members == list(range(counts.size)),
            "teams",
            "must split the agents 0..n-1, each into exactly one team",
        )

    @property
    def n_agents(self) -> int:
        return int(self.action_counts.size)

    @property
    def n_teams(self) -> int:
        return len(self.teams)

    @property
    def width(self) -> int:
        """The largest action count: the row width of per-agent tables and masks."""
        return int(self.action_counts.max())

    def team_of(self, agent: int) -> int:
        """The team agent ``agent`` plays for."""
        return next(k for k, team in enumerate(self.teams) if agent in team)

    def require_one_team(self, what: str) -> None:
        """Reject games of several teams where ``what`` drives one team of learners."""
        require(
            self.n_teams == 1,
            "game",
            f"{what} plays cooperative games of one team; {self.name} has {self.n_teams}",
        )
