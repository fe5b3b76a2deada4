"""The generic episode loop: any learner object on any PettingZoo ``ParallelEnv``.

:func:`play_episodes` drives a learner with the object API (``act`` / ``greedy(state,
masks)``, ``observe(state, joint, reward)``, ``end_episode(final_state, terminated)``:
:class:`cmarlcd.learners.tabular.TabularLearner`,
:class:`cmarlcd.learners.deep_agent.DeepAgent`) through any ``ParallelEnv`` whose
``state()`` is an integer or hashable and whose infos may carry ``"action_mask"``. On the
games of :mod:`cmarlcd.games` it learns exactly what the compiled loops of
:mod:`cmarlcd.training.tabular` learn, one Python call per step.

:func:`play_copies` plays several copies of an environment in lockstep: each step asks
the learner for every live copy's joint action at once (``act_many`` / ``greedy_many``,
one forward pass of a deep learner, where the learner has them), and tells it whose
episode each step belongs to (the ``copy`` keyword of ``act``, ``observe`` and
``end_episode``). A copy whose episode ends starts the next one while episodes of the
budget remain. With one copy it is :func:`play_episodes`, call for call.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from cmarlcd.training.tabular import EpisodeStats


def shared_reward(rewards: Mapping[str, float]) -> float:
    """The global reward when every agent receives it (as in the DSN)."""
    return float(next(iter(rewards.values())))


def play_episodes(
    env,
    learner: Any,
    episodes: int,
    *,
    learn: bool = True,
    seed: int | None = None,
    global_reward: Callable[[Mapping[str, float]], float] = shared_reward,
) -> EpisodeStats:
    """Play ``episodes`` episodes of ``env``: sampled actions and learning when ``learn``,
    greedy actions otherwise. ``seed`` seeds the first ``env.reset``; later episodes
    continue the environment's own stream."""
    return play_copies(
        [env], learner, episodes, learn=learn, seeds=[seed], global_reward=global_reward
    )


class _Copies:
    """The copies of :func:`play_copies`: which episode each plays, and its last infos."""

    def __init__(self, envs: Sequence[Any], episodes: int) -> None:
        self.envs, self.episodes = list(envs), episodes
        self.started = 0
        self.episode_of: dict[int, int] = {}  # live copy -> the episode it plays
        self.infos: list[Any] = [None] * len(self.envs)
        self.agents: list[list[str]] = [[] for _ in self.envs]

    def start(self, copy: int, seed: int | None) -> bool:
        """Start the budget's next episode on ``copy``, if one is left."""
        if self.started >= self.episodes:
            return False
        env = self.envs[copy]
        _, self.infos[copy] = env.reset(seed=seed)
        self.agents[copy] = list(env.possible_agents)
        self.episode_of[copy] = self.started
        self.started += 1
        return True

    def masks(self, copy: int) -> list | None:
        """The agents' action masks in ``copy``'s infos, or None."""
        infos, agents = self.infos[copy], self.agents[copy]
        if "action_mask" not in infos[agents[0]]:
            return None
        return [infos[a]["action_mask"] for a in agents]


def play_copies(
    envs: Sequence[Any],
    learner: Any,
    episodes: int,
    *,
    learn: bool = True,
    seeds: Sequence[int | None] | None = None,
    global_reward: Callable[[Mapping[str, float]], float] = shared_reward,
) -> EpisodeStats:
    """Play ``episodes`` episodes over the copies ``envs`` of one environment, in
    lockstep: sampled actions and learning when ``learn``, greedy actions otherwise.
    ``seeds[k]`` seeds copy ``k``'s first reset; its later episodes continue its own
    stream. The statistics are in the order the episodes started."""
    copies = _Copies(envs, episodes)
    stats = EpisodeStats(
        np.zeros(episodes), np.zeros(episodes, dtype=np.int64), np.zeros(episodes, dtype=np.bool_)
    )
    several = len(copies.envs) > 1
    for copy in range(len(copies.envs)):
        first = None if seeds is None else seeds[copy]
        _start(copies, copy, first, stats, learner, learn, several)
    while copies.episode_of:
        live = sorted(copies.episode_of)
        states = [copies.envs[k].state() for k in live]
        masks = [copies.masks(k) for k in live]
        joints = _joint_actions(learner, states, masks, live, learn, several)
        for copy, state, joint in zip(live, states, joints, strict=True):
            env, episode = copies.envs[copy], copies.episode_of[copy]
            actions = dict(zip(copies.agents[copy], joint, strict=True))
            _, rewards, terminations, _, copies.infos[copy] = env.step(actions)
            reward = global_reward(rewards)
            if learn:
                learner.observe(state, joint, reward, **_whose(copy, several))
            stats.returns[episode] += reward
            stats.lengths[episode] += 1
            stats.terminated[episode] = any(terminations.values())
            if not env.agents:
                _end(copies, copy, learner, learn, several, bool(stats.terminated[episode]))
                _start(copies, copy, None, stats, learner, learn, several)
    return stats


def _whose(copy: int, several: bool) -> dict[str, int]:
    """The ``copy`` keyword, given only when several copies play (so that a learner of
    one environment at a time needs no such argument)."""
    return {"copy": copy} if several else {}


def _start(copies: _Copies, copy: int, seed, stats, learner, learn: bool, several: bool) -> None:
    """Start ``copy``'s next episode; one that ends at its reset (no agent left) is
    closed at once, as terminated."""
    while copies.start(copy, seed) and not copies.envs[copy].agents:
        stats.terminated[copies.episode_of[copy]] = True
        _end(copies, copy, learner, learn, several, terminated=True)
        seed = None


def _end(copies: _Copies, copy: int, learner, learn: bool, several: bool, terminated: bool):
    """Close ``copy``'s episode (the learner learns from it when ``learn``)."""
    del copies.episode_of[copy]
    if learn:
        final = copies.envs[copy].state()
        learner.end_episode(final_state=final, terminated=terminated, **_whose(copy, several))


def _joint_actions(learner, states, masks, live, learn: bool, several: bool) -> list:
    """Every live copy's joint action: with one call where the learner acts for many
    states at once, else copy by copy."""
    if several and learn and hasattr(learner, "act_many"):
        return learner.act_many(states, masks, live)
    if several and not learn and hasattr(learner, "greedy_many"):
        return [tuple(int(a) for a in joint) for joint in learner.greedy_many(states, masks)]
    if learn:
        return [
            learner.act(s, m, **_whose(k, several))
            for s, m, k in zip(states, masks, live, strict=True)
        ]
    return [learner.greedy(s, m) for s, m in zip(states, masks, strict=True)]
