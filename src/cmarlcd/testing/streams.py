"""Stream equivalence: does a learner learn what another learns from the same visits?

The instrument for deep CMARL-CD on a game whose states are integers (one-hot for a
network, which can then hold any table). A *reference* learner (tabular CMARL-CD) plays
the game and learns as it goes; a *candidate* (deep CMARL-CD) is fed exactly the same
visits, step by step (``observe`` and ``end_episode``: it never acts), so both see an
identical stream. At each checkpoint both are compared on every state the stream has
visited: the share of states whose greedy joint actions agree, and the largest
difference between their coordination degrees (clipped, over every agent's legal
actions). A candidate that learns what the reference learns scores 1 and 0 at every
checkpoint, whatever the stream; one whose updates accumulate, or whose record is not a
maximum, drifts away.

>>> from cmarlcd.games.sensor_network import SensorNetworkEnv
>>> from cmarlcd.learners import CMARLCDStochastic
>>> points = stream_equivalence(SensorNetworkEnv(), CMARLCDStochastic([9] * 4, seed=0),
...                             candidate, checkpoints=(1_000, 10_000))   # doctest: +SKIP

Both learners need ``greedy(state, masks)`` and ``degrees(state, masks)`` (each agent's
clipped degrees, shape (n_agents, width)) besides the object API of
:func:`cmarlcd.training.episodes.play_episodes`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from cmarlcd.errors import require
from cmarlcd.training.episodes import play_episodes


@dataclass(frozen=True)
class Checkpoint:
    """Reference and candidate compared after ``episodes`` episodes of one stream."""

    episodes: int
    states: int
    """States the stream has visited so far (the states compared)."""
    agreement: float
    """Share of those states where the greedy joint actions are the same."""
    agent_agreement: float
    """Share of those (state, agent) pairs where the agent's greedy actions are the same."""
    max_difference: float
    """Largest |reference degree - candidate degree| over those states, agents and legal
    actions."""


class _Tee:
    """Plays with the reference's actions and hands every step to both learners;
    remembers each visited state with the masks of its first visit."""

    def __init__(self, reference: Any, candidate: Any) -> None:
        self.reference, self.candidate = reference, candidate
        self.visited: dict[Any, Any] = {}

    def act(self, state, masks=None) -> tuple[int, ...]:
        self.visited.setdefault(_key(state), masks)
        return self.reference.act(state, masks)

    def observe(self, state, joint_action, reward: float) -> None:
        self.reference.observe(state, joint_action, reward)
        self.candidate.observe(state, joint_action, reward)

    def end_episode(self, final_state=None, terminated: bool = True) -> None:
        self.reference.end_episode(final_state=final_state, terminated=terminated)
        self.candidate.end_episode(final_state=final_state, terminated=terminated)


def _key(state: Any) -> Any:
    return int(state) if np.ndim(state) == 0 else tuple(np.asarray(state).ravel().tolist())


def compare(reference: Any, candidate: Any, visited: dict[Any, Any], episodes: int) -> Checkpoint:
    """Both learners on every state of ``visited`` (state -> masks, None: all legal)."""
    agree, agents, pairs, largest = 0, 0, 0, 0.0
    for state, masks in visited.items():
        mine_greedy, their_greedy = reference.greedy(state, masks), candidate.greedy(state, masks)
        agree += mine_greedy == their_greedy
        agents += sum(a == b for a, b in zip(mine_greedy, their_greedy, strict=True))
        pairs += len(mine_greedy)
        mine, theirs = reference.degrees(state, masks), candidate.degrees(state, masks)
        legal = np.ones(mine.shape, dtype=bool) if masks is None else _legal(masks, mine.shape)
        if legal.any():
            largest = max(largest, float(np.abs(mine - theirs)[legal].max()))
    share = agree / len(visited) if visited else 1.0
    return Checkpoint(episodes, len(visited), share, agents / pairs if pairs else 1.0, largest)


def _legal(masks: Sequence[np.ndarray], shape: tuple[int, ...]) -> np.ndarray:
    legal = np.zeros(shape, dtype=bool)
    for agent, mask in enumerate(masks):
        legal[agent, : len(mask)] = np.asarray(mask, dtype=bool)
    return legal


class Stream:
    """One stream of ``env``: ``reference`` plays it (learning) and ``candidate`` is fed
    its visits; :meth:`play` goes on by some episodes, :meth:`compare` compares the two
    learners now. ``seed`` seeds the environment's first reset."""

    def __init__(self, env: Any, reference: Any, candidate: Any, seed: int = 0) -> None:
        self.env, self.seed, self.episodes = env, seed, 0
        self._tee = _Tee(reference, candidate)

    def play(self, episodes: int) -> None:
        require(episodes >= 1, "episodes", f"must be >= 1 (got {episodes})")
        first = self.seed if self.episodes == 0 else None
        play_episodes(self.env, self._tee, episodes, seed=first)
        self.episodes += episodes

    def compare(self) -> Checkpoint:
        tee = self._tee
        return compare(tee.reference, tee.candidate, tee.visited, self.episodes)


def stream_equivalence(
    env: Any,
    reference: Any,
    candidate: Any,
    checkpoints: Sequence[int],
    seed: int = 0,
) -> list[Checkpoint]:
    """Play ``env`` with ``reference`` (learning), feed ``candidate`` the same visits, and
    compare them (:func:`compare`) after each number of episodes in ``checkpoints``.
    ``seed`` seeds the environment's first reset."""
    marks = sorted({int(c) for c in checkpoints})
    require(bool(marks) and marks[0] >= 1, "checkpoints", "give episode counts >= 1")
    stream, found = Stream(env, reference, candidate, seed), []
    for mark in marks:
        if mark > stream.episodes:
            stream.play(mark - stream.episodes)
        found.append(stream.compare())
    return found
