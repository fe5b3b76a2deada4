"""Two tiny games for checking learners: small enough to learn in a second, rich enough to
catch a learner that ignores masks, randomness or the other team.

* :data:`CHAIN` -- one team of two agents, a three-step chain (stochastic transitions,
  a state-dependent mask);
* :data:`DUEL` -- two teams of two agents racing along their own chains (the first to the
  end wins), with state features so that deep learners can play it too.
"""

from __future__ import annotations

import numpy as np

from cmarlcd.compiled import kernel
from cmarlcd.games.spec import GameKernels, GameSpec

#: The joint action that advances the chain from each state.
CHAIN_TARGET = np.array([[0, 0], [2, 1], [1, 2]])
#: The chance that the target joint action advances the chain.
ADVANCE = 0.9


@kernel
def chain_reset(env, rng):
    env[0][0] = 0


@kernel
def chain_step(env, joint, rng, rewards):
    s = env[0][0]
    rewards[0] = 0.0
    if joint[0] == CHAIN_TARGET[s, 0] and joint[1] == CHAIN_TARGET[s, 1] and rng.random() < ADVANCE:
        env[0][0] = s + 1
        rewards[0] = 10.0 if s == 2 else 1.0


@kernel
def chain_state(env, team):
    return env[0][0]


@kernel
def chain_done(env):
    return env[0][0] == 3


@kernel
def chain_legal(env, masks):
    masks[:] = True
    if env[0][0] == 1:
        masks[1, 2] = False


CHAIN = GameSpec(
    name="chain_v0",
    kernels=GameKernels(chain_reset, chain_step, chain_state, chain_done, chain_legal),
    new_env=lambda: (np.zeros(1, dtype=np.int64),),
    agents=("agent_0", "agent_1"),
    action_counts=np.array([3, 3]),
    n_states=4,
    max_steps=10,
    teams=((0, 1),),
)
"""In state ``s`` (0, 1, 2) the two agents advance only by playing ``CHAIN_TARGET[s]``,
and then only with probability 0.9; the last step pays 10, the others 1; anything else
pays nothing. In state 1 agent ``agent_1`` may not play action 2. The optimum returns 12
in 3 steps."""

#: Steps a team must make to win the duel.
DUEL_GOAL = 3


@kernel
def duel_reset(env, rng):
    env[0][:] = 0


@kernel
def duel_moves(progress, joint, team, rng) -> bool:
    """Whether ``team`` plays its target joint action and the move succeeds."""
    s = progress[team]
    hit = joint[2 * team] == CHAIN_TARGET[s, 0] and joint[2 * team + 1] == CHAIN_TARGET[s, 1]
    return hit and rng.random() < ADVANCE


@kernel
def duel_step(env, joint, rng, rewards):
    progress = env[0]
    red, blue = duel_moves(progress, joint, 0, rng), duel_moves(progress, joint, 1, rng)
    if red:
        progress[0] += 1
    if blue:
        progress[1] += 1
    rewards[0] = rewards[1] = 0.0
    for k in range(2):
        if progress[k] == DUEL_GOAL and progress[1 - k] < DUEL_GOAL:
            rewards[k], rewards[1 - k] = 5.0, -5.0


@kernel
def duel_state(env, team):
    return env[0][team] * (DUEL_GOAL + 1) + env[0][1 - team]


@kernel
def duel_done(env):
    return env[0][0] == DUEL_GOAL or env[0][1] == DUEL_GOAL


@kernel
def duel_legal(env, masks):
    masks[:] = True
    for k in range(2):
        if env[0][k] == 1:
            masks[2 * k + 1, 2] = False


@kernel
def duel_features(env, team, out):
    out[0] = env[0][team] / DUEL_GOAL
    out[1] = env[0][1 - team] / DUEL_GOAL


DUEL = GameSpec(
    name="duel_v0",
    kernels=GameKernels(duel_reset, duel_step, duel_state, duel_done, duel_legal, duel_features),
    new_env=lambda: (np.zeros(2, dtype=np.int64),),
    agents=("red_0", "red_1", "blue_0", "blue_1"),
    action_counts=np.array([3, 3, 3, 3]),
    n_states=(DUEL_GOAL + 1) ** 2,
    max_steps=12,
    teams=((0, 1), (2, 3)),
    n_features=2,
)
"""Two teams race along their own copy of the chain (the same targets and mask); a team
that reaches the end first wins 5 and the other loses 5; both reaching it on one step is
a tie. A team observes (its progress, the other's progress)."""
