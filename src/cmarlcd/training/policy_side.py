"""Fixed joint policies as one side of a game: a table over state indices, how a
learner's greedy policy, taken at a checkpoint, is evaluated (:mod:`cmarlcd.training.loop`),
and the uniform random policy, the floor a learner's return is read against.

Neither side learns; only its ``greedy`` kernel is ever called.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from cmarlcd.compiled import Unbound, specialise_kernel
from cmarlcd.games.spec import GameSpec
from cmarlcd.learners.policy import uniform_legal_action
from cmarlcd.training.protocol import IDLE, Side

game = Unbound("game")


class PolicyData(NamedTuple):
    """A fixed policy's arrays, as its kernels read them."""

    counts: np.ndarray
    playing: np.ndarray
    """``playing[s]``: the joint action played in state ``s`` (made legal on first use)."""
    checked: np.ndarray
    """``checked[s]``: ``playing[s]`` has been checked against the state's masks."""
    joints: np.ndarray
    rewards: np.ndarray


def policy_greedy(side, env, team, offset, legal, rng, joint) -> None:
    """Template: the policy's joint action in the team's state. [choice] An action the
    game forbids in a state (one the learner never visited, whose row was set up as if
    every action were legal) is replaced by the agent's lowest legal action there: the
    greedy choice among equal untouched values. Masks depend on the state alone, so each
    state's row is checked once, on its first use."""
    s = game.state(env, team)
    if not side.checked[s]:
        game.legal(env, legal)
        for i in range(joint.shape[0]):
            if not legal[offset + i, side.playing[s, i]]:
                side.playing[s, i] = np.argmax(legal[offset + i])
        side.checked[s] = True
    for i in range(joint.shape[0]):
        joint[i] = side.playing[s, i]


class PolicySide(Side):
    """Team ``team`` of ``spec`` playing the fixed ``policy`` (one joint action per state
    index, ``(n_states, n_agents)``)."""

    def __init__(self, spec: GameSpec, team: int, policy: np.ndarray) -> None:
        counts = spec.action_counts[list(spec.teams[team])].copy()
        steps = spec.max_steps
        self.kernels = IDLE._replace(greedy=specialise_kernel(policy_greedy, game=spec.kernels))
        self.data = PolicyData(
            counts,
            np.array(policy, dtype=np.int64),  # a copy: made legal in place
            np.zeros(spec.n_states, dtype=np.bool_),
            np.zeros((steps, counts.shape[0]), dtype=np.int64),
            np.zeros(steps),
        )


# ------------------------------------------------------------- the uniform random policy


class UniformData(NamedTuple):
    """The uniform random policy's arrays, as its kernel reads them."""

    counts: np.ndarray
    joints: np.ndarray
    rewards: np.ndarray


def uniform_greedy(side, env, team, offset, legal, rng, joint) -> None:
    """Template: each agent a uniform legal action, drawn from ``rng`` (the side's
    evaluation stream)."""
    game.legal(env, legal)
    for i in range(joint.shape[0]):
        joint[i] = uniform_legal_action(legal[offset + i], side.counts[i], rng.random())


class UniformSide(Side):
    """Team ``team`` of ``spec`` playing uniform legal actions: the floor a learner's
    return is read against."""

    def __init__(self, spec: GameSpec, team: int) -> None:
        counts = spec.action_counts[list(spec.teams[team])].copy()
        steps = spec.max_steps
        self.kernels = IDLE._replace(greedy=specialise_kernel(uniform_greedy, game=spec.kernels))
        self.data = UniformData(
            counts, np.zeros((steps, counts.shape[0]), dtype=np.int64), np.zeros(steps)
        )
