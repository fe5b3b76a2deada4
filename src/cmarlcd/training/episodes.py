"""The generic episode loop: any learner object on any PettingZoo ``ParallelEnv``.

:func:`play_episodes` drives a learner with the object API (``act`` / ``greedy(state,
masks)``, ``observe(state, joint, reward)``, ``end_episode(final_state, terminated)``:
:class:`cmarlcd.learners.tabular.protocol.TabularLearner`,
:class:`cmarlcd.learners.deep.agent.DeepAgent`) through any ``ParallelEnv`` whose
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


class _Lockstep:
    """One :func:`play_copies` call: the copies, which episode each plays, their last
    infos, the statistics, and the learner they are played for."""

    def __init__(
        self, envs: Sequence[Any], learner: Any, episodes: int, learn: bool, steps: int | None
    ) -> None:
        self.envs, self.learner, self.episodes, self.learn = list(envs), learner, episodes, learn
        self.steps, self.played = steps, 0  # the budget in steps (or None), the steps played
        self.several = len(self.envs) > 1
        self.started = 0
        self.episode_of: dict[int, int] = {}  # live copy -> the episode it plays
        self.infos: list[Any] = [None] * len(self.envs)
        self.agents: list[list[str]] = [[] for _ in self.envs]
        self.stats = self._empty(episodes if steps is None else 2 * len(self.envs))

    @staticmethod
    def _empty(size: int) -> EpisodeStats:
        return EpisodeStats(np.zeros(size), np.zeros(size, np.int64), np.zeros(size, np.bool_))

    def more(self) -> bool:
        """Whether another episode of the budget is to start."""
        if self.steps is None:
            return self.started < self.episodes
        # (an environment whose every episode ends at its reset plays no step: at most
        # ``steps`` episodes, so that the budget ends)
        return self.played < self.steps and self.started < self.steps

    def _room(self) -> None:
        """Room in the statistics for one more episode (a budget of steps does not know
        its episodes ahead: the arrays double as they fill)."""
        size = len(self.stats.returns)
        if self.started < size:
            return
        grown = self._empty(2 * size)
        for old, new in zip(
            (self.stats.returns, self.stats.lengths, self.stats.terminated),
            (grown.returns, grown.lengths, grown.terminated),
            strict=True,
        ):
            new[:size] = old
        self.stats = grown

    def played_stats(self) -> EpisodeStats:
        """The statistics of the episodes played."""
        stats, n = self.stats, self.started
        return EpisodeStats(stats.returns[:n], stats.lengths[:n], stats.terminated[:n])

    def whose(self, copy: int) -> dict[str, int]:
        """The ``copy`` keyword, given only when several copies play (so that a learner
        of one environment at a time needs no such argument)."""
        return {"copy": copy} if self.several else {}

    def start(self, copy: int, seed: int | None) -> None:
        """Start the budget's next episode on ``copy``, if one is left; one that ends at
        its reset (no agent left) is closed at once, as terminated."""
        while self.more():
            self._room()
            env = self.envs[copy]
            _, self.infos[copy] = env.reset(seed=seed)
            self.agents[copy] = list(env.possible_agents)
            self.episode_of[copy] = self.started
            self.started += 1
            if env.agents:
                return
            self.stats.terminated[self.episode_of[copy]] = True
            self.end(copy, terminated=True)
            seed = None

    def end(self, copy: int, terminated: bool) -> None:
        """Close ``copy``'s episode (the learner learns from it when ``learn``)."""
        del self.episode_of[copy]
        if self.learn:
            final = self.envs[copy].state()
            self.learner.end_episode(final_state=final, terminated=terminated, **self.whose(copy))

    def masks(self, copy: int) -> list | None:
        """The agents' action masks in ``copy``'s infos, or None."""
        infos, agents = self.infos[copy], self.agents[copy]
        if "action_mask" not in infos[agents[0]]:
            return None
        return [infos[a]["action_mask"] for a in agents]

    def joint_actions(self, states: list, masks: list, live: list[int]) -> list:
        """Every live copy's joint action: with one call where the learner acts for many
        states at once, else copy by copy."""
        learner = self.learner
        if self.several and self.learn and hasattr(learner, "act_many"):
            return learner.act_many(states, masks, live)
        if self.several and not self.learn and hasattr(learner, "greedy_many"):
            return [tuple(int(a) for a in joint) for joint in learner.greedy_many(states, masks)]
        if self.learn:
            return [
                learner.act(s, m, **self.whose(k))
                for s, m, k in zip(states, masks, live, strict=True)
            ]
        return [learner.greedy(s, m) for s, m in zip(states, masks, strict=True)]

    def step(self, copy: int, state, joint, global_reward) -> None:
        """Play ``joint`` in ``copy``: the learner observes it, the statistics count it,
        and an episode that ends is closed and the copy's next one started."""
        env, episode, stats = self.envs[copy], self.episode_of[copy], self.stats
        _, rewards, terminations, _, self.infos[copy] = env.step(
            dict(zip(self.agents[copy], joint, strict=True))
        )
        reward = global_reward(rewards)
        self.played += 1
        if self.learn:
            self.learner.observe(state, joint, reward, **self.whose(copy))
        stats.returns[episode] += reward
        stats.lengths[episode] += 1
        stats.terminated[episode] = any(terminations.values())
        if not env.agents:
            self.end(copy, bool(stats.terminated[episode]))
            self.start(copy, None)


def play_copies(
    envs: Sequence[Any],
    learner: Any,
    episodes: int,
    *,
    learn: bool = True,
    seeds: Sequence[int | None] | None = None,
    global_reward: Callable[[Mapping[str, float]], float] = shared_reward,
    steps: int | None = None,
) -> EpisodeStats:
    """Play ``episodes`` episodes over the copies ``envs`` of one environment, in
    lockstep: sampled actions and learning when ``learn``, greedy actions otherwise.
    ``seeds[k]`` seeds copy ``k``'s first reset; its later episodes continue its own
    stream. The statistics are in the order the episodes started.

    With ``steps``, the budget counts environment steps instead (``episodes`` is then
    not read): episodes start while the copies have played fewer than ``steps`` steps in
    all, and those in play when it is reached are played to their end."""
    play = _Lockstep(envs, learner, episodes, learn, steps)
    for copy in range(len(play.envs)):
        play.start(copy, None if seeds is None else seeds[copy])
    while play.episode_of:
        live = sorted(play.episode_of)
        states = [play.envs[k].state() for k in live]
        joints = play.joint_actions(states, [play.masks(k) for k in live], live)
        for copy, state, joint in zip(live, states, joints, strict=True):
            play.step(copy, state, joint, global_reward)
    return play.played_stats()
